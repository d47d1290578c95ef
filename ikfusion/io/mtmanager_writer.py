"""Write MT Manager ASCII exports (the simulator's capture files, and test fixtures)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from ..rotations import matrix_to_quat_wxyz, matrix_to_xsens_euler


def write_mtmanager(folder: str | Path, prefix: str, sensor_id: str, packet_counter: np.ndarray,
                    R_world_sensor: np.ndarray, rate: float | None, *,
                    acc: np.ndarray | None = None, gyr: np.ndarray | None = None,
                    delimiter: str = "\t", orientation: str = "quat",
                    coordinate_system: str | None = "ENU") -> Path:
    """Write ``<folder>/<prefix><sensor_id>.txt`` atomically.

    Args:
        folder: Output folder.
        prefix: Trial prefix (e.g. ``MT_012005D6_009-001_``).
        sensor_id: 8 hex digits.
        packet_counter: (N,) counters; written modulo 65536 (the 16-bit wrap).
        R_world_sensor: (N, 3, 3) orientations (ENU); NaN rows give empty fields.
        rate: [Hz], written as ``// Update Rate:``; None writes no rate line.
        acc: (N, 3) specific force [m/s^2] or None.
        gyr: (N, 3) angular rate [rad/s] or None.
        delimiter: A tab, ``","``, ``";"`` or ``" "``.
        orientation: ``"quat"``, ``"mat"`` or ``"euler"``.
        coordinate_system: Written as ``// Coordinate system:`` (None: omitted).
    """
    columns = ["PacketCounter", "SampleTimeFine"]
    blocks = [np.asarray(packet_counter) % 65536, np.full(len(packet_counter), np.nan)]
    if acc is not None:
        columns += ["Acc_X", "Acc_Y", "Acc_Z"]
        blocks += list(np.asarray(acc).T)
    if gyr is not None:
        columns += ["Gyr_X", "Gyr_Y", "Gyr_Z"]
        blocks += list(np.asarray(gyr).T)
    R = np.asarray(R_world_sensor)
    good = np.isfinite(R).all(axis=(1, 2))
    if orientation == "quat":
        q = np.full((len(R), 4), np.nan)
        q[good] = matrix_to_quat_wxyz(R[good])
        columns += ["Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3"]
        blocks += list(q.T)
    elif orientation == "mat":
        columns += [f"Mat[{i}][{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
        blocks += [R[:, i, j] for i in range(3) for j in range(3)]
    elif orientation == "euler":
        e = np.full((len(R), 3), np.nan)
        e[good] = matrix_to_xsens_euler(R[good])
        columns += ["Roll", "Pitch", "Yaw"]
        blocks += list(e.T)
    else:
        raise ValueError(f"orientation must be quat, mat or euler, not {orientation!r}")
    lines = []
    if rate is not None:
        lines.append(f"// Update Rate: {rate:.1f}Hz")
    if coordinate_system is not None:
        lines.append(f"// Coordinate system: {coordinate_system}")
    lines.append(delimiter.join(columns))
    table = np.column_stack(blocks)
    for row in table:
        fields = [f"{int(row[0]):05d}"]
        fields += ["" if not np.isfinite(v) else f"{v:.6f}" for v in row[1:]]
        lines.append(delimiter.join(fields))
    target = Path(folder) / f"{prefix}{sensor_id}.txt"
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.")
    with os.fdopen(fd, "w") as out:
        out.write("\n".join(lines) + "\n")
    os.replace(tmp, target)
    return target
