"""The joint calibration problem in CasADi: readers, clocks, wand and transmit times together.

Every reception ``i`` (transmission ``k`` from emitter position ``e_k``, heard by reader ``m``)
has the residual and cost (all in metres)::

    r_i = toa_i - (tau_k + ||p_m - e_k|| + b_m),      cost = sum_i w_i r_i^2 / 2,

where ``e_k`` is a wand position (3 unknowns per wand transmission) or, for the calibration tag
inside reader ``j``, that reader's own position ``p_j``; ``tau_k`` is one unknown per
transmission, ``b_m`` the reader clock offsets and ``w_i = 1 / sigma^2`` for kept receptions,
0 for rejected ones. The weights are a parameter of the NLP, so NLOS rejection rounds re-solve
without rebuilding it. Reader heights are known: only the horizontal reader positions are
unknowns. Each ``toa_i`` is shifted by the earliest reception of its transmission (the caller
does that), so the ``tau`` unknowns stay small whatever the clock epoch.

The decision vector is ``x = [x_1, y_1, ..., x_M, y_M, b_1 .. b_M, wand positions (x, y, z per
transmission), tau of wand transmissions, tau of reader-tag transmissions]``. The gauge (origin
reader at x = y = 0, axis reader at y = 0, origin clock 0) and the unknowns of transmissions left
out are fixed through equal bounds, which IPOPT removes from the problem.

The cost is one CasADi SX expression; IPOPT receives its exact gradient and exact sparse
Hessian (CasADi's automatic differentiation with sparsity detection). Residuals and their
Jacobian are also computed in closed form with numpy (:meth:`CalibrationNlp.residuals`,
:meth:`CalibrationNlp.jacobian`) for rejection rounds and covariances.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spla

#: IPOPT return statuses accepted as converged.
_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass(frozen=True)
class Layout:
    """Offsets of the unknowns in the decision vector.

    Attributes:
        readers: Number of readers M.
        wand: Number of wand transmissions W.
        tags: Number of reader-tag transmissions T.
    """

    readers: int
    wand: int
    tags: int

    @property
    def clock(self) -> int:
        """Offset of the clock offsets ``b``."""
        return 2 * self.readers

    @property
    def wand_position(self) -> int:
        """Offset of the wand positions (x, y, z per transmission)."""
        return 3 * self.readers

    @property
    def wand_tau(self) -> int:
        """Offset of the wand transmit times."""
        return self.wand_position + 3 * self.wand

    @property
    def tag_tau(self) -> int:
        """Offset of the reader-tag transmit times."""
        return self.wand_tau + self.wand

    @property
    def size(self) -> int:
        """Length of the decision vector."""
        return self.tag_tau + self.tags

    def reader_xy(self, m: np.ndarray) -> np.ndarray:
        """Indices of horizontal reader positions, shape (len(m), 2)."""
        return 2 * np.asarray(m, dtype=np.int64)[:, None] + np.arange(2)

    def wand_xyz(self, k: np.ndarray) -> np.ndarray:
        """Indices of wand positions, shape (len(k), 3)."""
        return self.wand_position + 3 * np.asarray(k, dtype=np.int64)[:, None] + np.arange(3)

    def tau(self, k: np.ndarray) -> np.ndarray:
        """Index of the transmit time of problem transmission ``k`` (wand first, then tags)."""
        k = np.asarray(k, dtype=np.int64)
        return np.where(k < self.wand, self.wand_tau + k, self.tag_tau + (k - self.wand))

    def transmission_unknowns(self, k: int) -> np.ndarray:
        """Every unknown of problem transmission ``k`` (position and transmit time)."""
        if k < self.wand:
            return np.append(self.wand_xyz(np.array([k]))[0], self.wand_tau + k)
        return np.array([self.tag_tau + k - self.wand])

    def pack(
        self,
        p_xy_readers: np.ndarray,
        clocks: np.ndarray,
        p_wand: np.ndarray,
        tau: np.ndarray,
    ) -> np.ndarray:
        """The decision vector from reader x, y (M, 2), clocks (M,), wand (W, 3), tau (W + T,)."""
        return np.concatenate([p_xy_readers.ravel(), clocks, p_wand.ravel(), tau]).astype(float)

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(p_xy_readers (M, 2), clocks (M,), p_wand (W, 3), tau (W + T,))``."""
        m = self.readers
        return (
            x[: 2 * m].reshape(m, 2),
            x[self.clock : self.clock + m],
            x[self.wand_position : self.wand_tau].reshape(self.wand, 3),
            x[self.wand_tau :],
        )


@dataclass(frozen=True)
class Receptions:
    """The receptions of the joint problem.

    Attributes:
        transmission: Problem transmission of each reception (wand ones first), shape (N,).
        reader: Receiving reader, shape (N,).
        emitter: Reader whose calibration tag sent it, or -1 for the wand, shape (N,).
        toa: Shifted time of arrival, shape (N,) [m].
    """

    transmission: np.ndarray
    reader: np.ndarray
    emitter: np.ndarray
    toa: np.ndarray

    @property
    def size(self) -> int:
        """Number of receptions N."""
        return int(self.toa.shape[0])

    @property
    def wand(self) -> np.ndarray:
        """Which receptions come from the wand, shape (N,) bool."""
        return self.emitter < 0


@dataclass(frozen=True)
class SolveResult:
    """One IPOPT run.

    Attributes:
        x: The solution (decision vector).
        status: IPOPT's return status.
        iterations: IPOPT iterations.
        success: Whether IPOPT converged.
    """

    x: np.ndarray
    status: str
    iterations: int
    success: bool


class CalibrationNlp:
    """The joint problem over a fixed set of receptions (weights and bounds vary per solve).

    Args:
        layout: The decision vector's layout.
        receptions: The receptions.
        heights: Known reader heights, shape (M,) [m].
        max_iterations: IPOPT iteration limit per solve.
        tolerance: IPOPT convergence tolerance.
    """

    def __init__(
        self,
        layout: Layout,
        receptions: Receptions,
        heights: np.ndarray,
        *,
        max_iterations: int = 200,
        tolerance: float = 1e-8,
    ) -> None:
        self.layout = layout
        self.receptions = receptions
        self.heights = np.asarray(heights, dtype=float)
        self.max_iterations = int(max_iterations)
        self.tolerance = float(tolerance)
        # Coordinates index the extended vector [x; heights]: known heights are entries too.
        rec = receptions
        nx = layout.size
        wand = rec.wand
        emit = np.empty((rec.size, 3), dtype=np.int64)
        emit[wand] = layout.wand_xyz(rec.transmission[wand])
        emit[~wand, :2] = layout.reader_xy(rec.emitter[~wand])
        emit[~wand, 2] = nx + rec.emitter[~wand]
        self._emitter_index = emit
        self._reader_index = np.column_stack([layout.reader_xy(rec.reader), nx + rec.reader])
        self._clock_index = layout.clock + rec.reader
        self._tau_index = layout.tau(rec.transmission)

    # ------------------------------------------------------------------ numpy model

    def _geometry(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Emitter-minus-reader vectors (N, 3) and their lengths (N,) at ``x`` [m]."""
        extended = np.concatenate([x, self.heights])
        diff = extended[self._emitter_index] - extended[self._reader_index]
        return diff, np.sqrt(np.sum(diff**2, axis=1))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Residuals ``toa - predicted`` of every reception at ``x``, shape (N,) [m]."""
        x = np.asarray(x, dtype=float)
        _, dist = self._geometry(x)
        return self.receptions.toa - (x[self._tau_index] + dist + x[self._clock_index])

    def jacobian(self, x: np.ndarray) -> sps.csr_matrix:
        """Jacobian of the residuals with respect to the decision vector, sparse (N, nx)."""
        x = np.asarray(x, dtype=float)
        diff, dist = self._geometry(x)
        u = diff / np.maximum(dist, 1e-9)[:, None]
        n = self.receptions.size
        rows = np.arange(n)
        nx = self.layout.size
        on_x = np.concatenate([self._reader_index, self._emitter_index], axis=1) < nx
        coords = np.concatenate([self._reader_index, self._emitter_index], axis=1)[on_x]
        slopes = np.concatenate([u, -u], axis=1)[on_x]
        parts = [
            (rows, self._tau_index, -np.ones(n)),
            (rows, self._clock_index, -np.ones(n)),
            (np.repeat(rows, 6).reshape(n, 6)[on_x], coords, slopes),
        ]
        r, c, v = (np.concatenate(k) for k in zip(*parts))
        return sps.csr_matrix((v, (r, c)), shape=(n, nx))

    # ------------------------------------------------------------------ CasADi problem

    @cached_property
    def _local_index(self) -> np.ndarray:
        """Extended-vector index of the 8 local unknowns of each reception, shape (N, 8).

        Order: emitter (x, y, z), reader (x, y, z), transmit time, clock offset.
        """
        return np.column_stack(
            [self._emitter_index, self._reader_index, self._tau_index, self._clock_index]
        )

    def _mapped(self, x: ca.MX, weight: ca.MX, part: str) -> list[ca.MX]:
        """Outputs of one reception function mapped over all receptions, each (k, N).

        Args:
            x: The decision vector.
            weight: Reception weights, shape (N,) [1/m^2].
            part: ``"cost"``, ``"gradient"`` or ``"hessian"``.
        """
        extended = ca.vertcat(x, ca.DM(self.heights))
        n = self.receptions.size
        local = ca.reshape(extended[self._local_index.ravel().tolist()], 8, n)
        mapped = self._functions[part].map(n)
        out = mapped(local, ca.DM(self.receptions.toa).T, weight.T)
        return list(out) if isinstance(out, tuple | list) else [out]

    @cached_property
    def _functions(self) -> dict[str, ca.Function]:
        return reception_functions()

    @cached_property
    def derivatives(self) -> tuple[ca.Function, ca.Function]:
        """The gradient and (upper-triangular) Hessian functions IPOPT receives.

        ``calibration_gradient(x, p) -> (f, grad_f_x)`` and ``calibration_hessian(x, p, lam_f,
        lam_g) -> triu_hess_gamma_x_x``, with ``p`` the reception weights.

        Local gradients and Hessians of every reception are scattered into the global ones by
        constant sparse matrices, so the Hessian's sparsity is known without graph colouring
        (every reception touches the reader unknowns, which makes colouring slow).
        """
        nx = self.layout.size
        x = ca.MX.sym("x", nx)
        weight = ca.MX.sym("weight", self.receptions.size)
        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", 0)
        cost, grad_local = self._mapped(x, weight, "gradient")
        (hess_local,) = self._mapped(x, weight, "hessian")
        index = self._local_index
        on_x = (index < nx).ravel()  # entries on known heights drop out
        slots = np.flatnonzero(on_x)
        gather = sps.csc_matrix(
            (np.ones(slots.size), (index.ravel()[on_x], slots)), shape=(nx, index.size)
        )
        grad = ca.mtimes(_casadi_sparse(gather), ca.vec(grad_local))
        pattern, scatter = _hessian_scatter(index, nx)
        hess = ca.MX(pattern, ca.mtimes(_casadi_sparse(scatter), ca.vec(hess_local)))
        grad_f = ca.Function(
            "calibration_gradient", [x, weight], [ca.sum2(cost), grad], ["x", "p"],
            ["f", "grad_f_x"],
        )  # fmt: skip
        hess_lag = ca.Function(
            "calibration_hessian",
            [x, weight, lam_f, lam_g],
            [lam_f * hess],
            ["x", "p", "lam_f", "lam_g"],
            ["triu_hess_gamma_x_x"],
        )
        return grad_f, hess_lag

    @cached_property
    def solver(self) -> ca.Function:
        """The IPOPT solver (built on first use; the reception weights are its parameter)."""
        grad_f, hess_lag = self.derivatives
        x = ca.MX.sym("x", self.layout.size)
        weight = ca.MX.sym("weight", self.receptions.size)
        cost = ca.sum2(self._mapped(x, weight, "cost")[0])
        options: dict[str, Any] = {
            "grad_f": grad_f,
            "hess_lag": hess_lag,
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": self.max_iterations,
            "ipopt.tol": self.tolerance,
        }
        problem = {"x": x, "f": cost, "p": weight}
        return ca.nlpsol("uwb_calibration", "ipopt", problem, options)

    def hessian(self, x: np.ndarray, weights: np.ndarray) -> sps.csc_matrix:
        """The exact Hessian of the cost at ``x`` (full symmetric), as IPOPT receives it."""
        _, hess_fn = self.derivatives
        upper = hess_fn(x, weights, 1.0, ca.DM.zeros(0, 1))
        sp = upper.sparsity()
        triu = sps.csc_matrix(
            (np.array(upper.nonzeros(), dtype=float), sp.row(), sp.colind()),
            shape=(sp.size1(), sp.size2()),
        )
        return sps.csc_matrix(triu + sps.triu(triu, k=1).T)

    def solve(
        self, x0: np.ndarray, weights: np.ndarray, lbx: np.ndarray, ubx: np.ndarray
    ) -> SolveResult:
        """Minimise ``sum w_i r_i^2 / 2`` from ``x0`` (fixed unknowns have ``lbx == ubx``)."""
        out = self.solver(x0=x0, p=weights, lbx=lbx, ubx=ubx)
        stats = self.solver.stats()
        status = str(stats.get("return_status", "unknown"))
        return SolveResult(
            x=np.array(out["x"], dtype=float).ravel(),
            status=status,
            iterations=int(stats.get("iter_count", 0)),
            success=status in _SUCCESS,
        )


def reception_functions() -> dict[str, ca.Function]:
    """The cost of one reception with its exact gradient and Hessian (CasADi AD).

    With ``v = (e, p, tau, b)`` (emitter position, reader position [m], transmit time, clock
    offset [m]) and ``r = toa - (tau + ||e - p|| + b)``, the cost is ``weight r^2 / 2``.
    Three functions, so that each evaluation computes only what IPOPT asks for:
    ``toa_reception_cost(v, toa, weight) -> cost``, ``toa_reception_gradient(...) -> (cost,
    gradient)`` and ``toa_reception_hessian(...) -> hessian`` (the 36 upper-triangular
    entries of the 8x8 Hessian, column by column).
    """
    v = ca.SX.sym("v", 8)
    toa = ca.SX.sym("toa")
    weight = ca.SX.sym("weight")
    r = toa - (v[6] + ca.sqrt(ca.sumsqr(v[0:3] - v[3:6])) + v[7])
    cost = 0.5 * weight * r**2
    hess, grad = ca.hessian(cost, v)
    rows, cols = _triu(8)
    upper = ca.vertcat(*[hess[int(i), int(j)] for i, j in zip(rows, cols)])
    args, names = [v, toa, weight], ["v", "toa", "weight"]
    return {
        "cost": ca.Function("toa_reception_cost", args, [cost], names, ["cost"]),
        "gradient": ca.Function(
            "toa_reception_gradient", args, [cost, grad], names, ["cost", "gradient"]
        ),
        "hessian": ca.Function("toa_reception_hessian", args, [upper], names, ["hessian"]),
    }


def _triu(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of the upper-triangular entries of an n x n matrix, column by column."""
    rows, cols = np.triu_indices(n)
    order = np.lexsort((rows, cols))
    return rows[order], cols[order]


def _hessian_scatter(index: np.ndarray, nx: int) -> tuple[ca.Sparsity, sps.csc_matrix]:
    """Upper-triangular Hessian sparsity and the matrix summing local entries into it.

    Args:
        index: Extended-vector index of the local unknowns, shape (N, 8); entries >= nx are
            constants and drop out.
        nx: Number of unknowns.
    """
    rows, cols = _triu(index.shape[1])
    a, b = index[:, rows].ravel(), index[:, cols].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    local = np.flatnonzero(hi < nx)
    # CasADi stores non-zeros column by column: key = column * nx + row.
    keys, slot = np.unique(hi[local] * nx + lo[local], return_inverse=True)
    pattern = ca.Sparsity.triplet(nx, nx, (keys % nx).tolist(), (keys // nx).tolist())
    scatter = sps.csc_matrix((np.ones(local.size), (slot, local)), shape=(keys.size, a.size))
    return pattern, scatter


def _casadi_sparse(matrix: sps.spmatrix) -> ca.DM:
    csc = sps.csc_matrix(matrix)
    csc.sum_duplicates()
    csc.sort_indices()
    pattern = ca.Sparsity(csc.shape[0], csc.shape[1], csc.indptr.tolist(), csc.indices.tolist())
    return ca.DM(pattern, csc.data.tolist())


def marginal_covariance(
    information: sps.spmatrix, free: np.ndarray, wanted: np.ndarray
) -> np.ndarray:
    """Covariance of some unknowns: the ``wanted`` block of the inverse information matrix.

    Args:
        information: Gauss-Newton information ``J^T W J``, sparse (nx, nx).
        free: Indices of the estimated unknowns (fixed ones, gauge included, are left out).
        wanted: Indices (among all nx) whose covariance is returned; fixed ones get zero rows
            and columns.

    Returns:
        Shape (len(wanted), len(wanted)).

    Raises:
        np.linalg.LinAlgError: When the information matrix of the free unknowns is singular.
    """
    info = sps.csc_matrix(information)[free][:, free]
    position = np.full(information.shape[0], -1, dtype=np.int64)
    position[free] = np.arange(free.size)
    cols = position[wanted]
    est = cols >= 0
    rhs = np.zeros((free.size, int(est.sum())))
    rhs[cols[est], np.arange(rhs.shape[1])] = 1.0
    try:
        lu = spla.splu(info)
    except RuntimeError as err:  # "Factor is exactly singular"
        raise np.linalg.LinAlgError(str(err)) from err
    sol = lu.solve(rhs)
    if not np.all(np.isfinite(sol)):
        raise np.linalg.LinAlgError("information matrix is singular")
    block = sol[cols[est]]
    out = np.zeros((wanted.size, wanted.size))
    idx = np.flatnonzero(est)
    out[np.ix_(idx, idx)] = 0.5 * (block + block.T)
    return out
