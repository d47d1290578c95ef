/* Delimited decimal numbers to doubles, the common case of ikfusion.io.table in one pass.
 *
 * A field is read only when it is empty (NaN, as the Python path's "nan" fill) or in the plain
 * form [+-]digits[.digits] whose digits, read as one integer, are at most 2**53 with at most 22
 * decimals: its value is then that integer divided by 10**decimals, both exact doubles, one
 * correctly rounded division (Clinger's fast path), which is the correctly rounded value of
 * the decimal text: the double NumPy's loadtxt (Python's string-to-double) reads. Anything
 * else (an exponent, NaN or inf spelled out, blanks, CR, NUL, a byte beyond ASCII, more
 * digits, a line with another field count, an empty line of a one-column table, which loadtxt
 * skips) returns -1 and the caller takes the Python path. Every byte read lies in
 * [text, text + size): the text needs no terminator.
 */
#include <stdint.h>
#include <string.h>

struct parse_block {
    const char *text;      /* the block, lines joined by '\n' (no trailing newline) */
    int64_t size;          /* bytes of text */
    int64_t delimiter;     /* the field delimiter (one byte, not '\n') */
    int64_t lines;
    int64_t width;         /* fields per line */
    double *out;           /* (lines, width) */
};

static const double POWERS[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10,
    1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static double quiet_nan(void)
{   /* the NaN NumPy writes (0x7ff8000000000000): loadtxt's "nan" and np.nan */
    const uint64_t bits = 0x7ff8000000000000u;
    double value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

static const char *field_value(const char *p, const char *end, char d, double *value)
{   /* reads the field at p up to a delimiter, newline or the end; where it stopped, or NULL
       when the field is not plain (or empty) */
    const char *start = p;
    int negative = 0, digits = 0, decimals = 0, point = 0;
    uint64_t m = 0;
    if (p < end && (*p == '-' || *p == '+'))
        negative = *p++ == '-';
    for (; p < end; ++p) {
        char c = *p;
        if (c >= '0' && c <= '9') {
            if (m > ((uint64_t)1 << 53))
                return NULL;  /* more digits than an exact double holds (m stays far from overflow) */
            digits = 1;
            m = m * 10 + (uint64_t)(c - '0');
            decimals += point;
            if (decimals > 22)
                return NULL;  /* checked per digit: a long run of zeros cannot overflow the count */
        } else if (c == '.' && !point) {
            point = 1;
        } else if (c == d || c == '\n') {
            break;
        } else {
            return NULL;  /* an exponent, blank, NUL, CR, a byte beyond ASCII, another sign... */
        }
    }
    if (p == start) {
        *value = quiet_nan();
        return p;
    }
    if (!digits || m > ((uint64_t)1 << 53))
        return NULL;
    double v = (double)m / POWERS[decimals];
    *value = negative ? -v : v;
    return p;
}

int64_t parse_block(const struct parse_block *a)
{   /* 0 when every line had width fields, each plain or empty, else -1 */
    const char *p = a->text, *end = a->text + a->size;
    double *out = a->out;
    char d = (char)a->delimiter;
    for (int64_t line = 0; line < a->lines; ++line) {
        for (int64_t col = 0; col < a->width; ++col) {
            const char *start = p;
            p = field_value(p, end, d, out++);
            if (p == NULL || (a->width == 1 && p == start))
                return -1;  /* not plain, or a blank line of one column */
            char stop = p < end ? *p : '\n';
            if ((col + 1 < a->width) != (stop == d))
                return -1;  /* a line with another field count */
            if (p < end)
                ++p;
        }
    }
    return p == end ? 0 : -1;
}
