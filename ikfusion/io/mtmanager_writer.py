"""Write MT Manager ASCII exports (the simulator's captures and test fixtures).

The files are what :func:`ikfusion.io.read_mtmanager` reads: ``//`` comment lines in the old
(``// Update Rate: 100.0Hz``) or new (``// General information:`` blocks) style, a header line
starting with ``PacketCounter``, then one row per received packet. Orientations and the free
acceleration are given in ENU and written in the coordinate system asked for (NED and NWU files
hold ``R_NED_sensor = R_ENU_NED^T @ R_ENU_sensor``); acc, gyr and mag are sensor-frame vectors and
are written as they are.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..atomic import atomic_write_text
from ..rotations import matrix_to_quat_wxyz, matrix_to_xsens_euler
from .mtmanager import world_conversions
from .orientation_columns import EULER_COLUMNS, MAT_COLUMNS, QUAT_COLUMNS

_FREE_ACC_NAMES = {"ENU": ("E", "N", "U"), "NED": ("N", "E", "D"), "NWU": ("N", "W", "U")}
_ORIENTATIONS = ("quat", "mat", "euler")


def _orientation_blocks(R: np.ndarray, formats: Sequence[str]) -> tuple[list[str], np.ndarray]:
    good = np.isfinite(R).all(axis=(1, 2))
    names: list[str] = []
    blocks = []
    for fmt in formats:
        if fmt == "quat":
            q = np.full((len(R), 4), np.nan)
            q[good] = matrix_to_quat_wxyz(R[good])
            names += list(QUAT_COLUMNS)
            blocks.append(q)
        elif fmt == "mat":
            names += list(MAT_COLUMNS)
            blocks.append(R.reshape(-1, 9))
        elif fmt == "euler":
            e = np.full((len(R), 3), np.nan)
            e[good] = matrix_to_xsens_euler(R[good])
            names += list(EULER_COLUMNS)
            blocks.append(e)
        else:
            raise ValueError(f"orientation must be quat, mat, euler (or a list of them), "
                             f"not {fmt!r}")
    return names, np.column_stack(blocks) if blocks else np.zeros((len(R), 0))


def _header_lines(style: str, sensor_id: str, rate: float | None,
                  coordinate_system: str | None, comments: Sequence[str]) -> list[str]:
    lines: list[str] = []
    if style == "old":
        lines.append("// Start Time: Unknown")
        if rate is not None:
            lines.append(f"// Update Rate: {rate:.1f}Hz")
        lines += ["// Filter Profile: human (46.1)", "// Firmware Version: 4.4.0"]
        if coordinate_system is not None:
            lines.append(f"// Coordinate system: {coordinate_system}")
    elif style == "new":
        lines += ["// General information: ", "//  MT Manager version: 2022.2.0 ",
                  "// Device information: ", f"//  DeviceId: {sensor_id}",
                  "//  ProductCode: MTW2-3A7G6", "// Device settings: ",
                  "//  Filter Profile: human(46.1)"]
        if rate is not None:
            lines.append(f"//  Update Rate: {rate:g}Hz")
        if coordinate_system is not None:
            lines.append(f"// Coordinate system: {coordinate_system}")
    else:
        raise ValueError(f"header must be 'old' or 'new', not {style!r}")
    lines += [c if c.startswith("//") else f"// {c}" for c in comments]
    return lines


def write_mtmanager(folder: str | Path, prefix: str, sensor_id: str,
                    packet_counter: npt.ArrayLike, R_world_sensor: npt.ArrayLike,
                    rate: float | None, *, acc: npt.ArrayLike | None = None,
                    gyr: npt.ArrayLike | None = None, mag: npt.ArrayLike | None = None,
                    free_acc: npt.ArrayLike | None = None,
                    sample_time_fine: bool | npt.ArrayLike = True, delimiter: str = "\t",
                    orientation: str | Sequence[str] = "quat",
                    coordinate_system: str | None = "ENU", header: str = "old",
                    empty: str = "", comments: Sequence[str] = (), decimals: int = 6) -> Path:
    """Write ``<folder>/<prefix><sensor_id>.txt`` atomically.

    Args:
        folder: Output folder (created when missing).
        prefix: Trial prefix (e.g. ``MT_012005D6_009-001_``).
        sensor_id: 8 hex digits.
        packet_counter: (N,) whole packet counters of the rows (unwrapped or not); written
            modulo 65536 (the 16-bit wrap), zero-padded to 5 digits. Leave out the counters of
            lost packets.
        R_world_sensor: (N, 3, 3) ENU orientations; NaN rows give empty (or ``empty``) fields.
        rate: [Hz], written as the update rate line; None writes no rate line.
        acc: (N, 3) specific force, sensor frame [m/s^2].
        gyr: (N, 3) angular rate, sensor frame [rad/s].
        mag: (N, 3) magnetic field, sensor frame [a.u.].
        free_acc: (N, 3) acceleration without gravity, ENU world frame [m/s^2].
        sample_time_fine: True: 10 kHz ticks computed from the counter and the rate (empty
            without a rate); False: an empty column; an array: those ticks.
        delimiter: A tab, ``","``, ``";"`` or ``" "``.
        orientation: ``"quat"``, ``"mat"``, ``"euler"``, a list of them (columns in that
            order), or an empty list for none.
        coordinate_system: ``"ENU"``, ``"NED"`` or ``"NWU"`` (the data are converted); None
            writes no coordinate-system line (readers then assume ENU).
        header: ``"old"`` (MT Manager 4) or ``"new"`` (MT Manager 2019+) comment lines.
        empty: Text of an empty field: ``""`` or ``"NaN"``.
        comments: Extra ``//`` lines after the header block.
        decimals: Decimals of the floating-point fields.

    Returns:
        The path written.

    Raises:
        ValueError: Inconsistent shapes, an unknown option.
    """
    if delimiter not in ("\t", ",", ";", " "):
        raise ValueError(f"delimiter must be a tab, ',', ';' or ' ', not {delimiter!r}")
    system = coordinate_system or "ENU"
    if system not in world_conversions():
        raise ValueError(f"coordinate_system must be ENU, NED or NWU, not {system!r}")
    W = world_conversions()[system]  # R_ENU_system
    counter = np.asarray(packet_counter)
    n = len(counter)
    if np.any(counter != np.round(counter)):
        raise ValueError("packet_counter must hold whole numbers")
    R = W.T @ np.asarray(R_world_sensor, dtype=float).reshape(n, 3, 3)
    formats = [orientation] if isinstance(orientation, str) else list(orientation)
    columns = ["PacketCounter", "SampleTimeFine"]
    blocks: list[np.ndarray] = [_fine_ticks(counter, rate, sample_time_fine).reshape(n, 1)]
    for name, values in (("Acc", acc), ("Gyr", gyr), ("Mag", mag)):
        if values is not None:
            columns += [f"{name}_{a}" for a in "XYZ"]
            blocks.append(_vectors(values, n, name))
    if free_acc is not None:
        columns += [f"FreeAcc_{a}" for a in _FREE_ACC_NAMES[system]]
        blocks.append(_vectors(free_acc, n, "free_acc") @ W)  # rows: v_sys = W^T v_enu
    names, values = _orientation_blocks(R, formats)
    columns += names
    blocks.append(values)
    table = np.column_stack(blocks)
    text = _format(np.mod(counter.astype(np.int64), 65536), table, delimiter, empty, decimals)
    lines = _header_lines(header, sensor_id, rate, coordinate_system, comments)
    lines.append(delimiter.join(columns))
    target = Path(folder) / f"{prefix}{sensor_id}.txt"
    return atomic_write_text(target, "\n".join(lines) + "\n" + text)


def _vectors(values: npt.ArrayLike, n: int, name: str) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    if v.shape != (n, 3):
        raise ValueError(f"{name} must have shape ({n}, 3), not {v.shape}")
    return v


def _fine_ticks(counter: np.ndarray, rate: float | None,
                sample_time_fine: bool | npt.ArrayLike) -> np.ndarray:
    if isinstance(sample_time_fine, bool):
        if not sample_time_fine or rate is None:
            return np.full(len(counter), np.nan)
        ticks = np.round((counter - counter[0]) * 10000.0 / rate) if len(counter) else counter
        return np.mod(ticks + 1_000_000, 2**32).astype(float)
    ticks = np.asarray(sample_time_fine, dtype=float)
    if ticks.shape != (len(counter),):
        raise ValueError(f"sample_time_fine must have shape ({len(counter)},)")
    return np.mod(ticks, 2**32)


def _format(counter: np.ndarray, table: np.ndarray, delimiter: str, empty: str,
            decimals: int) -> str:
    """Rows as text: the counter zero-padded, whole tick counts as integers, NaN as ``empty``."""
    n = len(counter)
    if n == 0:
        return ""
    columns = [np.char.mod("%05d", counter)]
    for k in range(table.shape[1]):
        col = table[:, k]
        finite = np.isfinite(col)
        whole = k == 0  # SampleTimeFine
        text = np.char.mod("%d" if whole else f"%.{decimals}f",
                           np.where(finite, col, 0).astype(np.int64) if whole
                           else np.where(finite, col, 0.0))
        columns.append(np.where(finite, text, empty))
    rows = np.stack(columns, axis=1).tolist()
    return "\n".join(delimiter.join(r) for r in rows) + "\n"
