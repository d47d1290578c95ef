/* Rows of numbers as fixed-decimal text, the fast path of ikfusion.number_text in one call.
 *
 * Each value's |v| * 10**d is already rounded by NumPy to an integer below 2**52 (held in a
 * double, exact) and checked to round as Python's "%.<d>f" does; here its digits are written:
 * a '-' when the value's sign bit is set, the integer part without leading zeros (at least one
 * digit), then '.' and the d decimals (none when d is 0). Between the fields, the row format's
 * literal texts. Only integer arithmetic on exact integers: the bytes are those of the NumPy
 * path, by construction.
 */
#include <stdint.h>
#include <string.h>

struct fixed_rows {
    const double *rows;    /* (n * k) the values (their sign bits) */
    const double *whole;   /* (n * k) |v| * 10**d rounded: integers below 2**52 */
    int64_t n;
    int64_t k;
    int64_t decimals;      /* 0..9 */
    const char *literals;  /* the k + 1 literals, concatenated */
    const int64_t *bounds; /* (k + 2) where each literal starts in literals, then the end */
    char *out;             /* room for n * (literal bytes + k * 22) */
    const int64_t *field_decimals;  /* (k) 0..9 per field, or NULL: decimals for all */
};

static const uint64_t UNITS[10] = {1u, 10u, 100u, 1000u, 10000u, 100000u, 1000000u,
    10000000u, 100000000u, 1000000000u};

static const char PAIRS[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

static char *digits(char *at, uint64_t value)
{   /* value in decimal without leading zeros (at least "0"); returns the end */
    if (value < 10) {
        *at = (char)('0' + value);
        return at + 1;
    }
    if (value < 100) {
        memcpy(at, PAIRS + 2 * value, 2);
        return at + 2;
    }
    char tmp[24];
    char *end = tmp + sizeof(tmp), *p = end;
    while (value >= 100) {
        unsigned pair = (unsigned)(value % 100);
        value /= 100;
        p -= 2;
        memcpy(p, PAIRS + 2 * pair, 2);
    }
    if (value >= 10) {
        p -= 2;
        memcpy(p, PAIRS + 2 * value, 2);
    } else {
        *--p = (char)('0' + value);
    }
    memcpy(at, p, (size_t)(end - p));
    return at + (end - p);
}

static char *fraction(char *at, uint64_t value, int64_t count)
{   /* the count last digits of value (below 10**count), leading zeros kept */
    uint32_t v = (uint32_t)value;  /* below 10**9 */
    int64_t i = count;
    while (i >= 2) {
        i -= 2;
        memcpy(at + i, PAIRS + 2 * (v % 100), 2);
        v /= 100;
    }
    if (i) at[0] = (char)('0' + v);
    return at + count;
}

static char *literal(char *at, const char *text, int64_t length)
{   /* the text between two fields (mostly one comma) */
    if (length == 1) {
        *at = *text;
        return at + 1;
    }
    memcpy(at, text, (size_t)length);
    return at + length;
}

#if defined(__GNUC__) || defined(__clang__)
#define ALWAYS_INLINE static inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE static inline
#endif

ALWAYS_INLINE char *field_text(char *at, const double *value, double whole, int64_t decimals,
                               uint64_t unit)
{   /* one field: its sign (from the value's sign bit), integer digits and decimals */
    uint64_t scaled = (uint64_t)whole;
    uint64_t bits;
    memcpy(&bits, value, sizeof(bits));
    if (bits >> 63) *at++ = '-';
    at = digits(at, scaled / unit);
    if (decimals) {
        *at++ = '.';
        at = fraction(at, scaled % unit, decimals);
    }
    return at;
}

ALWAYS_INLINE char *rows_text(const struct fixed_rows *p, int64_t decimals, uint64_t unit)
{   /* called with constant decimals and unit: their divisions become multiplications */
    char *at = p->out;
    const int64_t *b = p->bounds;
    for (int64_t r = 0; r < p->n; ++r) {
        const double *v = p->rows + r * p->k, *w = p->whole + r * p->k;
        for (int64_t f = 0; f < p->k; ++f) {
            at = literal(at, p->literals + b[f], b[f + 1] - b[f]);
            at = field_text(at, v + f, w[f], decimals, unit);
        }
        at = literal(at, p->literals + b[p->k], b[p->k + 1] - b[p->k]);
    }
    return at;
}

static char *mixed_rows_text(const struct fixed_rows *p)
{   /* rows_text with each field's own decimals (e.g. "%.6f" then "%d" fields, as "%.0f") */
    char *at = p->out;
    const int64_t *b = p->bounds;
    for (int64_t r = 0; r < p->n; ++r) {
        const double *v = p->rows + r * p->k, *w = p->whole + r * p->k;
        for (int64_t f = 0; f < p->k; ++f) {
            at = literal(at, p->literals + b[f], b[f + 1] - b[f]);
            int64_t decimals = p->field_decimals[f];
            at = field_text(at, v + f, w[f], decimals, UNITS[decimals]);
        }
        at = literal(at, p->literals + b[p->k], b[p->k + 1] - b[p->k]);
    }
    return at;
}

int64_t fixed_rows(const struct fixed_rows *p)
{   /* returns the bytes written; decimals 0 to 9 */
    char *end;
    if (p->field_decimals)
        return (int64_t)(mixed_rows_text(p) - p->out);
    switch (p->decimals) {
    case 0: end = rows_text(p, 0, 1); break;
    case 1: end = rows_text(p, 1, 10); break;
    case 2: end = rows_text(p, 2, 100); break;
    case 3: end = rows_text(p, 3, 1000); break;
    case 4: end = rows_text(p, 4, 10000); break;
    case 5: end = rows_text(p, 5, 100000); break;
    case 6: end = rows_text(p, 6, 1000000); break;
    case 7: end = rows_text(p, 7, 10000000); break;
    case 8: end = rows_text(p, 8, 100000000); break;
    default: end = rows_text(p, 9, 1000000000); break;
    }
    return (int64_t)(end - p->out);
}
