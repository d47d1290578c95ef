"""The sample rate of a trial of MT Manager exports, and where it came from.

SPEC section 4: the rate comes from ``// Update Rate:``, else from the file's own time columns
(``SampleTimeFine``, then the UTC columns ``UTC_Year .. UTC_Second, UTC_Nano``), else from the
rate the user gives (``--rate``). The time columns are read over single PacketCounter steps only,
so lost packets do not bias them. No rate is guessed from the product code: an Awinda MTw runs at
whatever rate was chosen for the number of sensors (40 to 120 Hz) and an MTi at its configured
output rate, so the product alone does not tell it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import numpy as np

from ..errors import InputError
from .packet_counter import COUNTER_WRAP, FINE_HZ, FINE_WRAP

#: ``rate_source`` values of an :class:`ikfusion.io.ImuRecording` read from MT Manager files.
RATE_SOURCES: tuple[str, ...] = ("Update Rate", "SampleTimeFine", "UTC", "--rate", "unknown")
_UTC = ("UTC_Year", "UTC_Month", "UTC_Day", "UTC_Hour", "UTC_Minute", "UTC_Second", "UTC_Nano")


class _TimedFile(Protocol):
    """What the rate needs of a parsed export (see :class:`ikfusion.io.MtManagerFile`)."""

    path: Path
    rate: float | None

    def column(self, name: str) -> np.ndarray | None: ...


def _rate_from_steps(seconds: np.ndarray) -> float | None:
    """Rate [Hz] from the time of single packet steps [s] (robust mean around the median)."""
    seconds = seconds[np.isfinite(seconds)]
    if not len(seconds):
        return None
    median = float(np.median(seconds))
    if median <= 0:
        return None
    close = seconds[np.abs(seconds - median) <= 0.1 * median]
    return round(1.0 / float(np.mean(close)), 3)


def _single_steps(file: _TimedFile, time: np.ndarray, wrap: float | None) -> float | None:
    """Rate [Hz] from a time column [s] (wrapping at ``wrap`` [s]) over single counter steps."""
    counter = file.column("PacketCounter")
    if counter is None:
        return None
    ok = np.isfinite(time) & np.isfinite(counter)
    if ok.sum() < 2:
        return None
    step = np.mod(np.diff(counter[ok]), COUNTER_WRAP)
    dt = np.diff(time[ok])
    if wrap is not None:
        dt = np.mod(dt, wrap)
    return _rate_from_steps(dt[step == 1])


def fine_rate(file: _TimedFile) -> float | None:
    """Rate [Hz] from SampleTimeFine ticks (10 kHz) over single PacketCounter steps."""
    fine = file.column("SampleTimeFine")
    if fine is None:
        return None
    return _single_steps(file, fine / FINE_HZ, FINE_WRAP / FINE_HZ)


def utc_seconds(file: _TimedFile) -> np.ndarray | None:
    """Seconds of each row since the first row's day from the UTC columns (NaN where absent)."""
    parts = [file.column(name) for name in _UTC]
    if any(p is None for p in parts[:6]):
        return None
    year, month, day, hour, minute, second, nano = (
        p if p is not None else np.zeros_like(parts[0]) for p in parts)
    ok = np.isfinite(year) & np.isfinite(month) & np.isfinite(day) & np.isfinite(hour) \
        & np.isfinite(minute) & np.isfinite(second) & (month >= 1) & (month <= 12) & (day >= 1)
    valid = file.column("UTC_Valid")
    if valid is not None:
        ok &= ~(np.isfinite(valid) & (valid == 0))
    if ok.sum() < 2:
        return None
    months = ((year[ok] - 1970) * 12 + month[ok] - 1).astype(np.int64)
    days = (np.datetime64("1970-01", "M") + months.astype("timedelta64[M]")).astype(
        "datetime64[D]").astype(np.int64) + day[ok].astype(np.int64) - 1
    out = np.full(len(year), np.nan)
    out[ok] = ((days - days[0]) * 86400.0 + hour[ok] * 3600.0 + minute[ok] * 60.0 + second[ok]
               + np.nan_to_num(nano[ok]) * 1e-9)
    return out


def utc_rate(file: _TimedFile) -> float | None:
    """Rate [Hz] from the UTC columns over single PacketCounter steps."""
    seconds = utc_seconds(file)
    return None if seconds is None else _single_steps(file, seconds, None)


def trial_rate(files: Sequence[_TimedFile], rate: float | None, warnings: list[str],
               required: bool = True) -> tuple[float, str]:
    """The rate [Hz] of a trial and its source (one of :data:`RATE_SOURCES`).

    Args:
        files: The parsed exports of the trial.
        rate: The rate the user gave [Hz] (``--rate``), used when the files tell none.
        warnings: Disagreements are appended here.
        required: When False, a rate nothing tells is returned as NaN with source
            ``"unknown"`` instead of raising.

    Raises:
        InputError: Files that disagree on ``// Update Rate:``, a rate given that is not a
            positive number, or (when required) a rate that nothing tells.
    """
    declared = {f.rate for f in files if f.rate is not None}
    if len(declared) > 1:
        listed = ", ".join(f"{f.path.name}: {f.rate:g} Hz" for f in files if f.rate is not None)
        raise InputError(f"the files of the trial disagree on the update rate ({listed})",
                         path=files[0].path, field="Update Rate")
    if rate is not None and (not np.isfinite(rate) or rate <= 0):
        raise InputError(f"the rate must be a positive number of Hz, not {rate!r}",
                         field="--rate")
    rates = [(fine_rate(f), utc_rate(f)) for f in files]  # per file, once
    measured = {"SampleTimeFine": [fine for fine, _ in rates if fine is not None],
                "UTC": [utc for _, utc in rates if utc is not None]}
    if declared:
        hz, source = declared.pop(), "Update Rate"
        note = f"the files declare `// Update Rate: {hz:g}Hz`"
    elif measured["SampleTimeFine"] or measured["UTC"]:
        source = "SampleTimeFine" if measured["SampleTimeFine"] else "UTC"
        hz = float(np.median(measured[source]))
        note = f"the files' {source} column{'s' if source == 'UTC' else ''} say {hz:g} Hz"
        warnings.append(f"no `// Update Rate:` in the files: {hz:g} Hz from {source}")
    elif rate is not None:
        return float(rate), "--rate"
    elif required:
        raise InputError("the sample rate is unknown: the files have no `// Update Rate:` line "
                         "and no SampleTimeFine or UTC time values; give it with --rate HZ",
                         path=files[0].path, field="--rate")
    else:
        return float("nan"), "unknown"
    if rate is not None and abs(rate - hz) > 1e-3 * hz:
        warnings.append(f"{note}; the rate given ({rate:g} Hz) is not used")
    _cross_check(files, rates, hz, warnings)
    return hz, source


def _cross_check(files: Sequence[_TimedFile], rates: list[tuple[float | None, float | None]],
                 hz: float, warnings: list[str]) -> None:
    """Warn of files whose (SampleTimeFine, UTC) ``rates`` [Hz] are 2 % off ``hz``."""
    for f, (fine, utc) in zip(files, rates):
        for name, r in (("SampleTimeFine", fine), ("UTC", utc)):
            if r is not None and abs(r - hz) > 0.02 * hz:
                warnings.append(f"{f.path.name}: {name} steps say {r:.4g} Hz but the "
                                f"recording rate is {hz:g} Hz")
