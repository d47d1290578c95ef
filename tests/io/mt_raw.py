"""Independent reading of MT Manager text, for tests: split lines by hand, no ikfusion parser."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ikfusion.rotations import quat_wxyz_to_matrix, xsens_euler_to_matrix


def raw_table(path: Path) -> tuple[list[str], list[list[str]], str]:
    """Header names, the data rows as lists of field texts, and the delimiter."""
    lines = path.read_text().splitlines()
    start = next(i for i, ln in enumerate(lines)
                 if ln.strip() and not ln.lstrip().startswith("//"))
    header = lines[start]
    delimiter = next((d for d in ("\t", ";", ",") if d in header), " ")
    names = header.split() if delimiter == " " else [h.strip() for h in header.split(delimiter)]
    rows = [ln.split(delimiter) for ln in lines[start + 1:]
            if ln.strip() and not ln.lstrip().startswith("//")]
    return names, rows, delimiter


def value(text: str) -> float:
    """A field as a float (empty -> NaN)."""
    t = text.strip()
    return math.nan if t == "" else float(t)


def row_dict(names: list[str], row: list[str]) -> dict[str, float]:
    """Column name -> value of one row."""
    return {n: value(v) for n, v in zip(names, row)}


def orientation(values: dict[str, float]) -> np.ndarray | None:
    """R_world_sensor of a row from its quaternion, else matrix, else Euler columns."""
    if "Quat_q0" in values:
        return quat_wxyz_to_matrix([values[f"Quat_q{i}"] for i in range(4)])
    if "Mat[1][1]" in values:
        return np.array([[values[f"Mat[{i}][{j}]"] for j in (1, 2, 3)] for i in (1, 2, 3)])
    if "Roll" in values:
        return xsens_euler_to_matrix(values["Roll"], values["Pitch"], values["Yaw"])
    return None


def counters(names: list[str], rows: list[list[str]]) -> np.ndarray:
    """PacketCounter of every row, unwrapped by hand (steps modulo 65536)."""
    k = names.index("PacketCounter")
    raw = np.array([int(r[k]) for r in rows])
    return raw[0] + np.concatenate([[0], np.cumsum(np.mod(np.diff(raw), 65536))])
