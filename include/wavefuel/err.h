/* Error reporting: every fallible wavefuel function returns an int status and fills a WfError.
 * Status 0 is success; WF_EINPUT (2) means bad user input (exit code 2); WF_ESYS (1) a system, I/O
 * or library failure; WF_EINTR (3) an interrupted run. Only main() prints and exits. */
#ifndef WAVEFUEL_ERR_H
#define WAVEFUEL_ERR_H

#include <stddef.h>

enum { WF_OK = 0, WF_ESYS = 1, WF_EINPUT = 2, WF_EINTR = 3 };

typedef struct WfError {
    int  code;       /* one of the WF_E* values, 0 when no error was recorded */
    char msg[1024];  /* "file:line: key: what was expected (got value)" */
} WfError;

/* Record an error (printf-style) and return `code`, so callers can write
 * `return wf_err(err, WF_EINPUT, "%s:%d: ...", ...)`. err may be NULL. A message that does not
 * fit is truncated with "..." at the end rather than overflowing. */
int wf_err(WfError *err, int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Prefix an existing message with context ("scenarios/a.yaml: "); keeps the code; returns it. */
int wf_err_prefix(WfError *err, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Strict number parsing, the one number reader of every input (YAML, CSV fields, options): the whole string
 * must be a finite number in decimal notation (123, -0.5, 1e-3, .5; leading/trailing blanks allowed). Returns
 * 0 and stores the value, or -1 for empty text, trailing garbage, overflow, NaN, Inf or hexadecimal ("0x10"). */
int wf_parse_double(const char *s, double *out);
/* Same for integers in [min, max]. */
int wf_parse_long(const char *s, long min, long max, long *out);

#endif
