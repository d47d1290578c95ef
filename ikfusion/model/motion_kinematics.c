/* Frame placements of a whole motion: ikfusion.model.motion_kinematics.frame_placements in C.
 *
 * For each configuration, every planned joint is composed as the NumPy path does it
 * (oMi = oMparent * jointPlacement * joint(q), Eigen's quaternion matrix, each 3x3 product's
 * sums in Eigen's order), then each frame (oMf = oMi * frame.placement): the same operations in
 * the same order (no contraction into fused multiply-adds), so the same numbers. Free-flyer and
 * spherical joints only (the caller runs NumPy for any other). Matrices are row-major.
 */
#include <stdint.h>

#pragma STDC FP_CONTRACT OFF

struct placements {
    const double *q;          /* (n, nq) configurations, quaternions x, y, z, w */
    int64_t n, nq;
    int64_t joints;           /* planned joints, parents first (slot 0 is the world) */
    const int64_t *plan;      /* (joints, 4): free flyer (1) or spherical (0), idx_q,
                                 parent slot (0: the world), placement rotated (0/1) */
    const double *placement;  /* (joints, 12): the joint placement's R (9) then t (3) */
    int64_t frames;
    const int64_t *frame_plan;       /* (frames, 2): joint slot, placement rotated (0/1) */
    const double *frame_placement;   /* (frames, 12): R (9) then t (3) */
    double *work;             /* ((joints + 1) * 12): each slot's R_world (9) and p_world (3) */
    double *p_out;            /* (n, frames, 3) [m] */
    double *R_out;            /* (n, frames, 9) */
};

static void quat_matrix(const double *v, double *R)
{   /* v = (x, y, z, w), as given (not normalised): Eigen's toRotationMatrix */
    double x = v[0], y = v[1], z = v[2], w = v[3];
    double tx = 2.0 * x, ty = 2.0 * y, tz = 2.0 * z;
    double twx = tx * w, twy = ty * w, twz = tz * w;
    double txx = tx * x, txy = ty * x, txz = tz * x;
    double tyy = ty * y, tyz = tz * y, tzz = tz * z;
    R[0] = 1.0 - (tyy + tzz);
    R[1] = txy - twz;
    R[2] = txz + twy;
    R[3] = txy + twz;
    R[4] = 1.0 - (txx + tzz);
    R[5] = tyz - twx;
    R[6] = txz - twy;
    R[7] = tyz + twx;
    R[8] = 1.0 - (txx + tyy);
}

static void rot_rot(const double *A, const double *B, double *out)
{   /* out = A @ B, each sum (A[r,0] B[0,c] + A[r,1] B[1,c]) + A[r,2] B[2,c] */
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
            double a = A[3 * r] * B[c], b = A[3 * r + 1] * B[3 + c], d = A[3 * r + 2] * B[6 + c];
            double ab = a + b;
            out[3 * r + c] = ab + d;
        }
}

static void rot_vec(const double *A, const double *v, double *out)
{   /* out = A @ v, summed in the same order */
    for (int r = 0; r < 3; ++r) {
        double a = A[3 * r] * v[0], b = A[3 * r + 1] * v[1], d = A[3 * r + 2] * v[2];
        double ab = a + b;
        out[r] = ab + d;
    }
}

static void compose_joint(const struct placements *p, const double *qk, int64_t j)
{   /* slot j + 1 from its parent's slot */
    const int64_t *plan = p->plan + 4 * j;
    const double *placement = p->placement + 12 * j;
    double *R = p->work + 12 * (j + 1), *pos = R + 9;
    const double *parent = p->work + 12 * plan[2];
    double R_motion[9], R_local[9], p_local[3];
    int64_t i = plan[1];
    quat_matrix(plan[0] ? qk + i + 3 : qk + i, R_motion);
    if (plan[3]) rot_rot(placement, R_motion, R_local);
    else for (int e = 0; e < 9; ++e) R_local[e] = R_motion[e];
    if (plan[0]) {  /* free flyer: translation + (placement R) p_motion */
        double moved[3];
        if (plan[3]) rot_vec(placement, qk + i, moved);
        else for (int e = 0; e < 3; ++e) moved[e] = qk[i + e];
        for (int e = 0; e < 3; ++e) p_local[e] = placement[9 + e] + moved[e];
    } else {
        for (int e = 0; e < 3; ++e) p_local[e] = placement[9 + e];
    }
    if (plan[2] == 0) {
        for (int e = 0; e < 9; ++e) R[e] = R_local[e];
        for (int e = 0; e < 3; ++e) pos[e] = p_local[e];
        return;
    }
    double turned[3];
    rot_rot(parent, R_local, R);
    rot_vec(parent, p_local, turned);
    for (int e = 0; e < 3; ++e) pos[e] = parent[9 + e] + turned[e];
}

int64_t frame_placements(const struct placements *p)
{
    double *world = p->work;  /* slot 0: identity, origin */
    for (int e = 0; e < 12; ++e) world[e] = (e == 0 || e == 4 || e == 8) ? 1.0 : 0.0;
    for (int64_t k = 0; k < p->n; ++k) {
        const double *qk = p->q + k * p->nq;
        for (int64_t j = 0; j < p->joints; ++j) compose_joint(p, qk, j);
        for (int64_t f = 0; f < p->frames; ++f) {
            const int64_t *plan = p->frame_plan + 2 * f;
            const double *placement = p->frame_placement + 12 * f;
            const double *slot = p->work + 12 * plan[0];
            double *R = p->R_out + 9 * (k * p->frames + f);
            double *pos = p->p_out + 3 * (k * p->frames + f), turned[3];
            if (plan[1]) rot_rot(slot, placement, R);
            else for (int e = 0; e < 9; ++e) R[e] = slot[e];
            rot_vec(slot, placement + 9, turned);
            for (int e = 0; e < 3; ++e) pos[e] = slot[9 + e] + turned[e];
        }
    }
    return 0;
}
