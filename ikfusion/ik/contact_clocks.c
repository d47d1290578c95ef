/* A touch-down's contact clocks and settled anchors (ikfusion.ik.contact_clocks).
 *
 * What ikfusion.ik.contact_clocks.python_clocks computes with NumPy for the points planted
 * before the touch-down (bit i of `was`: point i), in one call, with the same operations (so
 * the same numbers, bit for bit: IEEE sums and NumPy's maximum and minimum, see np_max):
 *
 *     released = where(was, released, released + step)   (k) [s]
 *     age = where(was, age + step, 0.0)                   (k) [s]
 *
 * and, when `settle` is set (no planted point shares its rigid segment with another), the
 * anchors' heights lowered by at most `drop` toward the floor, each point alone
 * (ikfusion.ik.anchor_settling.settled_heights):
 *
 *     own = minimum(maximum(z - floor_z, 0.0), drop)
 *     z = maximum(z - own, floor_z)                      [m]
 *
 * (none when drop >= 0 and every height is floor_z, bit for bit), written to out (5 k:
 * released, age, anchors (k, 3)); `changed` says whether a height's bits changed.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#pragma STDC FP_CONTRACT OFF

struct clocks {
    const double *released, *age, *anchors;  /* (k), (k), (k, 3): the state's */
    double *out;  /* (5 k) the output */
    long long was;  /* the points planted before the touch-down */
    int k, settle;
    double step, drop, floor_z;
    int changed;  /* the answer: an anchor's height changed */
};

/* np.maximum / np.minimum of two doubles: NaN if either is, else the second when equal. */
static double np_max(double a, double b) { return (a > b || isnan(a)) ? a : b; }
static double np_min(double a, double b) { return (a < b || isnan(a)) ? a : b; }

static int same_bits(double a, double b)
{
    uint64_t x, y;
    memcpy(&x, &a, sizeof x);
    memcpy(&y, &b, sizeof y);
    return x == y;
}

void ik_contact_clocks(struct clocks *s)
{
    const int k = s->k;
    double *released = s->out, *age = released + k, *anchors = age + k;
    for (int i = 0; i < k; i++) {
        int planted = (int)(s->was >> i & 1);
        released[i] = planted ? s->released[i] : s->released[i] + s->step;
        age[i] = planted ? s->age[i] + s->step : 0.0;
    }
    memcpy(anchors, s->anchors, 3 * (size_t)k * sizeof(double));
    s->changed = 0;
    if (!s->settle)
        return;
    int on_floor = s->drop >= 0.0;
    for (int i = 0; i < k && on_floor; i++)
        on_floor = same_bits(s->anchors[3 * i + 2], s->floor_z);
    if (on_floor)
        return;
    for (int i = 0; i < k; i++) {
        double z = s->anchors[3 * i + 2];
        double own = np_min(np_max(z - s->floor_z, 0.0), s->drop);
        anchors[3 * i + 2] = np_max(z - own, s->floor_z);
        if (!same_bits(anchors[3 * i + 2], z))
            s->changed = 1;
    }
}
