/* A frame's smoothed sensed contact points and what they say (ikfusion.ik.sensed_evidence).
 *
 * What ikfusion.ik.sensed_evidence.python_evidence computes with NumPy and Python floats at the
 * start of ContactTracker.release, in one call, with the same operations in the same order (so
 * the same numbers, bit for bit: IEEE products, sums and quotients, no contraction into fused
 * multiply-adds, see the pragma and the volatile below), for k points:
 *
 *     p = a * p_old + b * p_new            (k, 3) [m], b = 1 - a
 *     pitch = a * pitch_old + b * pitch_new  (k) [rad]
 *     step = p - p_old                     (k, 3) [m]
 *     velocity = step / dt                 (k, 3) [m/s], only when dt > 0
 *     lowest = min of p[:, 2] (NaN when any is)
 *     height = p[:, 2] - lowest            (k) [m]
 *
 * written to out (11 k: p, pitch, step, velocity, height), and as bits (bit i: point i):
 * far = the rest points with z > lowest + far, low = height < enter, high = height > leave,
 * tilted = the heels with pitch > tilt and the toes with pitch < -tilt (NaN compares false).
 */
#include <math.h>

#pragma STDC FP_CONTRACT OFF

struct sensed {
    const double *p_new, *pitch_new;  /* (k, 3), (k): this frame's sensed points and pitches */
    const double *p_old, *pitch_old;  /* the last frame's smoothed ones */
    double *out;  /* (11 k) the output */
    const int *rest, *heels, *toes;  /* point indices */
    int n_rest, n_heels, n_toes, k;
    double a, b, dt, far, enter, leave, tilt;
    long long far_bits, low, high, tilted;  /* the answers */
};

void ik_sensed_evidence(struct sensed *s)
{
    const int k = s->k;
    double *p = s->out, *pitch = p + 3 * k, *step = pitch + k, *v = step + 3 * k;
    double *height = v + 3 * k;
    for (int i = 0; i < 3 * k; i++) {
        volatile double old = s->a * s->p_old[i];  /* rounded, as NumPy's */
        volatile double now = s->b * s->p_new[i];
        p[i] = old + now;
        step[i] = p[i] - s->p_old[i];
        if (s->dt > 0.0)
            v[i] = step[i] / s->dt;
    }
    for (int i = 0; i < k; i++) {
        volatile double old = s->a * s->pitch_old[i];
        volatile double now = s->b * s->pitch_new[i];
        pitch[i] = old + now;
    }
    double lowest = p[2];
    for (int i = 0; i < k && !isnan(lowest); i++) {
        double z = p[3 * i + 2];
        if (isnan(z) || z < lowest)
            lowest = z;
    }
    long long low = 0, high = 0, far = 0, tilted = 0;
    for (int i = 0; i < k; i++) {
        height[i] = p[3 * i + 2] - lowest;
        if (height[i] < s->enter)
            low |= 1LL << i;
        if (height[i] > s->leave)
            high |= 1LL << i;
    }
    volatile double far_z = lowest + s->far;
    for (int j = 0; j < s->n_rest; j++)
        if (p[3 * s->rest[j] + 2] > far_z)
            far |= 1LL << s->rest[j];
    for (int j = 0; j < s->n_heels; j++)
        if (pitch[s->heels[j]] > s->tilt)
            tilted |= 1LL << s->heels[j];
    for (int j = 0; j < s->n_toes; j++)
        if (pitch[s->toes[j]] < -s->tilt)
            tilted |= 1LL << s->toes[j];
    s->far_bits = far;
    s->low = low;
    s->high = high;
    s->tilted = tilted;
}
