/* Joint angles made continuous frame by frame: ikfusion.model.angle_continuity's rule in C.
 *
 * Each joint's (a1, a2, a3) [rad] per frame, in place. The first frame is kept; every later
 * frame takes, of its triple and the other triple of the same rotation (a1 + pi, pi - a2,
 * a3 + pi), each angle shifted by whole turns to lie within pi of the previous result, the one
 * nearer to the previous result (sum of squared differences; a tie keeps the triple itself).
 * A frame holding a non-finite angle is kept as it is and is no reference. The operations are
 * the NumPy path's, in the same order (no contraction into fused multiply-adds): the same
 * numbers.
 */
#include <math.h>
#include <stdint.h>

#pragma STDC FP_CONTRACT OFF

struct series {
    double *angles;  /* (frames, joints, 3) [rad], rewritten in place */
    int64_t frames;
    int64_t joints;
};

static const double PI = 3.141592653589793;
static const double TURN = 2.0 * 3.141592653589793;

static double near(double angle, double reference)
{   /* angle shifted by whole turns to lie within pi of reference (rint: halves to even) */
    double turns = nearbyint((reference - angle) / TURN);
    double shift = TURN * turns;
    return angle + shift;
}

static int finite3(const double *a)
{
    return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
}

static double squares(const double *a, const double *r)
{   /* ((a0 - r0)**2 + (a1 - r1)**2) + (a2 - r2)**2 */
    double d0 = a[0] - r[0], d1 = a[1] - r[1], d2 = a[2] - r[2];
    double s0 = d0 * d0, s1 = d1 * d1, s2 = d2 * d2;
    double s01 = s0 + s1;
    return s01 + s2;
}

static void joint_series(double *x, int64_t frames, int64_t step)
{   /* one joint: x[k * step + i] is angle i at frame k */
    const double *previous = x;
    int known = finite3(x);
    for (int64_t k = 1; k < frames; ++k) {
        double *row = x + k * step;
        if (!known || !finite3(row)) {
            if (!known && finite3(row)) {
                previous = row;
                known = 1;
            }
            continue;
        }
        double same[3], other[3];
        for (int i = 0; i < 3; ++i) same[i] = near(row[i], previous[i]);
        other[0] = near(row[0] + PI, previous[0]);
        other[1] = near(PI - row[1], previous[1]);
        other[2] = near(row[2] + PI, previous[2]);
        const double *chosen = squares(other, previous) < squares(same, previous) ? other : same;
        row[0] = chosen[0];
        row[1] = chosen[1];
        row[2] = chosen[2];
        previous = row;
    }
}

int64_t continuous_series(const struct series *p)
{
    for (int64_t j = 0; j < p->joints; ++j)
        joint_series(p->angles + 3 * j, p->frames, 3 * p->joints);
    return 0;
}
