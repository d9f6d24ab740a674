/* Numbers in messages: the shortest decimal text that reads back as the same double (0.3, not
 * 0.29999999999999999), so a message shows the value the user wrote. Internal to wavefuel. */
#ifndef WAVEFUEL_NUMFMT_H
#define WAVEFUEL_NUMFMT_H

#include <stddef.h>

enum { WF_NUM_LEN = 32 }; /* enough for "%.17g" of any double */

/* Writes into out (len >= WF_NUM_LEN bytes) the shortest "%.Ng" (N = 1..17) whose strtod() is x exactly ("inf",
 * "-inf", "nan" for those); returns out. Never fails. */
const char *wf_num(char *out, size_t len, double x);

/* wf_num into a buffer that lives until the end of the enclosing block: for one argument of a message call,
 * `wf_err(err, WF_EINPUT, "... (got %s)", WF_NUM(x))`. */
#define WF_NUM(x) wf_num((char[WF_NUM_LEN]){0}, WF_NUM_LEN, (x))

#endif
