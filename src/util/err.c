/* Error records and strict number parsing shared by every module. */
#include "wavefuel/err.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void mark_truncated(WfError *err, int n)
{
    if (n >= (int)sizeof err->msg) memcpy(err->msg + sizeof err->msg - 4, "...", 4);
}

int wf_err(WfError *err, int code, const char *fmt, ...)
{
    if (!err) return code;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
    mark_truncated(err, n);
    err->code = code;
    return code;
}

int wf_err_prefix(WfError *err, const char *fmt, ...)
{
    if (!err) return WF_ESYS;
    char pre[512], old[sizeof err->msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(pre, sizeof pre, fmt, ap);
    va_end(ap);
    memcpy(old, err->msg, sizeof old);
    int n = snprintf(err->msg, sizeof err->msg, "%s%s", pre, old);
    mark_truncated(err, n);
    return err->code ? err->code : WF_ESYS;
}

static const char *skip_blank(const char *s)
{
    while (*s == ' ' || *s == '\t') s++;
    return s;
}

/* Decimal notation only: [+-]digits[.digits][(e|E)[+-]digits], at least one digit before the exponent. strtod()
 * alone also reads hexadecimal ("0x10" is 16), "inf" and "nan", which no wavefuel input means. Returns the length
 * of the decimal number at the start of s, 0 if there is none. */
static size_t decimal_length(const char *s)
{
    size_t i = 0, digits = 0;
    if (s[i] == '+' || s[i] == '-') i++;
    for (; s[i] >= '0' && s[i] <= '9'; i++) digits++;
    if (s[i] == '.')
        for (i++; s[i] >= '0' && s[i] <= '9'; i++) digits++;
    if (!digits) return 0;
    if (s[i] == 'e' || s[i] == 'E') {
        size_t j = i + 1, exp_digits = 0;
        if (s[j] == '+' || s[j] == '-') j++;
        for (; s[j] >= '0' && s[j] <= '9'; j++) exp_digits++;
        if (exp_digits) i = j;
    }
    return i;
}

int wf_parse_double(const char *s, double *out)
{
    if (!s) return -1;
    s = skip_blank(s);
    if (!*s) return -1;
    char *end = NULL;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || errno == ERANGE || !isfinite(v)) return -1;
    if ((size_t)(end - s) != decimal_length(s)) return -1; /* hexadecimal, or strtod read further than decimal */
    end = (char *)skip_blank(end);
    while (*end == '\r' || *end == '\n') end++; /* line ends may follow, nothing else */
    if (*end) return -1;
    *out = v;
    return 0;
}

int wf_parse_long(const char *s, long min, long max, long *out)
{
    if (!s) return -1;
    s = skip_blank(s);
    if (!*s) return -1;
    char *end = NULL;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || errno == ERANGE) return -1;
    end = (char *)skip_blank(end);
    if (*end) return -1;
    if (v < min || v > max) return -1;
    *out = v;
    return 0;
}
