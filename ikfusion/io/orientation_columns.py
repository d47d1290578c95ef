"""Orientation columns of MT Manager exports: quaternion, rotation matrix, Euler angles.

* ``Quat_q0, Quat_q1, Quat_q2, Quat_q3``: ``R_world_sensor`` as (w, x, y, z); normalised.
* ``Mat[i][j]`` (i, j in 1..3): element (row i, column j) of ``R_world_sensor``. Rounded
  matrices are kept as written; one that is off orthonormal by more than rounding is projected
  to the nearest rotation, one that is not a rotation at all is NaN.
* ``Roll, Pitch, Yaw`` [deg]: ``R_world_sensor = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.

A file holding several of them is read from the quaternion, then the matrix, then the Euler
angles; a row whose preferred columns are NaN falls back to the next ones.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..rotations import angle_between, quat_wxyz_to_matrix, xsens_euler_to_matrix

#: Column names of each representation (in the order their values are used).
QUAT_COLUMNS: tuple[str, ...] = ("Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3")
MAT_COLUMNS: tuple[str, ...] = tuple(f"Mat[{i}][{j}]" for i in (1, 2, 3) for j in (1, 2, 3))
EULER_COLUMNS: tuple[str, ...] = ("Roll", "Pitch", "Yaw")

_ROUNDING = 1e-4  # |R^T R - I| allowed for matrices written with ~6 decimals
NOT_A_ROTATION = 0.05


@dataclass
class OrientationColumns:
    """Where each orientation representation sits in a header (column indices or None).

    Attributes:
        quat: Indices of ``Quat_q0..3``.
        mat: Indices of ``Mat[1][1], Mat[1][2], ..., Mat[3][3]`` (row-major).
        euler: Indices of ``Roll, Pitch, Yaw``.
        warnings: Incomplete groups that were ignored.
    """

    quat: list[int] | None
    mat: list[int] | None
    euler: list[int] | None
    warnings: list[str] = field(default_factory=list)

    @classmethod
    def find(cls, columns: Sequence[str]) -> OrientationColumns:
        """Locate the orientation columns of a header (names compared case-insensitively)."""
        lowered = [c.lower() for c in columns]
        warnings: list[str] = []

        def group(label: str, names: tuple[str, ...]) -> list[int] | None:
            where = [lowered.index(n.lower()) if n.lower() in lowered else None for n in names]
            if all(k is None for k in where):
                return None
            if any(k is None for k in where):
                absent = [n for n, k in zip(names, where) if k is None]
                warnings.append(f"incomplete {label} columns (missing {', '.join(absent)}); "
                                "not used")
                return None
            return [int(k) for k in where if k is not None]

        return cls(group("quaternion", QUAT_COLUMNS), group("matrix", MAT_COLUMNS),
                   group("Euler", EULER_COLUMNS), warnings)

    @property
    def available(self) -> bool:
        """Whether any complete representation is present."""
        return any(g is not None for g in (self.quat, self.mat, self.euler))

    @property
    def names(self) -> list[str]:
        """The representations present, in order of preference."""
        return [name for name, g in (("Quat", self.quat), ("Mat", self.mat),
                                     ("Euler", self.euler)) if g is not None]


def R_from_quat(quat_wxyz: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """(r, 3, 3) from (r, 4) quaternions (w, x, y, z), normalised; zero ones give NaN."""
    notes = []
    norm = np.linalg.norm(quat_wxyz, axis=1)
    ok = np.isfinite(norm) & (norm > 1e-9)
    R = np.full((len(quat_wxyz), 3, 3), np.nan)
    R[ok] = quat_wxyz_to_matrix(quat_wxyz[ok])
    off = ok & (np.abs(norm - 1.0) > 0.01)
    if off.any():
        notes.append(f"{int(off.sum())} quaternion(s) with a norm off 1 by more than 1% "
                     f"(up to {np.max(np.abs(norm[off] - 1.0)):.3f}); normalised")
    if (np.isfinite(norm) & ~ok).any():
        notes.append(f"{int((np.isfinite(norm) & ~ok).sum())} zero quaternion(s); those "
                     "samples are invalid")
    return R, notes


def R_from_matrix(rows: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """(r, 3, 3) from (r, 9) row-major ``Mat[i][j]`` values; checked for being rotations."""
    notes = []
    R = rows.reshape(-1, 3, 3).copy()
    finite = np.isfinite(R).all(axis=(1, 2))
    error = np.full(len(R), np.inf)
    gram = np.swapaxes(R[finite], 1, 2) @ R[finite]
    error[finite] = np.abs(gram - np.eye(3)).max(axis=(1, 2))
    bad = finite & ((error > NOT_A_ROTATION) | (_determinant(R) < 0))
    fix = finite & ~bad & (error > _ROUNDING)
    if fix.any():
        U, _, Vt = np.linalg.svd(R[fix])
        R[fix] = U @ Vt
        notes.append(f"{int(fix.sum())} matrix row(s) off orthonormal by up to "
                     f"{error[fix].max():.2g}; projected to the nearest rotation")
    if bad.any():
        R[bad] = np.nan
        notes.append(f"{int(bad.sum())} matrix row(s) are not rotations (|R^T R - I| > "
                     f"{NOT_A_ROTATION} or det < 0); those samples are invalid")
    return R, notes


def _determinant(R: np.ndarray) -> np.ndarray:
    """Determinants (r,) of matrices (r, 3, 3) by cofactors (NaN where R holds NaN).

    Only its sign is used, where ``|R^T R - I| <= NOT_A_ROTATION``: there ``|det|`` is near 1,
    so the sign is the one any way of computing it gives.
    """
    a, b, c = R[:, 0, 0], R[:, 0, 1], R[:, 0, 2]
    d, e, f = R[:, 1, 0], R[:, 1, 1], R[:, 1, 2]
    g, h, i = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
    with np.errstate(invalid="ignore", over="ignore"):
        return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def R_from_euler(roll_pitch_yaw_deg: np.ndarray) -> np.ndarray:
    """(r, 3, 3) from (r, 3) Xsens Roll, Pitch, Yaw [deg]; NaN rows stay NaN."""
    e = roll_pitch_yaw_deg
    return xsens_euler_to_matrix(e[:, 0], e[:, 1], e[:, 2])


def _converters(columns: OrientationColumns, data: np.ndarray
                ) -> list[tuple[str, Callable[[np.ndarray], tuple[np.ndarray, list[str]]]]]:
    """Per representation present: a function from row indices to (R (k, 3, 3), notes)."""
    out: list[tuple[str, Callable[[np.ndarray], tuple[np.ndarray, list[str]]]]] = []
    if columns.quat is not None:
        quat = np.asarray(columns.quat)
        out.append(("Quat", lambda rows: R_from_quat(data[np.ix_(rows, quat)])))
    if columns.mat is not None:
        mat = np.asarray(columns.mat)
        out.append(("Mat", lambda rows: R_from_matrix(data[np.ix_(rows, mat)])))
    if columns.euler is not None:
        euler = np.asarray(columns.euler)
        out.append(("Euler", lambda rows: (R_from_euler(data[np.ix_(rows, euler)]), [])))
    return out


def orientation_from_columns(columns: OrientationColumns,
                             data: np.ndarray) -> tuple[np.ndarray, str, list[str]]:
    """``R_world_sensor`` per row in the file's world frame, from the best columns of each row.

    Args:
        columns: Where the representations are.
        data: (r, c) the file's numbers.

    Returns:
        (r, 3, 3) orientations (NaN where no representation is finite), the representations
        used joined by ``+`` (``""`` when none), and notes for the user.
    """
    notes: list[str] = []
    out = np.full((len(data), 3, 3), np.nan)
    converters = _converters(columns, data)
    used = []
    todo = np.arange(len(data))
    for name, convert in converters:
        if not len(todo):
            break
        R, more = convert(todo)
        notes += more
        take = np.isfinite(R).all(axis=(1, 2))
        if take.any():
            out[todo[take]] = R[take]
            used.append(name)
        todo = todo[~take]
    if len(used) > 1:
        notes.append(f"orientation from {used[0]} columns; {' and '.join(used[1:])} columns "
                     "used where those were NaN")
    if len(converters) > 1 and len(data):
        notes += _disagreement(converters, len(data))
    return out, "+".join(used), notes


def _disagreement(converters: list[tuple[str, Callable[[np.ndarray], tuple[np.ndarray,
                                                                          list[str]]]]],
                  rows: int) -> list[str]:
    """A note when the first two representations disagree by more than 1 deg (median)."""
    sample = np.unique(np.linspace(0, rows - 1, min(rows, 200)).astype(np.int64))
    (name_a, convert_a), (name_b, convert_b) = converters[0], converters[1]
    A, _ = convert_a(sample)
    B, _ = convert_b(sample)
    both = np.isfinite(A).all(axis=(1, 2)) & np.isfinite(B).all(axis=(1, 2))
    if not both.any():
        return []
    angle = float(np.degrees(np.median(angle_between(A[both], B[both]))))
    if angle > 1.0:
        return [f"the {name_a} and {name_b} columns disagree by {angle:.1f} deg (median); "
                f"{name_a} is used"]
    return []
