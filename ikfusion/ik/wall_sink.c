/* How far each anatomical angle would sink past its limits (ikfusion.ik.wall_sink).
 *
 * What ikfusion.ik.limits.soft_wall.SoftWall.update computes with NumPy before its test
 * "does any angle reach a limit", in one call, with the same operations in the same order
 * (so the same numbers, bit for bit: IEEE products and sums, no contraction into fused
 * multiply-adds, see the pragma and the volatile below):
 *
 *     sunk[0] = (angle - upper) * grow + (angle - before) * drift
 *     sunk[1] = (-angle - (-lower)) * grow - (angle - before) * drift
 *
 * for every angle (count of them), written to sunk (2 * count, the upper limits' rows first).
 * limit holds upper then -lower (2 * count). Returns 1 when some entry is above 0 and none is
 * NaN (NumPy's max is then above 0), else 0.
 */
#include <math.h>

#pragma STDC FP_CONTRACT OFF

struct wall {
    const double *now, *before;  /* (count) the angles of the last frame and the frame before */
    const double *limit;  /* (2 * count) upper, then -lower [rad] */
    double *sunk;  /* (2 * count) the output */
    double grow, drift;  /* the factors of the sink and of the angles' change */
    int count;
};

int ik_wall_sink(const struct wall *w)
{
    int reaches = 0, nan = 0;
    for (int i = 0; i < w->count; i++) {
        double a = w->now[i];
        volatile double moved = (a - w->before[i]) * w->drift;  /* rounded, as NumPy's */
        volatile double up = (a - w->limit[i]) * w->grow;
        volatile double down = (-a - w->limit[w->count + i]) * w->grow;
        double s_up = up + moved, s_down = down - moved;
        w->sunk[i] = s_up;
        w->sunk[w->count + i] = s_down;
        nan |= isnan(s_up) || isnan(s_down);
        reaches |= s_up > 0.0 || s_down > 0.0;
    }
    return reaches && !nan;
}
