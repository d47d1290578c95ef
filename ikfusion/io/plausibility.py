"""Physically impossible values in IMU data fields: made NaN so that their sample is invalid.

A parser reads ``inf`` and ``1e308`` as numbers; no sensor measures them. A field group (the
three components of a vector, the four of a quaternion, the nine of a matrix, the three Euler
angles) that holds an infinite value or a value beyond what any body-worn IMU reports is set to
NaN in that row: the sample becomes invalid like a lost packet, the rows around it are kept,
and one warning per sensor counts the samples per field. The limits are far outside every
sensor's range, so they catch corrupted numbers, not hard movements:

* specific force and free acceleration: ``|a| <= 1e4 m/s^2`` (about 1000 g; IMUs saturate at
  16 to 200 g);
* angular rate: ``|w| <= 1e3 rad/s`` (MTw and MTi gyroscopes saturate near 35 rad/s);
* magnetic field: ``|m| <= 1e3`` a.u. (normalised to the local field, about 1);
* a quaternion's norm within 10 % of 1 (exports write it to 6 decimals);
* rotation-matrix elements within +-1.05 (the finer test, ``|R^T R - I| <= 0.05`` and
  ``det R > 0``, is made when the matrix is read:
  :func:`ikfusion.io.orientation_columns.R_from_matrix`);
* Euler angles within +-360 deg.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .orientation_columns import EULER_COLUMNS, MAT_COLUMNS, NOT_A_ROTATION, QUAT_COLUMNS

#: Largest magnitude accepted per vector field: specific force [m/s^2], angular rate [rad/s],
#: magnetic field [a.u.].
MAGNITUDE_LIMITS: dict[str, float] = {"Acc": 1e4, "FreeAcc": 1e4, "Gyr": 1e3, "Mag": 1e3}
QUAT_NORM_TOLERANCE = 0.1
EULER_LIMIT_DEG = 360.0


@dataclass(frozen=True)
class FieldCheck:
    """One group of columns checked together.

    Attributes:
        label: Name in warnings (``Acc``, ``Quat``, ``Mat``, ``Euler``, ...).
        columns: Column indices of the group.
        kind: ``"magnitude"``, ``"quaternion"``, ``"matrix"`` or ``"euler"``.
        limit: Largest magnitude for ``"magnitude"`` groups.
    """

    label: str
    columns: tuple[int, ...]
    kind: str
    limit: float = np.inf


def mtmanager_checks(columns: Sequence[str]) -> list[FieldCheck]:
    """The checks for the columns of an MT Manager header (names case-insensitive)."""
    lowered = [c.lower() for c in columns]
    checks = []
    for label, limit in MAGNITUDE_LIMITS.items():
        where = tuple(k for k, c in enumerate(lowered) if c.startswith(label.lower() + "_"))
        if where:
            checks.append(FieldCheck(label, where, "magnitude", limit))
    for label, names, kind in (("Quat", QUAT_COLUMNS, "quaternion"), ("Mat", MAT_COLUMNS, "matrix"),
                               ("Euler", EULER_COLUMNS, "euler")):
        if all(n.lower() in lowered for n in names):
            checks.append(FieldCheck(label, tuple(lowered.index(n.lower()) for n in names), kind))
    return checks


def _impossible(values: np.ndarray, check: FieldCheck) -> np.ndarray:
    """(r,) True where a row of the group is infinite or beyond its limit (NaN is not)."""
    bad = np.isinf(values).any(axis=1)
    finite = np.isfinite(values).all(axis=1)
    v = values[finite]
    if check.kind == "magnitude":
        wrong = np.abs(v).max(axis=1) > check.limit if len(v) else np.zeros(0, dtype=bool)
    elif check.kind == "quaternion":
        with np.errstate(over="ignore", invalid="ignore"):
            wrong = ~(np.abs(np.sqrt(np.einsum("ij,ij->i", v, v)) - 1.0) <= QUAT_NORM_TOLERANCE)
    elif check.kind == "euler":
        wrong = np.abs(v).max(axis=1) > EULER_LIMIT_DEG if len(v) else np.zeros(0, dtype=bool)
    else:  # a matrix within NOT_A_ROTATION of orthonormal has no element beyond sqrt(1.05)
        wrong = np.abs(v).max(axis=1) > 1.0 + NOT_A_ROTATION if len(v) \
            else np.zeros(0, dtype=bool)
    bad[np.flatnonzero(finite)[wrong]] = True
    return bad


def screen(data: np.ndarray, checks: Sequence[FieldCheck]) -> dict[str, int]:
    """Set every impossible field group to NaN in place; count the rows per group label.

    Args:
        data: (r, c) numbers of a file (modified in place).
        checks: The groups to check.

    Returns:
        Label -> rows made NaN (only labels with at least one).
    """
    counts: dict[str, int] = {}
    if not len(data) or not checks:
        return counts
    with np.errstate(invalid="ignore"):
        largest = np.fmax.reduce(np.abs(data), axis=0)  # per column, NaN ignored
    for check in checks:
        cols = np.asarray(check.columns, dtype=np.int64)
        if check.kind != "quaternion" and bool(np.all(largest[cols] <= _bound(check))):
            continue  # the fast path of clean files: every value within the limit
        bad = _impossible(data[:, cols], check)
        if bad.any():
            data[np.ix_(np.flatnonzero(bad), cols)] = np.nan
            counts[check.label] = int(bad.sum())
    return counts


def _bound(check: FieldCheck) -> float:
    """Largest element magnitude of a group that needs no row-by-row look."""
    return {"magnitude": check.limit, "euler": EULER_LIMIT_DEG}.get(check.kind,
                                                                  1.0 + NOT_A_ROTATION)


def screen_warning(where: str, counts: dict[str, int]) -> str | None:
    """One warning for a sensor's impossible values, or None when there were none."""
    if not counts:
        return None
    listed = ", ".join(f"{label} {n}" for label, n in counts.items())
    return (f"{where}: infinite or physically impossible values (beyond |acc| 1e4 m/s^2, |gyr| "
            f"1e3 rad/s, |mag| 1e3, quaternion norm 1 +- 10 %, matrix elements beyond +-1.05, "
            f"Euler angles beyond +-360 deg) in {listed} sample(s); those samples are invalid, "
            "the others kept")
