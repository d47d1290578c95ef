/* Delimited decimal numbers to doubles, the common case of ikfusion.io.table in one call.
 *
 * A field is taken only in the plain form [+-]digits[.digits] whose digits, read as one
 * integer, are at most 2**53 and at most 22 decimals: its value is then that
 * integer divided by 10**decimals, both exact doubles, one correctly rounded division (Clinger's
 * fast path), which is the correctly rounded value of the decimal text: the double NumPy's
 * loadtxt (Python's string-to-double) reads. Anything else (an exponent, NaN, blanks, CR, NUL,
 * an empty kept field, a skipped field that is not empty, another field count, more digits)
 * returns -1 and the caller uses loadtxt. Every byte read lies in [text, text + size).
 */
#include <stdint.h>

struct parse_block {
    const char *text;      /* the block, lines joined by '\n' (no trailing newline) */
    int64_t size;          /* bytes of text */
    int64_t delimiter;     /* the field delimiter (one byte) */
    int64_t lines;
    int64_t width;         /* fields per line */
    const uint8_t *keep;   /* (width) 1: the column is read into out */
    double *out;           /* (lines, kept columns) */
};

static const double POWERS[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10,
    1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int field_value(const char *p, const char *end, double *value)
{   /* the plain decimal field [p, end) as a double; 0, or -1 when not plain */
    int negative = 0, digits = 0, decimals = 0, point = 0;
    uint64_t m = 0;
    if (p < end && (*p == '-' || *p == '+'))
        negative = *p++ == '-';
    for (; p < end; ++p) {
        char c = *p;
        if (c >= '0' && c <= '9') {
            if (m > ((uint64_t)1 << 53))
                return -1;  /* more digits than an exact double holds (m stays far from overflow) */
            digits = 1;
            m = m * 10 + (uint64_t)(c - '0');
            decimals += point;
            if (decimals > 22)
                return -1;  /* checked per digit: a long run of zeros cannot overflow the count */
        } else if (c == '.' && !point) {
            point = 1;
        } else {
            return -1;  /* an exponent, blank, NUL, CR, a byte beyond ASCII, another sign... */
        }
    }
    if (!digits || m > ((uint64_t)1 << 53))
        return -1;
    double v = (double)m / POWERS[decimals];
    *value = negative ? -v : v;
    return 0;
}

int64_t parse_block(const struct parse_block *a)
{   /* 0 when every line had width fields and every kept field was plain, else -1 */
    const char *p = a->text, *end = a->text + a->size;
    double *out = a->out;
    char d = (char)a->delimiter;
    for (int64_t line = 0; line < a->lines; ++line) {
        for (int64_t col = 0; col < a->width; ++col) {
            const char *start = p;
            while (p < end && *p != d && *p != '\n')
                ++p;
            char stop = p < end ? *p : '\n';
            if ((col + 1 < a->width) != (stop == d))
                return -1;  /* a line with another field count */
            if (a->keep[col] ? field_value(start, p, out++) != 0 : p != start)
                return -1;  /* a kept field not plain, or a skipped field not empty */
            if (p < end)
                ++p;
        }
    }
    return p == end ? 0 : -1;
}
