/* samples.csv's numbers, parsed straight into the arrays a set keeps (io/csv_columns.py): a piece
   of the file, lines of k cells that are all plain decimal numbers, each correctly rounded to the
   nearest double as pyarrow's parser and Python's float() round them. Anything else (a blank line,
   a quote, a space, text, NaN, a line without its end) stops the parse: the caller then reads the
   file by pyarrow, and the careful reader names the line; so does a number beyond the bound (not
   finite, or implausible), which the checks after pyarrow's parse then name. Written by hand, not
   derived. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static const double POW10[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* The number at *pp ending at a comma, a carriage return or a line end: 0 with *out and *pp past
   it, or -1. No bounds checked: the piece ends with a line end (simucal_csv_numbers), at which every
   scan stops. A mantissa of at most 15 digits (so below 2^53) times a power of ten up to 22 is one
   exactly rounded product or quotient of two exact doubles (Clinger's fast path); any other number
   goes to strtod, which rounds correctly. */
static int number(const char **pp, double *out)
{
    const char *p = *pp, *start = p, *digits;
    int neg = 0, exp10 = 0, ndigits;
    uint64_t m = 0;  /* wraps beyond 19 digits: strtod then reads the text */
    if (*p == '-' || *p == '+')
        neg = *p++ == '-';
    for (digits = p; (unsigned)(*p - '0') < 10; p++)
        m = m * 10 + (uint64_t)(*p - '0');
    ndigits = (int)(p - digits);
    if (*p == '.') {
        const char *fraction = ++p;
        for (; (unsigned)(*p - '0') < 10; p++)
            m = m * 10 + (uint64_t)(*p - '0');
        exp10 = -(int)(p - fraction);
        ndigits -= exp10;
    }
    if (!ndigits)
        return -1;
    if (*p == 'e' || *p == 'E') {
        int eneg = 0, e = 0;
        const char *edigits;
        p++;
        if (*p == '-' || *p == '+')
            eneg = *p++ == '-';
        for (edigits = p; (unsigned)(*p - '0') < 10; p++)
            if (e < 100000)
                e = e * 10 + (*p - '0');
        if (p == edigits)
            return -1;
        exp10 += eneg ? -e : e;
    }
    if (*p != ',' && *p != '\n' && *p != '\r')
        return -1;
    if (ndigits <= 15 && exp10 >= -22 && exp10 <= 22) {  /* leading zeros counted too: a few more go to strtod */
        double v = (double)m;
        v = exp10 < 0 ? v / POW10[-exp10] : v * POW10[exp10];
        *out = neg ? -v : v;
    } else {
        char text[128];
        size_t n = (size_t)(p - start);
        if (n >= sizeof text)
            return -1;
        memcpy(text, start, n);
        text[n] = 0;
        *out = strtod(text, NULL);
    }
    *pp = p;
    return 0;
}

/* Lines of text[0:len] (after the first line where skip is 1, the header) of k numbers each, every
   one within +-bound: cell j of line i into cols[j][i * stride[j]], and the least and the greatest of
   column j into extremes[4 j] and extremes[4 j + 1] (as given: +-inf, or a piece's before), the rows
   that hold each into extremes[4 j + 2] and extremes[4 j + 3] (the clipping check scans only for an
   extreme held often enough to be a run). Returns the lines read, or -1 at anything else, or where
   the piece holds more than max_rows lines. */
long simucal_csv_numbers(const char *text, long len, int skip, int k, double **cols, const long *stride,
                         long max_rows, double bound, double *extremes)
{
    const char *p = text, *end = text + len;
    long i = 0;
    if (len == 0 || (end[-1] != '\n' && end[-1] != '\r'))  /* every scan of a number stops at the last byte */
        return -1;
    if (skip) {
        p = memchr(text, '\n', (size_t)len);
        if (p == NULL)
            return -1;
        p++;
    }
    for (; p < end; i++) {
        if (i >= max_rows)
            return -1;
        for (int j = 0; j < k; j++) {
            double v;
            if (number(&p, &v) < 0 || !(v >= -bound && v <= bound))  /* NaN fails both */
                return -1;
            cols[j][i * stride[j]] = v;
            double *e = extremes + 4 * j;
            if (v <= e[0]) {
                if (v < e[0])
                    e[0] = v, e[2] = 0;
                e[2] += 1;
            }
            if (v >= e[1]) {
                if (v > e[1])
                    e[1] = v, e[3] = 0;
                e[3] += 1;
            }
            if (j < k - 1 && *p++ != ',')
                return -1;
        }
        if (*p == '\r')
            p++;
        if (p >= end || *p++ != '\n')
            return -1;
    }
    return i;
}

/* The line ends in text[0:len]; *quoted set to 1 where it holds a quote. One pass, 64 bytes at a time
   into byte counters (which the compiler vectorises), where numpy's comparisons took three. */
long simucal_csv_lines(const char *text, long len, int *quoted)
{
    long lines = 0, i = 0;
    unsigned char quote = 0;
    for (; i + 64 <= len; i += 64) {
        unsigned char ends = 0;
        for (int j = 0; j < 64; j++) {
            ends += text[i + j] == '\n';
            quote |= text[i + j] == '"';
        }
        lines += ends;
    }
    for (; i < len; i++) {
        lines += text[i] == '\n';
        quote |= text[i] == '"';
    }
    *quoted = quote != 0;
    return lines;
}
