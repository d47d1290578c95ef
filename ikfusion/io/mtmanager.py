"""Xsens MT Manager ASCII exports: one file per sensor, joined on a common time base.

Every variant of SPEC section 4 is read:

* ``//`` comment lines anywhere: the old header (``// Update Rate: 100.0Hz``) and the newer
  ``// General information:`` blocks (``//  DeviceId: 00B42D4B``, ``// Coordinate system: ENU``);
* the header line of column names, which holds ``PacketCounter``;
* tab, comma, semicolon or space delimiters (in space-delimited files an empty field is a run of
  spaces), empty fields and ``NaN`` (read as NaN, the rest of the row intact, the sample flagged
  invalid);
* the orientation as ``Quat_q0..3`` (w, x, y, z), ``Mat[i][j]`` (row i, column j of
  ``R_world_sensor``) or ``Roll/Pitch/Yaw`` [deg] (``R = Rz(yaw) Ry(pitch) Rx(roll)``); a file with
  several uses the quaternion, then the matrix, then the Euler angles, row by row;
* optional ``Acc_*`` [m/s^2] and ``Gyr_*`` [rad/s] and ``Mag_*`` [a.u.] (sensor frame),
  ``FreeAcc_*`` [m/s^2] (world frame, columns named after the world axes, e.g. ``FreeAcc_E``),
  ``SampleTimeFine`` (10 kHz ticks), UTC and other columns (kept in ``channels``).

The time base comes from PacketCounter, a 16-bit counter that wraps at 65536: it is unwrapped
and checked by :mod:`ikfusion.io.packet_counter` (``SampleTimeFine``, when present, decides how
many wraps a step spans; rows out of order are sorted; a restarted, swapped or scrambled counter
is refused rather than turned into a huge timeline), and every sensor of a trial is placed at
sample ``counter - first counter of the trial``. The rate comes from ``// Update Rate:``, else
the ``SampleTimeFine`` or UTC columns, else the rate given (:mod:`ikfusion.io.sample_rate`).
Infinite or physically impossible values make their sample invalid
(:mod:`ikfusion.io.plausibility`).
A gap in the counter is a lost packet: reported per sensor, its orientation slerp-filled and
flagged invalid. Sensors that start late or stop early are NaN and invalid outside their span.
NED and NWU exports are converted to ENU: ``R_ENU_sensor = R_ENU_NED @ R_NED_sensor`` and the
free acceleration likewise; acc, gyr and mag stay in the sensor frame.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..rotations import R_ENU_NED, R_ENU_NWU
from .orientation_columns import OrientationColumns, orientation_from_columns
from .packet_counter import COUNTER_WRAP, place_counter, trial_span_limit
from .plausibility import mtmanager_checks, screen, screen_warning
from .recording import (
    ImuRecording,
    SensorStream,
    build_stream,
    check_sensor_ids,
    gap_summary,
    normalize_sensor_id,
)
from .sample_rate import trial_rate
from .table import (
    delimiter_name,
    detect_delimiter,
    fit_fields,
    parse_block,
    parse_numeric,
    repeated_byte,
    short_quote,
    split_header,
)

__all__ = [
    "ImuRecording",
    "MtManagerFile",
    "SensorStream",
    "read_mtmanager",
    "read_mtmanager_file",
    "trial_files",
]

_ID_IN_NAME = re.compile(r"([0-9A-Fa-f]{8})\.txt$", re.IGNORECASE)
_ID_OF_FILE = re.compile(r"([0-9A-Fa-f]{8})\.(?:txt|csv)$", re.IGNORECASE)
_RATE = re.compile(r"(?:update|sample|output)\s*rate\s*[:=]\s*([0-9]+(?:[.,][0-9]*)?)\s*(k?hz)?",
                   re.IGNORECASE)
_SYSTEM = re.compile(r"coordinate\s*system\s*:\s*([A-Za-z]*)", re.IGNORECASE)
_DEVICE = re.compile(r"device\s*id\s*:\s*([0-9A-Fa-f]{8})\b", re.IGNORECASE)
_VECTORS = {"acc": "Acc_", "gyr": "Gyr_", "mag": "Mag_"}


def world_conversions() -> dict[str, np.ndarray]:
    """``R_ENU_<system>`` for the coordinate systems MT Manager exports."""
    return {"ENU": np.eye(3), "NED": R_ENU_NED, "NWU": R_ENU_NWU}


def world_axis_letters() -> dict[str, np.ndarray]:
    """ENU direction of each world-axis letter used in column names (``FreeAcc_E`` ...)."""
    return {"E": np.array([1.0, 0.0, 0.0]), "W": np.array([-1.0, 0.0, 0.0]),
            "N": np.array([0.0, 1.0, 0.0]), "S": np.array([0.0, -1.0, 0.0]),
            "U": np.array([0.0, 0.0, 1.0]), "D": np.array([0.0, 0.0, -1.0])}


@dataclass
class MtManagerFile:
    """One export parsed into columns (no time base yet).

    Attributes:
        path: The file.
        sensor_id: From the file name ``<prefix><id>.txt``, else the header's DeviceId.
        rate: ``// Update Rate:`` [Hz], or None when the file has none.
        coordinate_system: ``// Coordinate system:`` (ENU when absent).
        columns: Column names of the header line.
        data: (rows, columns) floats, NaN where a field is empty or NaN.
        line_numbers: (rows,) 1-based line number of each data row.
        header_line: 1-based line number of the header line.
        delimiter: The field delimiter.
        warnings: Remarks made while reading (odd lines, skipped repeated headers, ...).
    """

    path: Path
    sensor_id: str
    rate: float | None
    coordinate_system: str
    columns: list[str]
    data: np.ndarray
    line_numbers: np.ndarray
    header_line: int
    delimiter: str
    warnings: list[str] = field(default_factory=list)
    _positions: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._positions = {}
        for k, name in enumerate(self.columns):  # the first column of a name, as list.index
            self._positions.setdefault(name.lower(), k)

    def column(self, name: str) -> np.ndarray | None:
        """The values of one column (case-insensitive name), or None when absent."""
        k = self.index(name)
        return None if k is None else self.data[:, k]

    def index(self, name: str) -> int | None:
        """Position of a column (case-insensitive name), or None."""
        return self._positions.get(name.lower())


@dataclass
class _HeaderInfo:
    """What the ``//`` comment lines say."""

    rate: float | None = None
    system: str = "ENU"
    device: str | None = None


def _read_text(file: Path) -> str:
    if file.is_dir():
        raise InputError("is a folder, not an MT Manager export file", path=file)
    try:
        raw = file.read_bytes()
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", path=file) from err
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    text = text.lstrip("\ufeff")
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


def _comment_info(text: str, file: Path, number: int, info: _HeaderInfo) -> None:
    if m := _RATE.search(text):
        value = float(m.group(1).replace(",", "."))
        if (m.group(2) or "").lower() == "khz":
            value *= 1000.0
        if value <= 0:
            raise InputError(f"the update rate must be positive, found {value:g} Hz", path=file,
                             line=number, field="Update Rate")
        info.rate = value
    if m := _SYSTEM.search(text):
        system = m.group(1).upper()
        if system not in world_conversions():
            raise InputError(f"unknown coordinate system {short_quote(m.group(1))} (ENU, NED or "
                             "NWU)",
                             path=file, line=number, field="Coordinate system")
        info.system = system
    if m := _DEVICE.search(text):
        info.device = m.group(1).upper()


def read_mtmanager_file(path: str | Path) -> MtManagerFile:
    """Parse one export file: comments, header line, numbers (no time base yet).

    Args:
        path: One ``<prefix><sensor id>.txt`` file.

    Raises:
        InputError: An empty file, no header line with PacketCounter, a truncated line, a field
            that is not a number (naming file, line and column).
    """
    file = Path(path)
    text = _read_text(file)
    if not text.strip():
        raise InputError("empty file: an MT Manager export has `//` comment lines, a header line "
                         "starting with PacketCounter and data rows", path=file, line=1,
                         field="PacketCounter")
    info = _HeaderInfo()
    header, header_line, body_start = _find_header(text, file, info)
    delimiter = detect_delimiter(header)
    columns = split_header(header, delimiter)
    _check_header(columns, delimiter, file, header_line)
    body = text[body_start:].rstrip("\n")
    data = None
    raw = np.frombuffer(body.encode(), np.uint8)
    if not (repeated_byte(raw, ord("/")) or repeated_byte(raw, ord("\n"))):  # no comment or
        data = parse_block(body, delimiter, len(columns))  # blank line: one call parses all
    warnings: list[str] = []
    if data is not None:
        numbers = header_line + 1 + np.arange(len(data), dtype=np.int64)
    else:
        lines, line_list = _data_lines(body, header, header_line, file, info, warnings)
        lines = fit_fields(lines, line_list, delimiter, columns, file)
        data = parse_numeric(lines, line_list, delimiter, columns, file)
        numbers = np.asarray(line_list, dtype=np.int64)
    sensor_id = _sensor_id(file, info.device, warnings)
    return MtManagerFile(file, sensor_id, info.rate, info.system, columns, data, numbers,
                         header_line, delimiter, warnings)


def _find_header(text: str, file: Path, info: _HeaderInfo) -> tuple[str, int, int]:
    """The header line, its 1-based number and where the data start; reads the comments."""
    pos, number = 0, 0
    while pos < len(text):
        end = text.find("\n", pos)
        end = len(text) if end < 0 else end
        line = text[pos:end].strip()
        number += 1
        if line.startswith("//"):
            _comment_info(line, file, number, info)
        elif line:
            return text[pos:end], number, end + 1
        pos = end + 1
    raise InputError("no header line: only comment lines, no line of column names starting "
                     "with PacketCounter", path=file, line=max(number, 1), field="PacketCounter")


def _check_header(columns: list[str], delimiter: str, file: Path, line: int) -> None:
    lowered = [c.lower() for c in columns]
    if "packetcounter" not in lowered:  # not an MT Manager export: say nothing of its content
        raise InputError(f"not an MT Manager export: line {line}, the first line that is not a "
                         f"`//` comment, should be the header line of column names with "
                         f"PacketCounter; it has no PacketCounter column ({len(columns)} "
                         f"field{'s' if len(columns) != 1 else ''} when split by "
                         f"{delimiter_name(delimiter)})",
                         path=file, line=line, field="PacketCounter")
    twice = sorted({c for c in columns if lowered.count(c.lower()) > 1})
    if twice:
        raise InputError(f"columns named twice in the header: "
                         f"{', '.join(short_quote(t) for t in twice[:5])}", path=file,
                         line=line, field=twice[0])


def _data_lines(body: str, header: str, header_line: int, file: Path, info: _HeaderInfo,
                warnings: list[str]) -> tuple[list[str], list[int]]:
    """Data lines and their numbers, skipping blank and comment lines (line by line)."""
    lines: list[str] = []
    numbers: list[int] = []
    header_key = header.strip()
    for k, line in enumerate(body.split("\n")):
        number = header_line + 1 + k
        text = line.strip()
        if not text:
            continue
        if text.startswith("//"):
            _comment_info(text, file, number, info)
            continue
        if text == header_key:
            warnings.append(f"{file.name} line {number}: the header line repeated; skipped")
            continue
        lines.append(line)
        numbers.append(number)
    return lines, numbers


def _sensor_id(file: Path, device: str | None, warnings: list[str]) -> str:
    match = _ID_OF_FILE.search(file.name)
    if match:
        sid = match.group(1).upper()
        if device is not None and device != sid:
            warnings.append(f"{file.name}: the header says DeviceId {device} but the file name "
                            f"says {sid}; using {sid}")
        return sid
    if device is not None:
        return device
    return normalize_sensor_id(file.stem)


def trial_files(path: str | Path) -> list[Path]:
    """The export files of a trial given by one file, a folder or a trial prefix.

    A folder must hold the exports of one trial (``<prefix><8 hex digit id>.txt`` with one
    prefix); a prefix ``folder/MT_012005D6_009-001_`` selects the files named prefix + id.

    Raises:
        InputError: Nothing found, or a folder with several trials (listing their prefixes).
    """
    p = Path(path)
    if p.is_file():
        return [p]
    if p.is_dir():
        exports = sorted(f for f in p.iterdir() if f.is_file() and _ID_IN_NAME.search(f.name))
        if not exports:
            others = sorted(f.name for f in p.iterdir())[:8]
            raise InputError("no MT Manager exports (files named <trial prefix><8 hex digit "
                             f"sensor id>.txt) in the folder; it holds: "
                             f"{', '.join(others) or 'nothing'}", path=p, field="PATH")
        prefixes: dict[str, int] = {}
        for f in exports:
            prefix = f.name[:-len("00B40000.txt")]
            prefixes[prefix] = prefixes.get(prefix, 0) + 1
        if len(prefixes) > 1:
            listed = ", ".join(f"{k or '(no prefix)'} ({v} file{'s' if v > 1 else ''})"
                               for k, v in prefixes.items())
            raise InputError(f"the folder holds the exports of {len(prefixes)} trials: {listed}; "
                             f"give one trial prefix, e.g. {p / next(iter(prefixes))}",
                             path=p, field="PATH")
        return exports
    parent = p.parent if str(p.parent) else Path(".")
    if parent.is_dir():
        exports = sorted(f for f in parent.glob(_glob_escape(p.name) + "*")
                         if f.is_file() and _ID_IN_NAME.fullmatch(f.name[len(p.name):]))
        if exports:
            return exports
    raise InputError("no file, folder or trial prefix with MT Manager exports "
                     "(<prefix><8 hex digit sensor id>.txt)", path=p, field="PATH")


def _glob_escape(text: str) -> str:
    return re.sub(r"([*?\[])", r"[\1]", text)


@dataclass
class _Placed:
    """One file's rows on the trial's counter: unwrapped counters and kept rows."""

    file: MtManagerFile
    counter: np.ndarray  # (r,) unwrapped counter of the kept rows
    rows: np.ndarray  # (r,) row indices into file.data (first occurrence of each counter)
    wraps: bool  # a 16-bit counter (its epoch can shift by whole wraps)


def _place(file: MtManagerFile, hz: float, warnings: list[str]) -> _Placed:
    k = file.index("PacketCounter")
    if k is None:  # read_mtmanager_file guarantees the column; kept for the type checker
        raise InputError("no PacketCounter column", path=file.path, line=file.header_line,
                         field="PacketCounter")
    counter, rows, wraps = place_counter(file.data[:, k], file.column("SampleTimeFine"),
                                         file.line_numbers, file.header_line, file.path,
                                         file.columns[k], hz, warnings, file.data)
    return _Placed(file, counter, rows, wraps)


def _align_epochs(placed: list[_Placed]) -> None:
    """Shift 16-bit counters by whole wraps to start within half a wrap of the first file's.

    The sensors of one trial share the counter, but a sensor whose first packets were lost
    across a wrap starts on the other side of it.
    """
    reference = next((int(p.counter[0]) for p in placed if len(p.counter)), None)
    if reference is None:
        return
    for p in placed:
        if len(p.counter) and p.wraps:
            shift = int(np.round((reference - int(p.counter[0])) / COUNTER_WRAP))
            p.counter = p.counter + COUNTER_WRAP * shift


def _check_trial_span(placed: list[_Placed], start: int, end: int) -> None:
    """Refuse files whose counters lie too far apart to be one recording."""
    nonempty = [p for p in placed if len(p.counter)]
    limit = trial_span_limit([int(p.counter[-1] - p.counter[0]) + 1 for p in nonempty])
    if end - start + 1 <= limit:
        return
    middle = float(np.median([p.counter[0] for p in nonempty]))
    odd = max(nonempty, key=lambda p: abs(float(p.counter[0]) - middle))
    raise InputError(f"the PacketCounter of this file starts at {int(odd.counter[0])} while the "
                     f"trial's other files start near {int(middle)}: the files together would "
                     f"span {end - start + 1} samples; they do not come from one recording",
                     path=odd.file.path, line=int(odd.file.line_numbers[odd.rows[0]]),
                     field="PacketCounter")


def read_mtmanager(path: str | Path, rate: float | None = None,
                   sensor_map: Mapping[str, str] | None = None, *,
                   require_rate: bool = True) -> ImuRecording:
    """Read a trial of MT Manager exports: a trial prefix, a folder or one file.

    Args:
        path: ``folder/``, ``folder/MT_012005D6_009-001_`` (a trial prefix) or one
            ``...00B421E6.txt``.
        rate: Sample rate [Hz] for files that do not tell it (the command line's ``--rate``).
            The files' own rate wins (``// Update Rate:``, else SampleTimeFine or UTC
            columns); a disagreement is reported in the warnings.
        sensor_map: Sensor id -> segment: every mapped sensor must be in the trial; trial
            sensors the map does not name are reported in the warnings.
        require_rate: When False, a trial whose rate nothing tells is read with ``rate`` and
            ``time`` NaN and ``rate_source`` ``"unknown"`` (for ``inspect``).

    Returns:
        The :class:`ImuRecording` (ENU world, time from 0 at the trial's first sample);
        ``rate_source`` says where the rate came from
        (:data:`ikfusion.io.sample_rate.RATE_SOURCES`).

    Raises:
        InputError: Naming the file, line and column of bad input; a rate that cannot be known;
            files that disagree on the rate; mapped sensors missing from the trial; a
            PacketCounter that cannot be placed in time.
    """
    files = [read_mtmanager_file(f) for f in trial_files(path)]
    warnings = [w for f in files for w in f.warnings]
    hz, rate_source = trial_rate(files, rate, warnings, required=require_rate)
    placed = [_place(f, hz, warnings) for f in files]
    _align_epochs(placed)
    nonempty = [p for p in placed if len(p.counter)]
    if not nonempty:
        raise InputError("no data rows in any file of the trial", path=files[0].path,
                         line=files[0].header_line + 1)
    start = min(int(p.counter[0]) for p in nonempty)
    end = max(int(p.counter[-1]) for p in nonempty)
    _check_trial_span(placed, start, end)
    n = end - start + 1
    counter = start + np.arange(n, dtype=np.int64)
    sensors: dict[str, SensorStream] = {}
    for p in placed:
        stream = _stream(p, start, n, counter, warnings)
        if stream.sensor_id in sensors:
            raise InputError(f"sensor {stream.sensor_id} appears twice in the trial (also in "
                             f"{sensors[stream.sensor_id].path})", path=p.file.path)
        sensors[stream.sensor_id] = stream
        _span_warnings(stream, n, hz, warnings)
    systems = sorted({f.coordinate_system for f in files})
    recording = ImuRecording(time=np.arange(n) / hz, rate=hz, sensors=sensors,
                             coordinate_system="ENU", source_coordinate_system="/".join(systems),
                             source=[f.path for f in files], warnings=warnings,
                             rate_source=rate_source)
    if sensor_map is not None:
        recording.warnings += check_sensor_ids(sensor_map, sensors, Path(path))
    return recording


def _stream(p: _Placed, start: int, n: int, counter: np.ndarray,
            warnings: list[str]) -> SensorStream:
    file = p.file
    W = world_conversions()[file.coordinate_system]
    orientation = OrientationColumns.find(file.columns)
    for message in orientation.warnings:
        warnings.append(f"{file.path.name}: {message}")
    data = file.data[p.rows]
    impossible = screen_warning(f"sensor {file.sensor_id}",
                                screen(data, mtmanager_checks(file.columns)))
    if impossible:
        warnings.append(impossible)
    R_file, source, notes = orientation_from_columns(orientation, data)
    for message in notes:
        warnings.append(f"{file.path.name}: {message}")
    R = W @ R_file
    vectors: dict[str, np.ndarray | None] = {}
    for name, prefix in _VECTORS.items():
        vectors[name] = _sensor_vector(file, data, prefix, warnings)
    vectors["free_acc"] = _free_acc(file, data, W, warnings)
    for name, values in list(vectors.items()):
        if values is not None and len(values) and not np.isfinite(values).any():
            warnings.append(f"{file.path.name}: the {name} columns are empty in every row; "
                            "ignored")
            vectors[name] = None
    if not orientation.available:
        warnings.append(f"{file.path.name}: no orientation columns (Quat_q0..3, Mat[i][j] or "
                        "Roll/Pitch/Yaw); the orientation is NaN and every sample invalid")
    index = p.counter - start
    return build_stream(file.sensor_id, index, n, R, vectors, rows=len(file.data),
                        channels=list(file.columns), packet_counter=counter,
                        orientation_source=source, path=file.path)


def _sensor_vector(file: MtManagerFile, data: np.ndarray, prefix: str,
                   warnings: list[str]) -> np.ndarray | None:
    names = [prefix + a for a in "XYZ"]
    where = [file.index(c) for c in names]
    if all(k is None for k in where):
        return None
    if any(k is None for k in where):
        absent = [c for c, k in zip(names, where) if k is None]
        warnings.append(f"{file.path.name}: column(s) {', '.join(absent)} missing; those "
                        "components are NaN")
    return np.column_stack([data[:, k] if k is not None else np.full(len(data), np.nan)
                            for k in where])


def _free_acc(file: MtManagerFile, data: np.ndarray, W: np.ndarray,
              warnings: list[str]) -> np.ndarray | None:
    """Free acceleration in the ENU world from ``FreeAcc_<axis>`` columns."""
    found = [(k, c[len("FreeAcc_"):].upper()) for k, c in enumerate(file.columns)
             if c.lower().startswith("freeacc_")]
    if not found:
        return None
    letters = world_axis_letters()
    out = np.zeros((len(data), 3))
    covered = np.zeros(3)
    for k, axis in found:
        if axis in letters:
            direction = letters[axis]
        elif axis in ("X", "Y", "Z"):
            direction = W[:, "XYZ".index(axis)]
        else:
            warnings.append(f"{file.path.name}: column {file.columns[k]} names no world axis; "
                            "ignored")
            continue
        out += data[:, k][:, None] * direction[None, :]
        covered += np.abs(direction)
    if np.any(covered == 0):
        warnings.append(f"{file.path.name}: the FreeAcc columns do not cover three world axes; "
                        "the missing components are NaN")
        out[:, covered == 0] = np.nan
    return out


def _span_warnings(stream: SensorStream, n: int, hz: float, warnings: list[str]) -> None:
    """Lost packets, late start and early stop of one sensor, for the user."""
    summary = gap_summary(stream.sensor_id, stream.gaps, hz)
    if summary:
        warnings.append(summary)
    if not stream.received.any():
        warnings.append(f"sensor {stream.sensor_id}: no data rows")
        return
    first, end = stream.span
    if first > 0:
        warnings.append(f"sensor {stream.sensor_id} starts {_samples(first, hz)} after the "
                        "trial's first sample; NaN and invalid before")
    if end < n:
        warnings.append(f"sensor {stream.sensor_id} stops {_samples(n - end, hz)} before the "
                        "trial's last sample; NaN and invalid after")


def _samples(count: int, hz: float) -> str:
    """``1.50 s (150 samples)``, or ``150 samples`` when the rate is unknown."""
    return f"{count / hz:.2f} s ({count} samples)" if np.isfinite(hz) else f"{count} samples"
