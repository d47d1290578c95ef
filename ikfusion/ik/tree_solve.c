/* The closed-form optimum of a step's QP on the kinematic tree's sparsity (ikfusion.ik.tree_solve).
 *
 * minimise 1/2 x^T H x + c^T x subject to A x = b, with H factored leaves first as
 * H = U D U^T (U unit upper triangular, D diagonal): column k of U holds the tree ancestors of
 * tangent column k only (anc[ptr[k]] .. anc[ptr[k+1]-1], in decreasing order), so no entry fills
 * in. The equality rows go through the Schur complement S = A H^-1 A^T = V^T D^-1 V with
 * V = U^-1 A^T, factored by a dense Cholesky S = L L^T.
 *
 * packed: H (n x n, row-major, symmetric: its lower triangle read), c (n), G (m_in x n), h (m_in),
 * A (m_eq x n), b (m_eq), as ikfusion.ik.qp.QpBuffer lays them out.
 * The plan: ptr and anc, off: the lower-triangle offsets (row * n + column) of H outside the tree
 * pattern (n_off of them), x: the minimiser (n), work: at least ptr[n] + 2 n +
 * m_eq * (2 n + m_eq + 2) doubles.
 *
 * Returns 0: x is the minimiser and satisfies G x <= h; 1: x is the minimiser but crosses a row
 * of G x <= h; 2: H is not positive definite or the equality rows are (nearly) dependent (the
 * smallest squared pivot of S below dependent_rows times its largest diagonal entry), or x is
 * not finite; 3: H has a nonzero outside the tree pattern (nothing solved); 4: the sum of every
 * packed number, taken in NumPy's order (pairwise_sum), is not finite (a NaN or an infinity, or
 * finite numbers overflowing it; nothing solved).
 */
#include <float.h>
#include <math.h>
#include <string.h>

/* Two doubles added, multiplied lane by lane (SSE2 on x86-64; each lane's arithmetic is the
 * scalar one). */
typedef double pair __attribute__((vector_size(16)));
typedef long long bits __attribute__((vector_size(16)));

static pair load(const double *at)
{
    pair v;
    memcpy(&v, at, sizeof v);
    return v;
}

/* U is stored packed: column k's entries U[anc[i], k] at L[i] for i in ptr[k] .. ptr[k+1]-1
 * (the nearest ancestor first). An ancestor's own ancestors are the rest of the list
 * (anc[ptr[a] ..] == anc[i + 1 .. ptr[k+1]) for a = anc[i]), so updating column a from
 * column k runs over two contiguous ranges. */

static void upper_solve(int n, const int *ptr, const int *anc, const double *L, double *z)
{   /* z <- U^-1 z, leaves first (z[k] is final once every descendant of k is done) */
    for (int k = n - 1; k >= 0; --k) {
        const double zk = z[k];
        if (zk == 0.0) continue;
        for (int i = ptr[k]; i < ptr[k + 1]; ++i) z[anc[i]] -= L[i] * zk;
    }
}

static void upper_transpose_solve(int n, const int *ptr, const int *anc, const double *L,
                                  double *y)
{   /* y <- U^-T y, root first */
    for (int k = 0; k < n; ++k) {
        double s = y[k];
        for (int i = ptr[k]; i < ptr[k + 1]; ++i) s -= L[i] * y[anc[i]];
        y[k] = s;
    }
}

static int factor(int n, const int *ptr, const int *anc, const double *H,
                  double *restrict L, double *restrict D, double *restrict t)
{   /* L and D <- the tree entries of H's lower triangle, then U (packed) and D; t: n scratch */
    for (int k = 0; k < n; ++k) {
        const double *row = H + (long)k * n;
        D[k] = row[k];
        for (int i = ptr[k]; i < ptr[k + 1]; ++i) L[i] = row[anc[i]];
    }
    for (int k = n - 1; k >= 0; --k) {
        const double d = D[k];
        if (!(d > 0.0)) return 0;
        const int first = ptr[k], count = ptr[k + 1] - first;
        double *restrict Lk = L + first;
        memcpy(t, Lk, sizeof(double) * (size_t)count);  /* H_ak after the deeper columns */
        {                                   /* and U_ak: independent divisions, two at once */
            const pair dd = {d, d};
            int i = 0;
            for (; i + 2 <= count; i += 2) {
                const pair q = load(Lk + i) / dd;
                memcpy(Lk + i, &q, sizeof q);
            }
            for (; i < count; ++i) Lk[i] /= d;
        }
        for (int i = 0; i < count; ++i) {
            const double u = Lk[i];
            if (u == 0.0) continue;         /* most of U is zero on a step's H (about 240 of its
                                             * 1116 entries on the real walk): subtracting 0 * t
                                             * changes no number but the sign of a zero */
            const int a = anc[first + i];
            D[a] -= u * t[i];
            double *restrict La = L + ptr[a];  /* its count - i - 1 entries */
            for (int j = i + 1; j < count; ++j) La[j - i - 1] -= u * t[j];
        }
    }
    return 1;
}

static double pairwise_sum(const double *a, long n)
{   /* NumPy's add.reduce of a contiguous array (its pairwise sum: eight running sums over
     * blocks of at most 128 numbers, longer spans halved), the sum qp._check_finite takes; its
     * independent additions run several times faster than one running sum (the eight sums
     * held in four SSE2 pairs: each lane's additions are the same, in the same order) */
    if (n < 8) {
        double s = 0.0;
        for (long i = 0; i < n; ++i) s += a[i];
        return s;
    }
    if (n <= 128) {
        pair r0 = load(a), r1 = load(a + 2), r2 = load(a + 4), r3 = load(a + 6);
        long i;
        for (i = 8; i < n - n % 8; i += 8) {
            r0 += load(a + i); r1 += load(a + i + 2);
            r2 += load(a + i + 4); r3 += load(a + i + 6);
        }
        double s = ((r0[0] + r0[1]) + (r1[0] + r1[1])) + ((r2[0] + r2[1]) + (r3[0] + r3[1]));
        for (; i < n; ++i) s += a[i];
        return s;
    }
    long half = n / 2;
    half -= half % 8;
    return pairwise_sum(a, half) + pairwise_sum(a + half, n - half);
}

static void dots(const double *v, const double *W, int n, int count, double *out)
{   /* out[j] += v . W[j] (rows of n) for j < count, each a running sum from out[j] in k
     * order; four at once (four independent running sums: the same numbers, a quarter of the
     * latency) */
    int j = 0;
    for (; j + 4 <= count; j += 4) {
        const double *w0 = W + (long)j * n, *w1 = w0 + n, *w2 = w1 + n, *w3 = w2 + n;
        double s0 = out[j], s1 = out[j + 1], s2 = out[j + 2], s3 = out[j + 3];
        for (int k = 0; k < n; ++k) {
            const double vk = v[k];
            s0 += vk * w0[k]; s1 += vk * w1[k]; s2 += vk * w2[k]; s3 += vk * w3[k];
        }
        out[j] = s0; out[j + 1] = s1; out[j + 2] = s2; out[j + 3] = s3;
    }
    for (; j < count; ++j) {
        const double *w = W + (long)j * n;
        double s = out[j];
        for (int k = 0; k < n; ++k) s += v[k] * w[k];
        out[j] = s;
    }
}

static void divide(double *restrict out, const double *num, const double *den, int n)
{   /* out[k] = num[k] / den[k], two at a time (each lane's division is the scalar one) */
    int k = 0;
    for (; k + 2 <= n; k += 2) {
        const pair q = load(num + k) / load(den + k);
        memcpy(out + k, &q, sizeof q);
    }
    for (; k < n; ++k) out[k] = num[k] / den[k];
}

/* What stays from call to call (ikfusion.ik.tree_solve.TreeClosedForm._Plan, same layout). */
struct plan {
    const int *ptr, *anc;
    const long *off;
    double *x, *work;
    double dependent_rows;
    int n, n_off;
};

int ik_tree_closed_form(const struct plan *p, int m_in, int m_eq, const double *packed)
{
    const int n = p->n, n_off = p->n_off, *ptr = p->ptr, *anc = p->anc;
    const long *off = p->off;
    const double dependent_rows = p->dependent_rows;
    double *x = p->x, *work = p->work;
    const double *H = packed, *c = H + (long)n * n, *G = c + n, *h = G + (long)m_in * n;
    const double *A = h + m_in, *b = A + (long)m_eq * n;
    if (!isfinite(pairwise_sum(packed, (long)(b + m_eq - packed)))) return 4;
    for (int i = 0; i < n_off; ++i)
        if (H[off[i]] != 0.0) return 3;
    double *F = work, *D = F + ptr[n], *g = D + n, *V = g + n, *W = V + (long)m_eq * n;
    double *S = W + (long)m_eq * n;
    double *r = S + (long)m_eq * m_eq, *lambda = r + m_eq;
    if (!factor(n, ptr, anc, H, F, D, g)) return 2;
    for (int k = 0; k < n; ++k) x[k] = -c[k];
    upper_solve(n, ptr, anc, F, x);
    for (int k = 0; k < n; ++k) x[k] /= D[k];
    upper_transpose_solve(n, ptr, anc, F, x);          /* x = -H^-1 c */
    if (m_eq > 0) {
        double largest = 0.0, smallest = INFINITY;
        memcpy(V, A, sizeof(double) * (size_t)m_eq * (size_t)n);
        for (int i = 0; i < m_eq; ++i) r[i] = -b[i];
        dots(x, V, n, m_eq, r);                         /* r = A x0 - b */
        for (int i = 0; i < m_eq; ++i) {
            double *v = V + (long)i * n;
            upper_solve(n, ptr, anc, F, v);
            divide(W + (long)i * n, v, D, n);           /* W = D^-1 V */
        }
        for (int i = 0; i < m_eq; ++i) {                /* S = V^T D^-1 V, lower triangle */
            double *row = S + (long)i * m_eq;
            for (int j = 0; j <= i; ++j) row[j] = 0.0;
            dots(V + (long)i * n, W, n, i + 1, row);
        }
        for (int i = 0; i < m_eq; ++i)
            if (S[(long)i * m_eq + i] > largest) largest = S[(long)i * m_eq + i];
        for (int j = 0; j < m_eq; ++j) {                /* S = L L^T in place (lower) */
            double d = S[(long)j * m_eq + j];
            for (int k = 0; k < j; ++k) d -= S[(long)j * m_eq + k] * S[(long)j * m_eq + k];
            if (!(d > 0.0)) return 2;
            if (d < smallest) smallest = d;
            const double l = sqrt(d);
            S[(long)j * m_eq + j] = l;
            for (int i = j + 1; i < m_eq; ++i) {
                double s = S[(long)i * m_eq + j];
                for (int k = 0; k < j; ++k) s -= S[(long)i * m_eq + k] * S[(long)j * m_eq + k];
                S[(long)i * m_eq + j] = s / l;
            }
        }
        if (smallest < dependent_rows * largest) return 2;
        for (int i = 0; i < m_eq; ++i) {                /* lambda = S^-1 r */
            double s = r[i];
            for (int k = 0; k < i; ++k) s -= S[(long)i * m_eq + k] * lambda[k];
            lambda[i] = s / S[(long)i * m_eq + i];
        }
        for (int i = m_eq - 1; i >= 0; --i) {
            double s = lambda[i];
            for (int k = i + 1; k < m_eq; ++k) s -= S[(long)k * m_eq + i] * lambda[k];
            lambda[i] = s / S[(long)i * m_eq + i];
        }
        for (int k = 0; k < n; ++k) g[k] = 0.0;         /* x -= H^-1 A^T lambda */
        for (int i = 0; i < m_eq; ++i)
            for (int k = 0; k < n; ++k) g[k] += W[(long)i * n + k] * lambda[i];
        upper_transpose_solve(n, ptr, anc, F, g);
        for (int k = 0; k < n; ++k) x[k] -= g[k];
    }
    double total = 0.0;
    for (int k = 0; k < n; ++k) total += x[k];
    if (!isfinite(total)) return 2;
    for (int i = 0; i < m_in; ++i) {
        double s = 0.0;
        for (int k = 0; k < n; ++k) s += G[(long)i * n + k] * x[k];
        if (!(s <= h[i])) return 1;
    }
    return 0;
}


/* The common step of ikfusion.ik.active_set.solve_with_active_set, after the closed form:
 * the range rows left out of the QP and the velocity bounds tested as its Python loop tests
 * them (ikfusion.ik.tree_solve.TreeClosedForm._Active, same layout).
 * G: (angles x n, row-major) every range row's rates; rooms: room_up (angles) then room_down
 * (angles); up, down: (angles) whether a row is in the QP (1) or left out (0); bounds: lb (n)
 * then ub (n) when has_bounds; tolerance: how far a row or a bound may be passed. */
struct active {
    const double *G, *rooms, *bounds;
    const unsigned char *up, *down;
    double tolerance;
    int angles, has_bounds;
};

/* Whether rate > limit + tolerance (1) or not (0), or -1 when a different summation order of
 * the rate (BLAS's gemv in the Python loop) could decide otherwise: the rate is within the
 * worst rounding of any order of it (n products summed: n * DBL_EPSILON / 2 of the sum of
 * their magnitudes, taken twice for the two orders and doubled for margin) of the threshold,
 * or not a number. */
static int passes(double rate, double magnitude, double threshold, int n)
{
    const double guard = (2.0 * n + 4.0) * DBL_EPSILON * magnitude + DBL_MIN;
    const double gap = rate - threshold;
    if (!(fabs(gap) > guard)) return -1;
    return gap > 0.0;
}

/* The dot product of row and x (n) and the sum of its terms' magnitudes (in *magnitude): eight
 * running sums of each, in pairs, for a latency of a quarter of one sum's. */
static double rate_of(const double *row, const double *x, int n, double *magnitude)
{
    const pair zero = {0.0, 0.0};
    const bits sign = {0x7fffffffffffffffLL, 0x7fffffffffffffffLL};
    pair r0 = zero, r1 = zero, r2 = zero, r3 = zero, m0 = zero, m1 = zero, m2 = zero, m3 = zero;
    int k = 0;
    for (; k + 8 <= n; k += 8) {
        const pair t0 = load(row + k) * load(x + k), t1 = load(row + k + 2) * load(x + k + 2);
        const pair t2 = load(row + k + 4) * load(x + k + 4);
        const pair t3 = load(row + k + 6) * load(x + k + 6);
        r0 += t0; r1 += t1; r2 += t2; r3 += t3;
        m0 += (pair)((bits)t0 & sign); m1 += (pair)((bits)t1 & sign);
        m2 += (pair)((bits)t2 & sign); m3 += (pair)((bits)t3 & sign);
    }
    const pair rs = (r0 + r1) + (r2 + r3), ms = (m0 + m1) + (m2 + m3);
    double rate = rs[0] + rs[1], sum = ms[0] + ms[1];
    for (; k < n; ++k) {
        const double t = row[k] * x[k];
        rate += t;
        sum += fabs(t);
    }
    *magnitude = sum;
    return rate;
}

/* The left-out range rows crossed and the bounds passed by x (the plan's): 0: none, 5: one is
 * (or a summation order could decide that one is): the Python loop decides. */
int ik_active_check(const struct plan *p, const struct active *a)
{
    const int n = p->n, angles = a->angles;
    const double *x = p->x, tolerance = a->tolerance;
    for (int i = 0; i < angles; ++i) {
        if (a->up[i] && a->down[i]) continue;
        double magnitude;
        const double rate = rate_of(a->G + (long)i * n, x, n, &magnitude);
        if (!a->up[i] && passes(rate, magnitude, a->rooms[i] + tolerance, n) != 0) return 5;
        if (!a->down[i] && passes(-rate, magnitude, a->rooms[angles + i] + tolerance, n) != 0)
            return 5;
    }
    if (a->has_bounds) {
        const double *lb = a->bounds, *ub = lb + n;
        for (int k = 0; k < n; ++k)
            if (x[k] < lb[k] - tolerance || x[k] > ub[k] + tolerance) return 5;
    }
    return 0;
}

/* ik_tree_closed_form, then, when it solved (0), ik_active_check of its x: 0 (x is the step)
 * or 5 (the Python loop goes on from x); else the closed form's own answer (1 to 4). */
int ik_active_step(const struct plan *p, const struct active *a, int m_in, int m_eq,
                   const double *packed)
{
    const int answer = ik_tree_closed_form(p, m_in, m_eq, packed);
    return answer != 0 ? answer : ik_active_check(p, a);
}


/* The least-distance form of the packed QP (ikfusion.ik.least_distance) on the tree factor:
 * H = L L^T with L = U D^1/2, u = L^T x + v, v = L^-1 c; the rows C = [G; A] become
 * M = C L^-T (m_in + m_eq rows of n, into M) with bounds upper = [h; b] + M v and
 * lower = [-1e30; b] + M v. v is left in x and D^1/2 in work (for ik_least_distance_step).
 * Returns 0, or 2 (H not positive definite) or 3 (H off the tree pattern): nothing usable. */
static void scaled_solve(const struct plan *p, const double *root, double *z)
{   /* z <- D^-1/2 U^-1 z */
    upper_solve(p->n, p->ptr, p->anc, p->work, z);
    for (int k = 0; k < p->n; ++k) z[k] /= root[k];
}

int ik_least_distance(const struct plan *p, int m_in, int m_eq, const double *packed,
                      double *M, double *upper, double *lower)
{
    const int n = p->n, m = m_in + m_eq;
    const double *H = packed, *c = H + (long)n * n, *G = c + n, *h = G + (long)m_in * n;
    const double *A = h + m_in, *b = A + (long)m_eq * n;
    double *x = p->x, *F = p->work, *D = F + p->ptr[n], *root = D + n;
    for (int i = 0; i < p->n_off; ++i)
        if (H[p->off[i]] != 0.0) return 3;
    if (!factor(n, p->ptr, p->anc, H, F, D, root)) return 2;
    for (int k = 0; k < n; ++k) root[k] = sqrt(D[k]);
    memcpy(x, c, sizeof(double) * (size_t)n);
    scaled_solve(p, root, x);                            /* v */
    memcpy(M, G, sizeof(double) * (size_t)m_in * (size_t)n);
    memcpy(M + (long)m_in * n, A, sizeof(double) * (size_t)m_eq * (size_t)n);
    for (int i = 0; i < m; ++i) {
        scaled_solve(p, root, M + (long)i * n);
        upper[i] = 0.0;
    }
    dots(x, M, n, m, upper);                             /* M v */
    for (int i = 0; i < m; ++i) {
        const double mv = upper[i];
        upper[i] = (i < m_in ? h[i] : b[i - m_in]) + mv;
        lower[i] = (i < m_in ? -1e30 : b[i - m_in]) + mv;
    }
    return 0;
}

/* The step x = L^-T (u - v) = U^-T D^-1/2 (u - v) from DAQP's u after ik_least_distance (v in
 * x): 0, or 2 when it is not finite. */
int ik_least_distance_step(const struct plan *p, const double *u)
{
    const int n = p->n;
    double *x = p->x, *F = p->work, *root = F + p->ptr[n] + n, total = 0.0;
    for (int k = 0; k < n; ++k) x[k] = (u[k] - x[k]) / root[k];
    upper_transpose_solve(n, p->ptr, p->anc, F, x);
    for (int k = 0; k < n; ++k) total += x[k];
    return isfinite(total) ? 0 : 2;
}
