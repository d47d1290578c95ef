"""Xsens MT Manager ASCII exports: one file per sensor, joined on a common time base.

Every variant of SPEC section 4: ``//`` comment lines (old ``// Update Rate: 100.0Hz`` headers
and the newer ``// General information:`` blocks with ``// Coordinate system: ENU``), a header
line starting with ``PacketCounter``, tab / comma / semicolon / space delimiters (in
space-delimited files an empty field is a run of spaces), orientation as ``Quat_q0..3``,
``Mat[i][j]`` (row i, column j of ``R_world_sensor``) or ``Roll/Pitch/Yaw`` [deg] (preferred in
that order when a file has several), optional ``Acc_*``, ``FreeAcc_*``, ``Gyr_*``, ``Mag_*``,
``SampleTimeFine`` and UTC columns, empty fields and ``NaN``.

PacketCounter is 16-bit and wraps; it is unwrapped and every sensor of a trial is placed on the
common sample index ``counter - first counter``. A gap in the counter is a lost packet: the
orientation inside the gap is filled by slerp and flagged invalid. Samples outside a sensor's
span are NaN and invalid. NED and NWU exports are converted to ENU.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..rotations import (
    R_ENU_NED,
    R_ENU_NWU,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
    slerp,
    xsens_euler_to_matrix,
)

_WRAP = 65536
_CONVERSIONS = {"ENU": np.eye(3), "NED": R_ENU_NED, "NWU": R_ENU_NWU}
_VECTORS = {
    "acc": ("Acc_X", "Acc_Y", "Acc_Z"),
    "gyr": ("Gyr_X", "Gyr_Y", "Gyr_Z"),
    "mag": ("Mag_X", "Mag_Y", "Mag_Z"),
}
_FREE_ACC = (("FreeAcc_E", "FreeAcc_N", "FreeAcc_U"), ("FreeAcc_X", "FreeAcc_Y", "FreeAcc_Z"))
_QUAT = ("Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3")
_MAT = tuple(f"Mat[{i}][{j}]" for i in (1, 2, 3) for j in (1, 2, 3))
_EULER = ("Roll", "Pitch", "Yaw")
_ID = re.compile(r"([0-9A-Fa-f]{8})\.txt$")


@dataclass
class SensorStream:
    """One sensor on the recording's common time base.

    Attributes:
        sensor_id: Xsens device id (8 hex digits).
        R_world_sensor: (N, 3, 3) orientation, ENU world; slerp-filled in gaps, NaN outside the
            sensor's span.
        valid: (N,) True where the orientation was received and finite.
        acc: (N, 3) specific force, sensor frame [m/s^2], or None.
        free_acc: (N, 3) acceleration without gravity, world frame [m/s^2], or None.
        gyr: (N, 3) angular rate, sensor frame [rad/s], or None.
        mag: (N, 3) magnetic field, sensor frame [a.u.], or None.
        rows: Samples received (data lines).
        lost: Packets missing inside the sensor's PacketCounter span.
        channels: Column names of the file.
        path: The file.
    """

    sensor_id: str
    R_world_sensor: np.ndarray
    valid: np.ndarray
    acc: np.ndarray | None
    free_acc: np.ndarray | None
    gyr: np.ndarray | None
    mag: np.ndarray | None
    rows: int
    lost: int
    channels: list[str]
    path: Path


@dataclass
class ImuRecording:
    """A trial: every sensor on one time base.

    Attributes:
        time: (N,) [s] from the first sample of the trial.
        rate: [Hz].
        sensors: Sensor id -> :class:`SensorStream`.
        coordinate_system: Always ``"ENU"`` after reading.
        source_coordinate_system: What the files declared.
        warnings: Messages for the user.
    """

    time: np.ndarray
    rate: float
    sensors: dict[str, SensorStream]
    coordinate_system: str = "ENU"
    source_coordinate_system: str = "ENU"
    warnings: list[str] = field(default_factory=list)


@dataclass
class _RawFile:
    path: Path
    sensor_id: str
    rate: float | None
    coordinate_system: str
    columns: list[str]
    data: np.ndarray  # (rows, columns) floats, NaN where empty
    first_line: int


def _sensor_id(path: Path) -> str:
    match = _ID.search(path.name)
    return match.group(1).upper() if match else path.stem


def _delimiter(header: str) -> str | None:
    for d in ("\t", ",", ";"):
        if d in header:
            return d
    return " "


def _parse_number(text: str, path: Path, line: int, column: str) -> float:
    t = text.strip()
    if t == "" or t.lower() == "nan":
        return float("nan")
    try:
        return float(t)
    except ValueError:
        raise InputError(f"not a number: {t!r}", path=path, line=line, field=column) from None


def read_mtmanager_file(path: str | Path, rate: float | None = None) -> _RawFile:
    """Parse one export file into columns (no time base yet)."""
    file = Path(path)
    try:
        lines = file.read_text(errors="replace").splitlines()
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", path=file) from err
    if not any(line.strip() for line in lines):
        raise InputError("empty file (no header line starting with PacketCounter)", path=file,
                         line=1)
    file_rate, system, header_index = None, "ENU", None
    for n, line in enumerate(lines):
        text = line.strip()
        if text.startswith("//"):
            if m := re.search(r"Update Rate:\s*([0-9.]+)", text):
                file_rate = float(m.group(1))
            if m := re.search(r"Coordinate system:\s*(\w+)", text):
                system = m.group(1).upper()
            continue
        if not text:
            continue
        if not text.startswith("PacketCounter"):
            raise InputError(f"expected the header line starting with PacketCounter, found "
                             f"{text[:40]!r}", path=file, line=n + 1, field="PacketCounter")
        header_index = n
        break
    if header_index is None:
        raise InputError("no header line starting with PacketCounter", path=file,
                         line=len(lines), field="PacketCounter")
    if system not in _CONVERSIONS:
        raise InputError(f"unknown coordinate system {system!r} (ENU, NED or NWU)", path=file,
                         field="Coordinate system")
    delimiter = _delimiter(lines[header_index])
    columns = [c.strip() for c in lines[header_index].rstrip("\r\n").split(delimiter)]
    while columns and columns[-1] == "":
        columns.pop()
    rows = []
    for n in range(header_index + 1, len(lines)):
        line = lines[n].rstrip("\r\n")
        if not line.strip() or line.lstrip().startswith("//"):
            continue
        fields = line.split(delimiter)
        while len(fields) > len(columns) and fields[-1].strip() == "":
            fields.pop()
        if len(fields) != len(columns):
            raise InputError(
                f"{len(fields)} fields where the header has {len(columns)} (truncated line?)",
                path=file, line=n + 1, field=columns[min(len(fields), len(columns)) - 1])
        rows.append([_parse_number(v, file, n + 1, c) for v, c in zip(fields, columns)])
    data = np.array(rows, dtype=float).reshape(-1, len(columns))
    if rate is not None:
        file_rate = float(rate)
    return _RawFile(file, _sensor_id(file), file_rate, system, columns, data, header_index + 2)


def _column(raw: _RawFile, names: tuple[str, ...]) -> np.ndarray | None:
    if not all(n in raw.columns for n in names):
        return None
    return raw.data[:, [raw.columns.index(n) for n in names]]


def _orientation(raw: _RawFile) -> np.ndarray:
    """R_world_sensor (rows, 3, 3) in the file's own world frame (NaN when absent)."""
    quat = _column(raw, _QUAT)
    if quat is not None:
        return quat_wxyz_to_matrix(quat)
    mat = _column(raw, _MAT)
    if mat is not None:
        return mat.reshape(-1, 3, 3)
    euler = _column(raw, _EULER)
    if euler is not None:
        return xsens_euler_to_matrix(euler[:, 0], euler[:, 1], euler[:, 2])
    return np.full((len(raw.data), 3, 3), np.nan)


def _unwrap(counter: np.ndarray, path: Path, first_line: int) -> np.ndarray:
    if not np.isfinite(counter).all():
        bad = int(np.argmin(np.isfinite(counter)))
        raise InputError("PacketCounter is empty or not a number", path=path,
                         line=first_line + bad, field="PacketCounter")
    c = counter.astype(np.int64)
    steps = np.diff(c) % _WRAP
    return np.concatenate([[c[0]], c[0] + np.cumsum(steps)]) if len(c) else c


def _files(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix == ".txt" and _ID.search(p.name))
        if not files:
            raise InputError("no MT Manager exports (<prefix><sensor id>.txt) in the folder",
                             path=path)
        return files
    files = sorted(path.parent.glob(path.name + "*.txt")) if path.parent.is_dir() else []
    files = [f for f in files if _ID.search(f.name)]
    if not files:
        raise InputError("no file, folder or trial prefix with MT Manager exports", path=path)
    return files


def read_mtmanager(path: str | Path, rate: float | None = None) -> ImuRecording:
    """Read a trial: a trial prefix, a folder or one file.

    Args:
        path: ``folder/`` or ``folder/MT_012005D6_009-001_`` or one ``...00B421E6.txt``.
        rate: Sample rate [Hz] for files without ``// Update Rate:`` (overrides the files).

    Returns:
        The :class:`ImuRecording`.

    Raises:
        InputError: Naming the file, line and column of bad input.
    """
    raws = [read_mtmanager_file(f, rate) for f in _files(Path(path))]
    rates = {r.rate for r in raws if r.rate is not None}
    if not rates:
        raise InputError("no `// Update Rate:` in the files: give the rate (--rate HZ)",
                         path=raws[0].path, field="Update Rate")
    if len(rates) > 1:
        raise InputError(f"sensors disagree on the rate: {sorted(rates)} Hz", path=raws[0].path,
                         field="Update Rate")
    hz = rates.pop()
    counters = [_unwrap(_column(r, ("PacketCounter",))[:, 0], r.path, r.first_line)  # type: ignore[index]
                for r in raws]
    reference = next((c[0] for c in counters if len(c)), 0)
    aligned = []
    for c in counters:
        if len(c):  # the same epoch: start within half a wrap of the reference
            c = c + _WRAP * np.round((reference - c[0]) / _WRAP).astype(np.int64)
        aligned.append(c)
    start = min(int(c.min()) for c in aligned if len(c))
    end = max(int(c.max()) for c in aligned if len(c))
    n = end - start + 1
    systems = {r.coordinate_system for r in raws}
    sensors = {}
    warnings = []
    for raw, c in zip(raws, aligned):
        stream = _stream(raw, c - start, n)
        if stream.sensor_id in sensors:
            raise InputError(f"sensor {stream.sensor_id} appears twice", path=raw.path)
        sensors[stream.sensor_id] = stream
        if stream.lost:
            warnings.append(f"{stream.sensor_id}: {stream.lost} lost packets filled by slerp "
                            "and flagged invalid")
    return ImuRecording(np.arange(n) / hz, hz, sensors, "ENU", "/".join(sorted(systems)),
                        warnings)


def _stream(raw: _RawFile, index: np.ndarray, n: int) -> SensorStream:
    W = _CONVERSIONS[raw.coordinate_system]
    R_file = _orientation(raw)
    R = W @ R_file
    R_full = np.full((n, 3, 3), np.nan)
    R_full[index] = R
    valid = np.zeros(n, dtype=bool)
    valid[index] = np.isfinite(R).all(axis=(1, 2))
    _fill_gaps(R_full, valid, index)
    vectors: dict[str, np.ndarray | None] = {}
    for name, cols in _VECTORS.items():
        v = _column(raw, cols)
        vectors[name] = None if v is None else _place(v, index, n)
    free = next((_column(raw, cols) for cols in _FREE_ACC if _column(raw, cols) is not None),
                None)
    free_acc = None if free is None else _place(free @ W.T, index, n)
    span = int(index.max() - index.min() + 1) if len(index) else 0
    return SensorStream(raw.sensor_id, R_full, valid, vectors["acc"], free_acc, vectors["gyr"],
                        vectors["mag"], len(raw.data), span - len(np.unique(index)),
                        list(raw.columns), raw.path)


def _place(values: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    out = np.full((n, values.shape[1]), np.nan)
    out[index] = values
    return out


def _fill_gaps(R: np.ndarray, valid: np.ndarray, index: np.ndarray) -> None:
    """Slerp the orientation across gaps inside the sensor's span (flags stay invalid)."""
    good = np.nonzero(valid)[0]
    if len(good) < 2:
        return
    missing = np.setdiff1d(np.arange(good[0], good[-1] + 1), good)
    if not len(missing):
        return
    right = np.searchsorted(good, missing)
    k0, k1 = good[right - 1], good[right]
    t = (missing - k0) / (k1 - k0)
    q = slerp(matrix_to_quat_wxyz(R[k0]), matrix_to_quat_wxyz(R[k1]), t)
    R[missing] = quat_wxyz_to_matrix(q)
