/* Shortest round-trip formatting of doubles for messages (see numfmt.h). */
#include "util/numfmt.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *wf_num(char *out, size_t len, double x)
{
    if (!isfinite(x)) {
        snprintf(out, len, "%s", isnan(x) ? "nan" : x > 0 ? "inf" : "-inf");
        return out;
    }
    /* 17 significant digits always round-trip (IEEE 754 binary64); fewer often do. Try the shortest first. */
    int digits = 1;
    for (; digits < 17; digits++) {
        snprintf(out, len, "%.*g", digits, x);
        if (strtod(out, NULL) == x) break;
    }
    snprintf(out, len, "%.*g", digits, x);
    /* %g writes 100000 as 1e+05 when it has fewer digits than the exponent: whole numbers below 1e6 read
     * better in full, and more digits of the same value still round-trip. */
    const char *e = strchr(out, 'e');
    long exp10 = e ? strtol(e + 1, NULL, 10) : 0;
    if (e && exp10 > 0 && exp10 < 6) snprintf(out, len, "%.*g", (int)exp10 + 1, x);
    return out;
}
