/* A Gauss-Newton step's QP written from the evaluated step function (ikfusion.ik.step_rows).
 *
 * What ikfusion.ik.frame_problem.build_frame_problem does with NumPy after the compiled step
 * function's evaluation, in one call, in the same order and with the same operations: the
 * ranges' rooms softened (the soft wall's room added) with endless room for the angles whose
 * rates are all 0, the masks of the limits within the margin; H (its nonzeros scattered) and c;
 * the site targets', the root's and the swing feet's position rows (scalar weights) added; the
 * damping term and the Levenberg-Marquardt diagonal; then into the packed QP (ikfusion.ik.qp.QpBuffer: H, c,
 * G, h, A, b) the range rows near a limit (upper ones, then lower ones negated), the floor rows
 * and the contacts' equality rows; and the velocity bounds from the step's move since the previous
 * frame (ikfusion.ik.limits.velocity.VelocityLimit.bounds). The only difference from NumPy is the
 * summation order of the position rows' products (BLAS's J^T W J): round-off.
 *
 * Matrices are row-major. A sparse output is its nonzeros nz and their flat positions flat
 * (row * columns + column); J's rows are read through a CSR index (J_ptr, J_col, J_at).
 * Returns the range rows written (below); n_up: how many of them are upper limits.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

struct points {  /* a position task with scalar weights (w I) */
    int on, count;  /* count: its frames (the sites, or the contact points) */
    double scale;  /* the task's weight */
    const double *weight, *targets;  /* (count) each frame's w, (count * 3) [m] */
};

struct step_rows {
    /* the step function's outputs (constant per function) */
    const double *H_nz; const int *H_flat; int H_nnz;  /* H_flat (2 H_nnz): H's lower triangle
                                                          then the same entries mirrored */
    const double *c_nz; const int *c_flat; int c_nnz;
    const double *P;  /* (sites * 3): a dense vector */
    const double *J_nz; const int *J_ptr; const int *J_col; const int *J_at;  /* CSR of J */
    const double *G_nz; const int *G_flat; int G_nnz; double *G;  /* G: (angles, nv) dense */
    const int *rate_rows;  /* (angles, 3) positions among G's nonzeros */
    const double *rooms_raw;  /* (2 * angles) room_up then room_down */
    const int *contact_site;  /* (contacts) each contact point's row among the sites */
    int nv, angles, root_site;
    /* outputs */
    double *rooms; unsigned char *close; double *packed; double *work;
    int n_up;
    /* this call */
    const double *wall_room;  /* (2 * angles) or NULL: hard limits */
    double margin;
    const int64_t *floor_rows; int n_floor; double floor_z;  /* floor_rows: contacts * 3 indices */
    const int64_t *held_rows; int n_held; const double *anchors;  /* anchors: (contacts * 3) */
    int root_on; double root_weight; const double *root_target;  /* (3) */
    struct points site_task, swing;  /* the site targets (every site), the swing feet */
    const double *damping; const double *moved;  /* (nv) each, damping NULL: none */
    double levenberg_marquardt;
    const double *span; double *bounds;  /* (nv) v_max dt, or NULL: no bounds here;
                                            (2 * nv) lb then ub, from moved */
};

static double minimum_zero(double x)
{   /* np.minimum(x, 0.0): x when below or NaN, else the second operand (+0.0) */
    return (x < 0.0 || isnan(x)) ? x : 0.0;
}

static double maximum_zero(double x)
{   /* np.maximum(x, 0.0): x when above or NaN, else the second operand (+0.0) */
    return (x > 0.0 || isnan(x)) ? x : 0.0;
}

static void velocity_bounds(const struct step_rows *p)
{   /* lb = min(-span - moved, 0), ub = max(span - moved, 0): VelocityLimit.bounds */
    for (int i = 0; i < p->nv; ++i) {
        p->bounds[i] = minimum_zero(-p->span[i] - p->moved[i]);
        p->bounds[p->nv + i] = maximum_zero(p->span[i] - p->moved[i]);
    }
}

static void J_row(const struct step_rows *p, int r, double *out)
{   /* row r of J, dense (nv) */
    memset(out, 0, sizeof(double) * p->nv);
    for (int i = p->J_ptr[r]; i < p->J_ptr[r + 1]; ++i) out[p->J_col[i]] = p->J_nz[p->J_at[i]];
}

static int site_row(const struct step_rows *p, int64_t contact_row)
{   /* a row (contact * 3 + axis) of the contact points as a row of the sites' J and P */
    return 3 * p->contact_site[contact_row / 3] + (int)(contact_row % 3);
}

static void add_position_rows(const struct step_rows *p, int rows, const double *J,
                              const double *w, const double *e, double *H, double *c)
{   /* H += J^T W J and c += J^T W e for rows (rows, nv), row weights w and errors e */
    const int nv = p->nv;
    double *WJ = p->work + (long)rows * nv;
    for (int k = 0; k < rows; ++k)
        for (int j = 0; j < nv; ++j) WJ[(long)k * nv + j] = w[k] * J[(long)k * nv + j];
    for (int i = 0; i < nv; ++i) {
        int any = 0;
        for (int k = 0; k < rows; ++k) any |= J[(long)k * nv + i] != 0.0;
        if (!any) continue;  /* (J^T W J's row i: exact zeros) */
        for (int j = 0; j < nv; ++j) {
            double s = 0.0;
            for (int k = 0; k < rows; ++k) s += J[(long)k * nv + i] * WJ[(long)k * nv + j];
            H[(long)i * nv + j] += s;
        }
    }
    for (int j = 0; j < nv; ++j) {
        double s = 0.0;
        for (int k = 0; k < rows; ++k) s += e[k] * WJ[(long)k * nv + j];
        c[j] += s;
    }
}

static void add_points(const struct step_rows *p, const struct points *task, const int *site,
                       double *H, double *c)
{   /* a position task's rows (its frames with a nonzero weight; site: each frame's row among
     * the sites, NULL: the sites themselves), at most 64 frames */
    double *J = p->work, w[3 * 64], e[3 * 64];
    int rows = 0;
    for (int s = 0; s < task->count && rows < 3 * 64; ++s) {
        if (task->weight[s] == 0.0) continue;
        for (int k = 0; k < 3; ++k, ++rows) {
            const int r = 3 * (site ? site[s] : s) + k;
            J_row(p, r, J + (long)rows * p->nv);
            w[rows] = task->scale * task->weight[s];
            e[rows] = p->P[r] - task->targets[3 * s + k];
        }
    }
    add_position_rows(p, rows, J, w, e, H, c);
}

static int ranges(struct step_rows *p)
{   /* the softened rooms, endless for still angles, and the masks within the margin */
    const int n = p->angles;
    int below = 0, n_up = 0;
    for (int a = 0; a < n; ++a) {
        const int *at = p->rate_rows + 3 * a;
        const int still = !(p->G_nz[at[0]] != 0.0 || p->G_nz[at[1]] != 0.0
                            || p->G_nz[at[2]] != 0.0);
        for (int side = 0; side < 2; ++side) {
            const int i = side * n + a;
            double room = p->rooms_raw[i];
            if (p->wall_room) room = room + p->wall_room[i];
            if (still) room = INFINITY;
            p->rooms[i] = room;
            p->close[i] = room < p->margin;
            below += p->close[i];
            if (side == 0) n_up += p->close[i];
        }
    }
    p->n_up = n_up;
    return below;
}

int ik_step_rows(struct step_rows *p)
{
    const int nv = p->nv, n = p->angles;
    if (p->span) velocity_bounds(p);
    for (int k = 0; k < p->G_nnz; ++k) p->G[p->G_flat[k]] = p->G_nz[k];
    const int below = ranges(p);
    const int m_in = below + p->n_floor;
    double *H = p->packed, *c = H + (long)nv * nv, *G = c + nv, *h = G + (long)m_in * nv;
    double *A = h + m_in, *b = A + (long)p->n_held * nv;
    for (int i = 0; i < p->n_floor; ++i) {  /* the floor rows, after the range rows */
        const int r = site_row(p, p->floor_rows[i]);
        double *row = G + (long)(below + i) * nv;
        J_row(p, r, row);
        for (int j = 0; j < nv; ++j) row[j] = -row[j];
        h[below + i] = p->P[r] - p->floor_z;
    }
    for (int i = 0; i < p->n_held; ++i) {
        const int r = site_row(p, p->held_rows[i]);
        J_row(p, r, A + (long)i * nv);
        b[i] = p->anchors[p->held_rows[i]] - p->P[r];
    }
    memset(H, 0, sizeof(double) * nv * nv);
    for (int k = 0; k < p->H_nnz; ++k) {
        const double v = p->H_nz[k];
        H[p->H_flat[k]] = v;
        H[p->H_flat[p->H_nnz + k]] = v;
    }
    memset(c, 0, sizeof(double) * nv);
    for (int k = 0; k < p->c_nnz; ++k) c[p->c_flat[k]] = p->c_nz[k];
    if (p->site_task.on) add_points(p, &p->site_task, NULL, H, c);
    if (p->root_on) {
        double *J = p->work, w[3], e[3];
        for (int k = 0; k < 3; ++k) {
            J_row(p, 3 * p->root_site + k, J + (long)k * nv);
            w[k] = p->root_weight;
            e[k] = p->P[3 * p->root_site + k] - p->root_target[k];
        }
        add_position_rows(p, 3, J, w, e, H, c);
    }
    if (p->damping)
        for (int i = 0; i < nv; ++i) {
            H[(long)i * nv + i] += p->damping[i];
            c[i] += p->damping[i] * p->moved[i];
        }
    if (p->swing.on) add_points(p, &p->swing, p->contact_site, H, c);
    for (int i = 0; i < nv; ++i) H[(long)i * nv + i] += p->levenberg_marquardt;
    int up = 0, down = p->n_up;
    for (int a = 0; a < n; ++a) {  /* the upper limits' rows, then the lower ones' negated */
        const double *row = p->G + (long)a * nv;
        if (p->close[a]) {
            memcpy(G + (long)up * nv, row, sizeof(double) * nv);
            h[up++] = p->rooms[a];
        }
        if (p->close[n + a]) {
            double *out = G + (long)down * nv;
            for (int j = 0; j < nv; ++j) out[j] = -row[j];
            h[down++] = p->rooms[n + a];
        }
    }
    return below;
}
