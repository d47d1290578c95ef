/* The projection onto the contacts' minimum-norm steps in one call (contact_projection.py).

   projection.py's reference loop, for contact rows along the world axes: evaluate the compiled
   points function (CasADi-generated, called through its own pointer) at q, test whether a
   planted point is further than the tolerance from its anchor (the same operations as
   ContactConstraint.slides) and whether every point is above the floor (above_floor); while one
   slides, the shortest step dq = A^T (A A^T)^-1 b on the rows held (A: their linear Jacobian
   rows, b: anchor - position [m]) and q <- q (+) dq, pinocchio's integrate for a free flyer
   (its first joint) and spherical joints.

   Answers: HELD (q projected, the points function's outputs at it), TO_QP (the minimum-norm
   steps did not hold the points or left one below the floor: the QPs take over from the
   start), TO_PYTHON (dependent rows, a number not finite, a failed evaluation: the reference
   path decides from the start). With TO_QP, floor_crossed says the first step crossed a
   linearised floor row: the QPs' closed-form try would fail (the caller skips it). Frames: world; lengths in metres; q as pinocchio's (the
   free flyer's translation, then quaternions x, y, z, w). */

#include <float.h>
#include <math.h>
#include <string.h>

#define HELD 0
#define TO_QP 1
#define TO_PYTHON 2

typedef long long casadi_int;
typedef int (*points_function)(const double **arg, double **res, casadi_int *iw, double *w,
                               int mem);

struct projection {
    points_function points; /* (q, geometry) -> (p_points (3n), J_points nonzeros) */
    const double **arg;     /* its arguments: arg[1] = geometry, set once; arg[0] = q here */
    double **res;           /* its results: res[0] = p_points (3n), res[1] = J nonzeros */
    casadi_int *iw;
    double *w;
    const int *J_row;       /* (J_nnz) row of each Jacobian nonzero among the 3n rows */
    const int *J_col;       /* (J_nnz) its column */
    int J_nnz;
    double *J;              /* (3n, nv) dense, row-major: zero outside the nonzeros */
    int n_points, nq, nv;
    int n_balls;
    const int *ball_q;      /* (n_balls) each spherical joint's first q index */
    const int *ball_v;      /* (n_balls) its first tangent index */
    const unsigned char *active;  /* (n) planted points */
    const unsigned char *free_z;  /* (n) held horizontally only */
    const double *anchors;  /* (n, 3) [m] */
    const unsigned char *enabled; /* (n) points the floor holds */
    double floor_z;         /* [m] */
    double tolerance;       /* [m] */
    int max_steps;
    double *q;              /* (nq) in: the solved configuration; out: the projected one */
    int *rows;              /* (3n) work: the rows held */
    double *S;              /* (3n, 3n) work: A A^T, then its Cholesky factor */
    double *y;              /* (3n) work */
    double *dq;             /* (nv) work */
    int steps;              /* out: the minimum-norm steps taken */
    int floor_crossed;      /* out: the first step crosses a linearised floor row (below) */
};

/* A linearised floor row -J_z dq <= z - floor_z crossed by more than this [m]: far beyond the
   round-off between this step and NumPy's (1e-13), far below a crossing that sends a frame to
   the QPs (the tolerance, 2e-5). */
#define CROSSED 1e-9

/* pinocchio's quaternion::exp3 of the rotation vector v (3,) [rad]: out = (x, y, z, w). */
static void exp3(const double *v, double *out)
{
    const double eps = DBL_EPSILON;
    const double t2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    const double t = sqrt(t2 + eps * eps);
    const double precision = pow(eps, 1.0 / 4.0);
    if (t2 > precision) {  /* Eigen's AngleAxis(t, v / t) as a quaternion */
        const double ha = 0.5 * t, s = sin(ha);
        for (int k = 0; k < 3; ++k)
            out[k] = s * (v[k] / t);
        out[3] = cos(ha);
    } else {  /* order 4 in theta */
        const double h = t2 / 4;
        const double a = 0.5 * (1.0 - h / 6.0 + h * h / 120.0);
        for (int k = 0; k < 3; ++k)
            out[k] = a * v[k];
        out[3] = 1.0 - h / 2 + h * h / 24;
    }
}

/* Hamilton product a b of quaternions (x, y, z, w). */
static void quat_product(const double *a, const double *b, double *out)
{
    out[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
    out[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
    out[1] = a[3] * b[1] + a[1] * b[3] + a[2] * b[0] - a[0] * b[2];
    out[2] = a[3] * b[2] + a[2] * b[3] + a[0] * b[1] - a[1] * b[0];
}

static void cross(const double *a, const double *b, double *out)
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* pinocchio's firstOrderNormalize: q * (3 - |q|^2) / 2. */
static void normalise(double *q)
{
    const double n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    const double alpha = (3.0 - n2) / 2.0;
    for (int k = 0; k < 4; ++k)
        q[k] *= alpha;
}

/* The free flyer's q (7) (+) v (6: linear, angular, in the body frame) as pinocchio's SE(3). */
static void integrate_free_flyer(const double *q, const double *v, double *out)
{
    const double eps = DBL_EPSILON;
    const double *lin = v, *w = v + 3, *quat = q + 3;
    const double t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2] + eps * eps;
    const double t = sqrt(t2), st = sin(t), ct = cos(t), inv_t2 = 1.0 / t2;
    const double precision = pow(eps, 1.0 / 4.0);
    const double a = t < precision ? 0.5 - t2 / 24.0 : (1.0 - ct) * inv_t2;
    const double b = t < precision ? 1.0 / 6.0 - t2 / 120.0 : (t - st) * inv_t2 / t;
    double wxv[3], wxwxv[3], p[3], e[4], uv[3], quv[3], r[4];
    cross(w, lin, wxv);
    cross(w, wxv, wxwxv);
    for (int k = 0; k < 3; ++k)
        p[k] = lin[k] + a * wxv[k] + b * wxwxv[k];
    exp3(w, e);
    cross(quat, p, uv);  /* Eigen's quaternion * vector: v + w uv + vec x uv, uv = 2 vec x v */
    for (int k = 0; k < 3; ++k)
        uv[k] += uv[k];
    cross(quat, uv, quv);
    for (int k = 0; k < 3; ++k)
        out[k] = (p[k] + quat[3] * uv[k] + quv[k]) + q[k];
    quat_product(quat, e, r);
    const double dot = r[0] * quat[0] + r[1] * quat[1] + r[2] * quat[2] + r[3] * quat[3];
    for (int k = 0; k < 4; ++k)
        out[3 + k] = dot < 0 ? -r[k] : r[k];
    normalise(out + 3);
}

/* q (+) dq for a free flyer at q[0:7], v[0:6] and spherical joints (pinocchio's integrate). */
void ik_integrate(int nq, int n_balls, const int *ball_q, const int *ball_v, const double *q,
                  const double *dq, double *out)
{
    memcpy(out, q, sizeof(double) * nq);
    integrate_free_flyer(q, dq, out);
    for (int j = 0; j < n_balls; ++j) {
        double e[4];
        exp3(dq + ball_v[j], e);
        quat_product(q + ball_q[j], e, out + ball_q[j]);
        normalise(out + ball_q[j]);
    }
}

/* Whether a planted point is further than the tolerance from its anchor (2: not finite). */
static int slides(const struct projection *p, const double *P)
{
    int far = 0;
    for (int i = 0; i < 3 * p->n_points; ++i)
        if (!isfinite(P[i]))
            return 2;
    for (int i = 0; i < p->n_points && !far; ++i) {
        if (!p->active[i])
            continue;
        const double *a = p->anchors + 3 * i, *x = P + 3 * i;
        const double dx = x[0] - a[0], dy = x[1] - a[1];
        const double dz = p->free_z[i] ? 0.0 : x[2] - a[2];
        far = sqrt(dx * dx + dy * dy + dz * dz) > p->tolerance;
    }
    return far;
}

static int above_floor(const struct projection *p, const double *P)
{
    for (int i = 0; i < p->n_points; ++i)
        if (P[3 * i + 2] < p->floor_z - p->tolerance)
            return 0;
    return 1;
}

/* The rows held (index among the 3n coordinates), in order: their count. */
static int held_rows(const struct projection *p)
{
    int m = 0;
    for (int i = 0; i < p->n_points; ++i) {
        if (!p->active[i])
            continue;
        p->rows[m++] = 3 * i;
        p->rows[m++] = 3 * i + 1;
        if (!p->free_z[i])
            p->rows[m++] = 3 * i + 2;
    }
    return m;
}

/* y = (A A^T)^-1 b, lower Cholesky; 0 when the rows are (nearly) dependent: the smallest
   squared pivot below 1e-12 of the largest diagonal entry (equality_qp.independent_solve). */
static int independent_solve(const struct projection *p, int m, double *y)
{
    const int nv = p->nv;
    double *S = p->S, largest = 0.0, smallest = INFINITY;
    for (int i = 0; i < m; ++i) {
        const double *ai = p->J + (size_t)p->rows[i] * nv;
        for (int j = 0; j <= i; ++j) {
            const double *aj = p->J + (size_t)p->rows[j] * nv;
            double s = 0.0;
            for (int c = 0; c < nv; ++c)
                s += ai[c] * aj[c];
            S[i * m + j] = s;
        }
        if (S[i * m + i] > largest)
            largest = S[i * m + i];
    }
    for (int j = 0; j < m; ++j) {  /* S = L L^T in place (lower triangle) */
        double d = S[j * m + j];
        for (int k = 0; k < j; ++k)
            d -= S[j * m + k] * S[j * m + k];
        if (!(d > 0.0) || !isfinite(d))
            return 0;
        const double l = sqrt(d);
        S[j * m + j] = l;
        if (l < smallest)
            smallest = l;
        for (int i = j + 1; i < m; ++i) {
            double s = S[i * m + j];
            for (int k = 0; k < j; ++k)
                s -= S[i * m + k] * S[j * m + k];
            S[i * m + j] = s / l;
        }
    }
    if (smallest * smallest < 1e-12 * largest)
        return 0;
    for (int i = 0; i < m; ++i) {  /* L z = b, then L^T y = z */
        double s = y[i];
        for (int k = 0; k < i; ++k)
            s -= S[i * m + k] * y[k];
        y[i] = s / S[i * m + i];
    }
    for (int i = m - 1; i >= 0; --i) {
        double s = y[i];
        for (int k = i + 1; k < m; ++k)
            s -= S[k * m + i] * y[k];
        y[i] = s / S[i * m + i];
    }
    return 1;
}

/* Whether dq crosses a floor row linearised at the points P (k, 3) by more than CROSSED: then
   the QP's closed-form try (equality_qp.equality_optimum, this step to round-off) fails. */
static int crosses_floor(const struct projection *p, const double *P)
{
    const int nv = p->nv;
    for (int i = 0; i < p->n_points; ++i) {
        if (!p->enabled[i])
            continue;
        const double *Jz = p->J + (size_t)(3 * i + 2) * nv;
        double s = 0.0;
        for (int c = 0; c < nv; ++c)
            s += Jz[c] * p->dq[c];
        if (-s - (P[3 * i + 2] - p->floor_z) > CROSSED)
            return 1;
    }
    return 0;
}

/* One minimum-norm step from the evaluated points at q: q updated; 0 on dependent rows. */
static int minimum_norm_step(struct projection *p, const double *P, double *next)
{
    const int nv = p->nv, m = held_rows(p);
    const double *nz = p->res[1];
    for (int k = 0; k < p->J_nnz; ++k)
        p->J[(size_t)p->J_row[k] * nv + p->J_col[k]] = nz[k];
    for (int i = 0; i < m; ++i)
        p->y[i] = p->anchors[p->rows[i]] - P[p->rows[i]];
    if (m == 0 || !independent_solve(p, m, p->y))
        return 0;
    for (int c = 0; c < nv; ++c)
        p->dq[c] = 0.0;
    for (int i = 0; i < m; ++i) {
        const double *a = p->J + (size_t)p->rows[i] * nv, yi = p->y[i];
        for (int c = 0; c < nv; ++c)
            p->dq[c] += a[c] * yi;
    }
    if (p->steps == 0)
        p->floor_crossed = crosses_floor(p, P);
    ik_integrate(p->nq, p->n_balls, p->ball_q, p->ball_v, p->q, p->dq, next);
    memcpy(p->q, next, sizeof(double) * p->nq);
    return 1;
}

/* The minimum-norm loop of projection.project_on_contacts; next: (nq) work. */
int ik_project_contacts(struct projection *p, double *next)
{
    p->steps = 0;
    p->floor_crossed = 0;
    for (int step = 0; step < p->max_steps; ++step) {
        p->arg[0] = p->q;
        if (p->points(p->arg, p->res, p->iw, p->w, 0))
            return TO_PYTHON;
        const double *P = p->res[0];
        const int far = slides(p, P);
        if (far == 2)
            return TO_PYTHON;
        if (!far)
            return above_floor(p, P) ? HELD : TO_QP;
        if (!minimum_norm_step(p, P, next))
            return TO_PYTHON;
        p->steps = step + 1;
    }
    return TO_QP;
}
