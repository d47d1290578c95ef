"""Closed-form first fixes with no prior, batched over transmissions.

:func:`bancroft`: for reader m at ``s_m`` (its x, y part in 2-D), pseudo-range ``y_m`` (toa
minus the reader's clock offset) and unknowns ``x = (p, tau)``, squaring
``(y_m - tau)^2 = ||s_m - p||^2 + dz_m^2`` gives, with the Lorentz product
``<a, b> = a_p . b_p - a_tau b_tau``::

    <b_m, x> = alpha_m + lambda,   b_m = (s_m, -y_m),
    alpha_m = (||s_m||^2 + dz_m^2 - y_m^2) / 2,   lambda = <x, x> / 2,

where ``dz_m`` is the reader's height above the known tag height (2-D) or 0 (3-D). The weighted
least-squares solution is ``x = u + lambda v`` (``u``, ``v`` solve the normal equations for
``alpha`` and for a column of ones), and ``lambda`` solves the scalar quadratic
``<v, v>/2 lambda^2 + (<u, v> - 1) lambda + <u, u>/2 = 0``. Of the two roots the one that fits
the measured ranges better is kept (on a tie, the one nearer the readers' centroid). With the
clock fixed (two-way ranges) the time component is dropped and the product is Euclidean. It
needs as many readers as unknowns (4 in 3-D, 3 in 2-D with the clock; one fewer without).

:func:`subset_starts`: the same closed form on random subsets of receptions, keeping the
candidate that agrees with the most receptions (RANSAC), for transmissions where NLOS delays
pulled the all-reception solution into a wrong basin.

Reference: S. Bancroft, "An algebraic solution of the GPS equations", IEEE Trans. Aerospace and
Electronic Systems 21(1), 1985.
"""

from __future__ import annotations

import numpy as np

from .linalg import solve_batched


def bancroft(
    s_world_readers: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    *,
    dims: int,
    clock: bool,
    height: np.ndarray,
    late_c: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form fix per transmission (batched): the better of the two roots.

    Args:
        s_world_readers: Reader positions, shape (M, 3) [m] (centred, see
            :func:`bancroft_roots`).
        y: Pseudo-ranges, shape (T, M) [m].
        weights: Measurement weights (inverse variances), shape (T, M) [1/m^2]; 0 for missing.
        dims: 3 (unknown height) or 2 (known height).
        clock: Whether the transmit time is a parameter.
        height: Known tag height per transmission (centred), shape (T,) [m].
        late_c: When given, the root is chosen by a one-sided robust cost: normalised residuals
            later than ``late_c`` count logarithmically (NLOS delays cannot pull the choice to
            the spurious root); otherwise by the weighted sum of squares.

    Returns:
        ``(x, ok)``: parameters ``(px, py[, pz][, tau])`` shape (T, k), and whether a finite
        root was found.
    """
    roots, ok = bancroft_roots(s_world_readers, y, weights, dims=dims, clock=clock, height=height)
    x, found = _choose_root(roots, s_world_readers, y, weights, dims, clock, height, late_c)
    return x, ok & found


def bancroft_roots(
    s_world_readers: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    *,
    dims: int,
    clock: bool,
    height: np.ndarray,
) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Both closed-form roots per transmission (batched).

    Coordinates should be centred on the readers and ``y`` shifted per transmission so that
    values stay small (the squares lose precision otherwise).

    Args:
        s_world_readers: Reader positions, shape (M, 3) [m] (centred).
        y: Pseudo-ranges (toa minus reader clock offsets), shape (T, M) [m]; any value where the
            weight is 0.
        weights: Measurement weights (inverse variances), shape (T, M) [1/m^2]; 0 for
            missing or rejected.
        dims: 3 (unknown height) or 2 (known height).
        clock: True when the transmit time is unknown (a parameter), False when it is zero.
        height: Known tag height per transmission (centred), shape (T,) [m]; used when dims=2.

    Returns:
        ``((x1, x2), ok)``: the two candidate parameter vectors ``(px, py[, pz][, tau])``,
        each shape (T, k) (NaN or inf where a root does not exist), and whether the normal
        equations were solvable.
    """
    t_count, m_count = y.shape
    k = dims + int(clock)
    y0 = np.where(weights > 0, y, 0.0)
    spatial = s_world_readers[:, :dims]
    cols = [np.broadcast_to(spatial[None, :, i], (t_count, m_count)) for i in range(dims)]
    if clock:
        cols.append(-y0)
    if dims == 2:
        dz2 = (s_world_readers[None, :, 2] - height[:, None]) ** 2
    else:
        dz2 = np.zeros((1, m_count))
    alpha = 0.5 * (np.sum(spatial**2, axis=1)[None] + dz2 - y0**2)
    normal = np.empty((t_count, k, k))
    rhs = np.empty((t_count, k, 2))
    for i in range(k):
        wi = weights * cols[i]
        rhs[:, i, 0] = np.einsum("tm,tm->t", wi, alpha)
        rhs[:, i, 1] = wi.sum(axis=1)
        for j in range(i, k):
            normal[:, i, j] = normal[:, j, i] = np.einsum("tm,tm->t", wi, cols[j])
    sol, ok = solve_batched(normal, rhs)
    u, v = sol[..., 0], sol[..., 1]
    metric = np.ones(k)
    if clock:
        metric[dims] = -1.0
    qa = 0.5 * np.sum(metric * v * v, axis=1)
    qb = np.sum(metric * u * v, axis=1) - 1.0
    qc = 0.5 * np.sum(metric * u * u, axis=1)
    disc = np.maximum(qb * qb - 4.0 * qa * qc, 0.0)
    q = -0.5 * (qb + np.copysign(np.sqrt(disc), qb))
    with np.errstate(divide="ignore", invalid="ignore"):
        lam1 = np.where(qa != 0.0, q / qa, np.inf)
        lam2 = np.where(q != 0.0, qc / q, 0.0)
    with np.errstate(invalid="ignore", over="ignore"):
        roots = (u + lam1[:, None] * v, u + lam2[:, None] * v)
    return roots, ok


def _choose_root(
    roots: tuple[np.ndarray, np.ndarray],
    s_world_readers: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    dims: int,
    clock: bool,
    height: np.ndarray,
    late_c: float | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The root that fits better (a tie within one chi-square unit: nearer the centroid)."""
    t_count, k = roots[0].shape
    y0 = np.where(weights > 0, y, 0.0)
    best = np.zeros((t_count, k))
    best_cost = np.full(t_count, np.inf)
    best_norm = np.full(t_count, np.inf)
    for x in roots:
        with np.errstate(invalid="ignore", over="ignore"):
            cost = _cost(x, s_world_readers, y0, weights, dims, clock, height, late_c)
            norm = np.linalg.norm(x[:, :dims], axis=1)
            # Costs within one chi-square unit are a tie (e.g. the two exact intersections of
            # a minimal set): keep the root nearer the readers' centroid.
            tie = np.abs(cost - best_cost) <= 1.0
            better = (cost < best_cost - 1.0) | (tie & (norm < best_norm))
        best[better] = x[better]
        best_cost[better] = cost[better]
        best_norm[better] = norm[better]
    return best, np.isfinite(best_cost)


def _cost(
    x: np.ndarray,
    s: np.ndarray,
    y: np.ndarray,
    w: np.ndarray,
    dims: int,
    clock: bool,
    height: np.ndarray,
    late_c: float | None,
) -> np.ndarray:
    """Cost of candidate fixes, shape (T,): squared normalised residuals, late ones robustified.

    With ``late_c`` a normalised residual ``r > late_c`` costs ``c^2 (1 + 2 log(r / c))``,
    the loss whose IRLS weight is ``(c / r)^2``.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        d2 = (x[:, 0, None] - s[None, :, 0]) ** 2 + (x[:, 1, None] - s[None, :, 1]) ** 2
        z = x[:, 2] if dims == 3 else height
        d2 = d2 + (z[:, None] - s[None, :, 2]) ** 2
        pred = np.sqrt(d2) + (x[:, dims, None] if clock else 0.0)
        r = (y - pred) * np.sqrt(w)
        loss = r * r
        if late_c is not None:
            c = late_c
            loss = np.where(r > c, c * c * (1.0 + 2.0 * np.log(np.maximum(r, c) / c)), loss)
        cost = np.sum(np.where(w > 0, loss, 0.0), axis=1)
    return np.where(np.isfinite(cost), cost, np.inf)


def subset_starts(
    s_world_readers: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    *,
    dims: int,
    clock: bool,
    height: np.ndarray,
    late_c: float,
    subsets: int = 64,
    extra: int = 0,
    seed: int = 0,
) -> np.ndarray:
    """Robust starts from random subsets of receptions (RANSAC with the closed form).

    For each transmission, ``subsets`` random sets of ``k + extra`` receptions are solved with
    :func:`bancroft_roots`; every root is scored on all receptions with the one-sided robust
    cost of :func:`bancroft` (late residuals count logarithmically, early ones quadratically,
    so a root that makes receptions arrive early loses), and the best root wins. Minimal sets
    (``extra=0``) are most likely to be free of NLOS: with 4 of 12 receptions delayed, 64 sets
    of 4 contain a clean one with probability 0.9999. Draws come from a fixed seed, so results
    are reproducible.

    Args:
        s_world_readers: Reader positions, shape (M, 3) [m] (centred).
        y: Pseudo-ranges, shape (T, M) [m].
        weights: Measurement weights (inverse variances), shape (T, M) [1/m^2]; 0 for missing.
        dims: 3 or 2 (known height).
        clock: Whether the transmit time is a parameter.
        height: Known tag height per transmission (centred), shape (T,) [m].
        late_c: One-sided robust threshold [normalised residual].
        subsets: Subsets drawn per transmission.
        extra: Receptions per subset beyond the ``k`` unknowns.
        seed: Seed of the draws.

    Returns:
        Parameters ``(px, py[, pz][, tau])`` per transmission, shape (T, k); NaN where no
        subset could be solved.
    """
    t_count, m_count = y.shape
    k = dims + int(clock)
    rng = np.random.default_rng(seed)
    out = np.full((t_count, k), np.nan)
    chunk = max(1, 200_000 // max(subsets, 1))
    for first in range(0, t_count, chunk):
        rows = slice(first, min(first + chunk, t_count))
        n = rows.stop - rows.start
        w = weights[rows]
        keys = np.where(w[:, None, :] > 0, rng.random((n, subsets, m_count)), np.inf)
        rank = np.argsort(np.argsort(keys, axis=2), axis=2)
        pick = (rank < k + extra) & np.isfinite(keys)
        flat_w = (pick * w[:, None, :]).reshape(n * subsets, m_count)
        flat_y = np.repeat(y[rows], subsets, axis=0)
        flat_h = np.repeat(height[rows], subsets)
        all_w = np.repeat(w, subsets, axis=0)
        roots, ok = bancroft_roots(
            s_world_readers, flat_y, flat_w, dims=dims, clock=clock, height=flat_h
        )
        best = np.full((n, k), np.nan)
        best_cost = np.full(n, np.inf)
        for x in roots:
            cost = _cost(x, s_world_readers, flat_y, all_w, dims, clock, flat_h, late_c)
            cost = np.where(ok, cost, np.inf).reshape(n, subsets)
            j = np.argmin(cost, axis=1)
            c = cost[np.arange(n), j]
            better = c < best_cost
            best[better] = x.reshape(n, subsets, k)[np.arange(n), j][better]
            best_cost[better] = c[better]
        out[rows] = best
    return out


def _normalised(
    x: np.ndarray,
    s: np.ndarray,
    y: np.ndarray,
    w: np.ndarray,
    dims: int,
    clock: bool,
    height: np.ndarray,
) -> np.ndarray:
    """Normalised residuals ``(y - pred) sqrt(w)`` of candidate fixes, shape (T, M)."""
    with np.errstate(invalid="ignore", over="ignore"):
        d2 = (x[:, 0, None] - s[None, :, 0]) ** 2 + (x[:, 1, None] - s[None, :, 1]) ** 2
        z = x[:, 2] if dims == 3 else height
        d2 = d2 + (z[:, None] - s[None, :, 2]) ** 2
        pred = np.sqrt(d2) + (x[:, dims, None] if clock else 0.0)
        return np.where(w > 0, (y - pred) * np.sqrt(w), 0.0)
