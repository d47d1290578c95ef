"""PacketCounter of MT Manager exports: checked, unwrapped and bounded before it becomes time.

The counter is the time base of a trial, so a damaged one must never become a huge timeline:

* a 16-bit counter (every value < 65536) wraps; each step is read as the signed step between
  -32768 and 32767 packets, and where ``SampleTimeFine`` (10 kHz ticks, 32-bit) is known it
  decides how many whole wraps the step spans, forwards or backwards;
* a PacketCounter column stepping by more than 1 beside a SampleTimeFine column stepping by 1
  is a swapped header, refused;
* one row whose counter is far from both its neighbours while they agree with each other is a
  corrupted counter value: the row is skipped (its data kept out of the timeline rather than
  placed at a wrong time), unless ``SampleTimeFine`` agrees with its counter;
* rows out of order are sorted by counter when the time agrees (``SampleTimeFine`` going back
  with it, or no ``SampleTimeFine``); a counter that goes back while ``SampleTimeFine`` goes
  forward has restarted and is refused;
* a file never spans more samples than ``2 x rows + 65536 +`` the lost packets that
  ``SampleTimeFine`` confirms: lost packets beyond what a 16-bit counter can tell are a
  corrupted counter or rows of another recording, refused with the line of the largest jump.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError

#: A 16-bit PacketCounter wraps here.
COUNTER_WRAP = 65536
#: SampleTimeFine (32-bit) wraps here.
FINE_WRAP = 2**32
#: SampleTimeFine ticks per second.
FINE_HZ = 10000.0
#: Neighbouring counters this many packets apart or closer agree with each other.
_LOCAL = 8


def signed_step(step: np.ndarray, wrap: int) -> np.ndarray:
    """Steps of a wrapping counter read as the nearest signed step in [-wrap/2, wrap/2)."""
    return _mod(step + wrap // 2, wrap) - wrap // 2


def _mod(x: np.ndarray, wrap: int) -> np.ndarray:
    """``np.mod(x, wrap)``, the same values; floats by a power of two without ``fmod``.

    ``x - wrap * floor(x / wrap)`` rounds once, as ``np.mod`` does (``fmod`` is exact, then
    ``+ wrap`` rounds for a negative remainder): dividing and multiplying by a power of two
    are exact. Several times faster than ``np.mod`` on floats (SampleTimeFine steps).
    """
    if x.dtype.kind != "f" or wrap & (wrap - 1) or not 0 < wrap < 2**1000:
        return np.mod(x, wrap)
    return x - wrap * np.floor(x / wrap)


def unplaceable_lines(lines: np.ndarray, rows: np.ndarray) -> str:
    """``line 12, 40, ...`` for a warning (at most five line numbers)."""
    listed = ", ".join(str(int(lines[i])) for i in rows[:5])
    return f"line {listed}{', ...' if len(rows) > 5 else ''}"


def place_counter(raw: np.ndarray, fine: np.ndarray | None, lines: np.ndarray, header_line: int,
                  path: Path, name: str, hz: float, warnings: list[str],
                  table: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, bool]:
    """Unwrap and check one file's PacketCounter.

    Args:
        raw: (rows,) the PacketCounter column (NaN where empty).
        fine: (rows,) the SampleTimeFine column [10 kHz ticks], or None.
        lines: (rows,) 1-based line number of each row.
        header_line: 1-based line number of the header line.
        path: The file (for messages).
        name: The PacketCounter column's name as written.
        hz: Sample rate [Hz], NaN when unknown (SampleTimeFine then counts no wraps).
        warnings: Remarks for the user are appended here.
        table: (rows, columns) all the file's numbers, to tell repeated rows (the same data
            again, dropped) from a counter that repeats over other data (more than a few rows
            in a row: refused).

    Returns:
        The unwrapped counter of the kept rows in counter order, their row indices (the first
        row of each counter value) and whether the counter is 16-bit (its epoch may shift by
        whole wraps).

    Raises:
        InputError: A counter that is not a whole number, a column that is not a packet
            counter, a counter that restarts, or jumps longer than the data can hold.
    """
    rows = np.flatnonzero(np.isfinite(raw))
    if len(rows) < len(raw):
        missing = np.flatnonzero(~np.isfinite(raw))
        warnings.append(f"{path.name}: {len(missing)} row(s) without a PacketCounter cannot be "
                        f"placed in time and are skipped ({unplaceable_lines(lines, missing)})")
    values = raw[rows]
    bad = np.flatnonzero((values != np.round(values)) | (values < 0))
    if len(bad):
        i = rows[bad[0]]
        raise InputError(f"PacketCounter must be a whole number >= 0, found {raw[i]:.10g}",
                         path=path, line=int(lines[i]), field=name)
    if not len(rows):
        return np.zeros(0, dtype=np.int64), rows, True
    wraps = bool(np.mean(values < COUNTER_WRAP) >= 0.5)
    too_wide = values >= (COUNTER_WRAP if wraps else FINE_WRAP)
    if too_wide.any():
        warnings.append(f"{path.name}: {int(too_wide.sum())} PacketCounter value(s) beyond "
                        f"{'16' if wraps else '32'} bit where the others are not: corrupted "
                        f"counters, rows skipped ({unplaceable_lines(lines, rows[too_wide])})")
        rows, values = rows[~too_wide], values[~too_wide]
    counter = values.astype(np.int64)
    wrap = COUNTER_WRAP if wraps else FINE_WRAP
    fine = _valid_fine(fine, lines, path, warnings)
    _check_steps_of_one(counter, wrap, fine, header_line, path, name)
    f = None if fine is None else fine[rows]
    keep = ~_outliers(counter, f, wrap, hz)
    if not keep.all():
        warnings.append(f"{path.name}: {int((~keep).sum())} row(s) whose PacketCounter is far "
                        "from both neighbours (which agree with each other): corrupted "
                        f"counters, rows skipped ({unplaceable_lines(lines, rows[~keep])})")
        rows, counter = rows[keep], counter[keep]
        f = None if f is None else f[keep]
    steps, confirmed = _steps(counter, f, wrap, hz, lines[rows], path, name, warnings)
    unwrapped = counter[0] + np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)
    backwards = int(np.sum(steps < 0))
    if backwards:
        warnings.append(f"{path.name}: PacketCounter goes backwards {backwards} time(s) (first "
                        f"at line {int(lines[rows[1:][steps < 0][0]])}); "
                        f"{'SampleTimeFine agrees, ' if confirmed[steps < 0].all() else ''}"
                        "the rows are sorted by counter")
    unique, first, inverse = np.unique(unwrapped, return_index=True, return_inverse=True)
    if len(unique) < len(unwrapped):
        _repeats(first, inverse, rows, table, lines, path, name, warnings)
    _check_span(unique, steps, confirmed, rows, lines, counter, path, name)
    return unique, rows[first], wraps


def _check_steps_of_one(counter: np.ndarray, wrap: int, fine: np.ndarray | None,
                        header_line: int, path: Path, name: str) -> None:
    """Refuse a PacketCounter and SampleTimeFine that are swapped in the header.

    The sign: the PacketCounter column mostly steps by more than 1 per row while the
    SampleTimeFine column holds 16-bit values stepping by exactly 1. (A counter that merely
    lost many packets steps by more than 1 too; the span bound judges that one.)
    """
    if len(counter) < 5 or fine is None:
        return
    step = signed_step(np.diff(counter), wrap)
    forward = step[step > 0]
    if not len(forward) or float(np.median(forward)) <= 1.0:
        return
    f = fine[np.isfinite(fine)]
    f_step = np.diff(f)
    if len(f) >= 5 and f.max() < COUNTER_WRAP and (f_step > 0).any() \
            and float(np.median(f_step[f_step > 0])) == 1.0:
        raise InputError(f"the {name} and SampleTimeFine columns look swapped: {name} steps by "
                         f"{float(np.median(forward)):g} per row and SampleTimeFine by 1; "
                         "correct the header line", path=path, line=header_line, field=name)


def _valid_fine(fine: np.ndarray | None, lines: np.ndarray, path: Path,
                warnings: list[str]) -> np.ndarray | None:
    """SampleTimeFine with impossible values (not a whole 32-bit tick count) made unknown.

    Such a value cannot confirm a gap: left in, a single corrupted tick count would "confirm"
    millions of lost packets.
    """
    if fine is None:
        return None
    known = np.isfinite(fine)
    bad = known & ((fine < 0) | (fine >= FINE_WRAP) | (fine != np.round(fine)))
    if not bad.any():
        return fine
    warnings.append(f"{path.name}: {int(bad.sum())} SampleTimeFine value(s) that are not a "
                    "32-bit tick count are ignored "
                    f"({unplaceable_lines(lines, np.flatnonzero(bad))})")
    return np.where(bad, np.nan, fine)


def _fine_packets(fine: np.ndarray, hz: float) -> np.ndarray:
    """Packets elapsed between consecutive rows by SampleTimeFine (signed; NaN when unknown)."""
    ticks = signed_step(np.diff(fine), FINE_WRAP)
    return ticks * hz / FINE_HZ if np.isfinite(hz) else np.full(len(ticks), np.nan)


def _outliers(counter: np.ndarray, fine: np.ndarray | None, wrap: int, hz: float) -> np.ndarray:
    """Rows whose counter is far from both neighbours while the neighbours agree."""
    out = np.zeros(len(counter), dtype=bool)
    if len(counter) < 3:
        return out
    before = signed_step(counter[1:-1] - counter[:-2], wrap)  # c[i] - c[i-1]
    across = signed_step(counter[2:] - counter[:-2], wrap)  # c[i+1] - c[i-1]
    far = (across >= 1) & (across <= _LOCAL) & ((before < -_LOCAL) | (before > across + _LOCAL))
    if fine is not None and far.any():
        packets = _fine_packets(fine, hz)[:-1]  # time from row i-1 to row i
        far &= ~(np.abs(packets - before) <= 0.5)  # the time agrees with the counter: misplaced
    out[1:-1] = far
    return out


def _steps(counter: np.ndarray, fine: np.ndarray | None, wrap: int, hz: float,
           lines: np.ndarray, path: Path, name: str,
           warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Signed steps between rows; SampleTimeFine decides the wraps where it agrees.

    Returns:
        (rows - 1,) steps in packets and (rows - 1,) True where SampleTimeFine confirms a step.
    """
    step = signed_step(np.diff(counter), wrap)
    confirmed = np.zeros(len(step), dtype=bool)
    if fine is None or wrap != COUNTER_WRAP:
        return step, confirmed
    expected = _fine_packets(fine, hz)
    known = np.isfinite(expected)
    if not known.any():
        return step, confirmed
    turns = np.zeros(len(step))
    turns[known] = np.round((expected[known] - step[known]) / COUNTER_WRAP)
    candidate = step + COUNTER_WRAP * turns.astype(np.int64)
    # Half a packet, and the sensor clock's drift against the sample clock (1e-4 is 100 ppm,
    # ten times a crystal's): a wider tolerance lets a corrupted tick count confirm a gap.
    tolerance = 0.5 + 1e-4 * np.abs(np.nan_to_num(expected))
    confirmed = known & (np.abs(expected - candidate) <= tolerance)
    step = np.where(confirmed, candidate, step)
    off = known & ~confirmed
    restart = off & (step < 0) & (expected >= 0)
    if restart.any():
        k = int(np.flatnonzero(restart)[0])
        raise InputError(f"{name} goes back from {counter[k]} to {counter[k + 1]} while "
                         "SampleTimeFine goes forward: the counter restarted or is corrupted, "
                         "so the rows cannot be placed in time", path=path,
                         line=int(lines[k + 1]), field=name)
    if off.any():
        warnings.append(f"{path.name}: SampleTimeFine and PacketCounter disagree on "
                        f"{int(off.sum())} step(s) (first at line "
                        f"{int(lines[1:][off][0])}); PacketCounter is used")
    return step, confirmed


def _repeats(first: np.ndarray, inverse: np.ndarray, rows: np.ndarray, table: np.ndarray | None,
             lines: np.ndarray, path: Path, name: str, warnings: list[str]) -> None:
    """Warn about rows repeating a counter; refuse a run of them that holds other data."""
    again = np.setdiff1d(np.arange(len(inverse)), first)  # positions in file order
    original = first[inverse.ravel()[again]]
    differs = np.ones(len(again), dtype=bool)
    if table is not None:
        a, b = table[rows[again]], table[rows[original]]
        differs = ~((a == b) | (np.isnan(a) & np.isnan(b))).all(axis=1)
    if differs.sum() > _LOCAL:
        run = np.flatnonzero(differs)
        step = np.diff(again[run])
        starts = np.flatnonzero(np.concatenate([[True], step != 1]))
        lengths = np.diff(np.concatenate([starts, [len(run)]]))
        longest = int(np.argmax(lengths))
        if lengths[longest] > _LOCAL:
            k = int(again[run[starts[longest]]])
            raise InputError(f"{name} repeats counters already read over {int(lengths[longest])} "
                             "rows in a row that hold other data: the counter restarted or is "
                             "corrupted, so the rows cannot be placed in time", path=path,
                             line=int(lines[rows[k]]), field=name)
    same = len(again) - int(differs.sum())
    detail = (f" ({same} repeat the same data, {int(differs.sum())} hold other data)"
              if table is not None and differs.any() else
              " (the same data again)" if table is not None else "")
    warnings.append(f"{path.name}: {len(again)} row(s) repeat a PacketCounter already read"
                    f"{detail}; the first row of each counter is kept")


def _check_span(unique: np.ndarray, steps: np.ndarray, confirmed: np.ndarray, rows: np.ndarray,
                lines: np.ndarray, counter: np.ndarray, path: Path, name: str) -> None:
    """Refuse a file whose counter spans far more samples than it holds rows."""
    span = int(unique[-1] - unique[0]) + 1
    confirmed_lost = int(np.sum(np.maximum(steps[confirmed] - 1, 0)))
    limit = 2 * len(unique) + COUNTER_WRAP + confirmed_lost
    if span <= limit:
        return
    jumps = np.where(confirmed, 0, np.abs(steps))
    k = int(np.argmax(jumps))
    raise InputError(f"{name} jumps from {counter[k]} to {counter[k + 1]} ({int(steps[k]):+d} "
                     f"packets); with its other jumps the file would span {span} samples for "
                     f"{len(unique)} rows, more lost packets than a 16-bit counter can tell "
                     "(without SampleTimeFine to confirm them): the counter is corrupted or the "
                     "rows come from different recordings", path=path,
                     line=int(lines[rows[k + 1]]), field=name)


def trial_span_limit(file_spans: list[int]) -> int:
    """Most samples a trial may span: its longest file plus one counter wrap either side."""
    return max(file_spans, default=0) + 2 * COUNTER_WRAP
