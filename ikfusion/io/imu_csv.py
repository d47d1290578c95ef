"""Generic IMU CSV, for data from other vendors (SPEC section 4).

One row per sensor and sample::

    time,sensor,qw,qx,qy,qz,ax,ay,az,gx,gy,gz
    0.00,pelvis,0.7071,0,0,0.7071,0.1,0.0,9.8,0.01,0.0,0.0

``time`` [s] on a common clock, ``sensor`` any label, the quaternion ``R_world_sensor`` scalar
first (w, x, y, z) in a Z-up world (taken as ENU), and optionally the specific force ``ax, ay, az``
[m/s^2] and the angular rate ``gx, gy, gz`` [rad/s] in the sensor frame. Rows are placed on a
common time base at the rate given or, by default, the median sample interval; a sample missing
inside a sensor's span is a lost sample (orientation slerp-filled and flagged invalid). Empty
and ``NaN`` fields are NaN with the rest of the row intact (the sample flagged invalid); infinite
or physically impossible values likewise, with a warning (:mod:`ikfusion.io.plausibility`). Time
stamps that would stretch the timeline far beyond the rows (``2 x rows + 65536`` samples) are
refused, naming the line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .orientation_columns import R_from_quat
from .packet_counter import COUNTER_WRAP
from .plausibility import MAGNITUDE_LIMITS, FieldCheck, screen, screen_warning
from .recording import ImuRecording, SensorStream, build_stream, gap_summary
from .table import detect_delimiter, fit_fields, parse_numeric, split_header

REQUIRED: tuple[str, ...] = ("time", "sensor", "qw", "qx", "qy", "qz")
OPTIONAL: tuple[str, ...] = ("ax", "ay", "az", "gx", "gy", "gz")


def _read_lines(file: Path) -> list[str]:
    try:
        return file.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", path=file) from err


def read_imu_csv(path: str | Path, rate: float | None = None) -> ImuRecording:
    """Read a generic IMU CSV into an :class:`ImuRecording`.

    Args:
        path: The CSV file.
        rate: Sample rate [Hz]; estimated from the median time step when omitted.

    Returns:
        The recording; sensor ids are the ``sensor`` labels in order of appearance.

    Raises:
        InputError: An empty file, missing columns, a truncated line, a field that is not a
            number, a row without time (naming the line and column), fewer than two instants.
    """
    file = Path(path)
    lines = _read_lines(file)
    numbered = [(n + 1, ln) for n, ln in enumerate(lines)
                if ln.strip() and not ln.lstrip().startswith("#")]
    if not numbered:
        raise InputError(f"empty file: expected the header {','.join(REQUIRED)}", path=file,
                         line=1, field="time")
    header_line, header = numbered[0]
    delimiter = detect_delimiter(header)
    columns = [c.lower() for c in split_header(header, delimiter)]
    missing = [c for c in REQUIRED if c not in columns]
    if missing:
        known = [c for c in columns if c in REQUIRED + OPTIONAL]
        found = (f"found {', '.join(known)} and {len(columns) - len(known)} other field(s)"
                 if known else f"none of them among its {len(columns)} field(s): not an IMU CSV")
        raise InputError(f"columns missing: {', '.join(missing)} (the header line, the first "
                         f"line that is not a # comment, must hold {','.join(REQUIRED)} and "
                         f"optionally {','.join(OPTIONAL)}; {found})", path=file,
                         line=header_line, field=missing[0])
    numbers = [n for n, _ in numbered[1:]]
    body = fit_fields([ln for _, ln in numbered[1:]], numbers, delimiter, columns, file)
    k_sensor = columns.index("sensor")
    split = [ln.split(delimiter) for ln in body]
    labels = [row[k_sensor].strip() for row in split]
    for row in split:
        row[k_sensor] = "0"
    numeric = parse_numeric([delimiter.join(r) for r in split], numbers, delimiter, columns,
                            file)
    return _assemble(file, columns, numeric, labels, np.asarray(numbers), rate)


def _assemble(file: Path, columns: list[str], values: np.ndarray, labels: list[str],
              numbers: np.ndarray, rate: float | None) -> ImuRecording:
    col = {c: k for k, c in enumerate(columns)}
    t = values[:, col["time"]]
    if not np.isfinite(t).all():
        bad = int(np.argmin(np.isfinite(t)))
        raise InputError("every row needs a time [s]", path=file, line=int(numbers[bad]),
                         field="time")
    empty = [i for i, s in enumerate(labels) if not s]
    if empty:
        raise InputError("every row needs a sensor label", path=file,
                         line=int(numbers[empty[0]]), field="sensor")
    names = np.asarray(labels)
    warnings: list[str] = []
    hz = rate if rate is not None else _estimate_rate(t, names, file)
    if not np.isfinite(hz) or hz <= 0:
        raise InputError(f"the rate must be a positive number of Hz, not {hz!r}",
                         field="--rate")
    position = (t - t.min()) * hz
    _check_span(position, names, numbers, file)
    slot = np.round(position).astype(np.int64)
    jitter = float(np.max(np.abs(position - slot)))
    if jitter > 0.25:
        warnings.append(f"{file.name}: time stamps are off the {hz:g} Hz grid by up to "
                        f"{jitter:.2f} sample; each row is placed at the nearest sample")
    n = int(slot.max()) + 1
    streams: dict[str, SensorStream] = {}
    for sid in dict.fromkeys(labels):
        rows = np.flatnonzero(names == sid)
        _, first = np.unique(slot[rows], return_index=True)
        kept = rows[np.sort(first)]
        if len(kept) < len(rows):
            warnings.append(f"{file.name}: sensor {sid} has {len(rows) - len(kept)} row(s) at "
                            "an instant it already had; the first is kept")
        block = values[kept].copy()
        impossible = screen_warning(f"{file.name}: sensor {sid}", screen(block, _checks(col)))
        if impossible:
            warnings.append(impossible)
        R, notes = R_from_quat(block[:, [col[c] for c in ("qw", "qx", "qy", "qz")]])
        warnings += [f"{file.name}: sensor {sid}: {m}" for m in notes]
        vectors = {"acc": _vector(block, col, ("ax", "ay", "az")),
                   "gyr": _vector(block, col, ("gx", "gy", "gz"))}
        streams[sid] = build_stream(sid, slot[kept], n, R, vectors, rows=len(rows),
                                    channels=list(columns), orientation_source="Quat",
                                    path=file)
        summary = gap_summary(sid, streams[sid].gaps, hz)
        if summary:
            warnings.append(summary)
    return ImuRecording(time=np.arange(n) / hz, rate=float(hz), sensors=streams,
                        coordinate_system="ENU", source_coordinate_system="ENU",
                        source=[file], warnings=warnings,
                        rate_source="--rate" if rate is not None else "time")


def _checks(col: dict[str, int]) -> list[FieldCheck]:
    """Plausibility checks of the quaternion, specific force and angular rate columns."""
    checks = [FieldCheck("quaternion", tuple(col[c] for c in ("qw", "qx", "qy", "qz")),
                         "quaternion")]
    for label, names in (("Acc", ("ax", "ay", "az")), ("Gyr", ("gx", "gy", "gz"))):
        where = tuple(col[c] for c in names if c in col)
        if where:
            checks.append(FieldCheck(label, where, "magnitude", MAGNITUDE_LIMITS[label]))
    return checks


def _check_span(position: np.ndarray, names: np.ndarray, numbers: np.ndarray,
                file: Path) -> None:
    """Refuse times that would make the timeline far longer than the rows can fill.

    Like the MT Manager reader: at most ``2 x rows + 65536`` samples, rows being those of the
    sensor with the most.
    """
    _, per_sensor = np.unique(names, return_counts=True)
    limit = 2 * int(per_sensor.max()) + COUNTER_WRAP
    if float(np.max(position)) + 1 <= limit:
        return
    order = np.argsort(position, kind="stable")
    k = int(np.argmax(np.diff(position[order])))
    raise InputError(f"the time jumps by {(position[order[k + 1]] - position[order[k]]):.0f} "
                     f"samples: the recording would span {float(np.max(position)) + 1:.0f} "
                     f"samples for {int(per_sensor.max())} rows per sensor; a time stamp is "
                     "corrupted or the rows come from different recordings", path=file,
                     line=int(numbers[order[k + 1]]), field="time")


def _vector(block: np.ndarray, col: dict[str, int], names: tuple[str, str, str]
            ) -> np.ndarray | None:
    if not any(c in col for c in names):
        return None
    return np.column_stack([block[:, col[c]] if c in col else np.full(len(block), np.nan)
                            for c in names])


def _estimate_rate(t: np.ndarray, names: np.ndarray, file: Path) -> float:
    """Rate [Hz]: the median step, refined by a least-squares fit of time against sample index.

    The fit over the whole file is insensitive to time-stamp jitter and to missing samples; a
    rate within 0.2 % of a whole number of Hz is rounded to it.
    """
    steps = []
    for sid in np.unique(names):
        times = np.unique(t[names == sid])
        if len(times) > 1:
            steps.append(np.diff(times))
    if not steps:
        raise InputError("fewer than two instants per sensor: the rate cannot be found; give it "
                         "with --rate HZ",
                         path=file, field="time")
    dt = float(np.median(np.concatenate(steps)))
    if dt <= 0:
        raise InputError("the time column does not increase", path=file, field="time")
    index = np.round((t - t.min()) / dt)
    ok = np.isfinite(index)
    if np.ptp(index[ok]) > 0:
        dt = float(np.polyfit(index[ok], t[ok], 1)[0])
    hz = 1.0 / dt
    return float(np.round(hz)) if abs(hz - np.round(hz)) < 2e-3 * hz else hz
