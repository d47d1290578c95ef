/* Rotation matrices to unit quaternions (w, x, y, z), w >= 0: the NumPy formulas of
 * ikfusion.rotations.matrix_to_quat_wxyz (_quat_wxyz_at_once) in C, the same operations in the
 * same order (no contraction into fused multiply-adds): the same numbers. Finite matrices only
 * (the caller runs NumPy otherwise). Matrices row-major.
 */
#include <math.h>
#include <stdint.h>

#pragma STDC FP_CONTRACT OFF

struct quats {
    const double *R;  /* (n, 9) */
    int64_t n;
    double *q;        /* (n, 4) w, x, y, z */
};

int64_t matrix_quats(const struct quats *p)
{
    for (int64_t k = 0; k < p->n; ++k) {
        const double *M = p->R + 9 * k;
        double m00 = M[0], m01 = M[1], m02 = M[2], m10 = M[3], m11 = M[4], m12 = M[5];
        double m20 = M[6], m21 = M[7], m22 = M[8];
        double a = m21 - m12, b = m02 - m20, c = m10 - m01;
        double d = m01 + m10, e = m02 + m20, f = m12 + m21;
        double t[4];
        t[0] = ((1.0 + m00) + m11) + m22;
        t[1] = ((1.0 + m00) - m11) - m22;
        t[2] = ((1.0 - m00) + m11) - m22;
        t[3] = ((1.0 - m00) - m11) + m22;
        int branch = 0;  /* the first largest, as argmax */
        for (int i = 1; i < 4; ++i)
            if (t[i] > t[branch]) branch = i;
        double w, x, y, z;
        switch (branch) {
        case 0: w = t[0]; x = a; y = b; z = c; break;
        case 1: w = a; x = t[1]; y = d; z = e; break;
        case 2: w = b; x = d; y = t[2]; z = f; break;
        default: w = c; x = e; y = f; z = t[3]; break;
        }
        double ww = w * w, xx = x * x, yy = y * y, zz = z * z;
        double s1 = ww + xx, s2 = s1 + yy, s3 = s2 + zz;
        double norm = sqrt(s3);
        double *q = p->q + 4 * k;
        q[0] = w / norm;
        q[1] = x / norm;
        q[2] = y / norm;
        q[3] = z / norm;
        if (q[0] < 0.0) {
            q[0] = -q[0];
            q[1] = -q[1];
            q[2] = -q[2];
            q[3] = -q[3];
        }
    }
    return 0;
}
