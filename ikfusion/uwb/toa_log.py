"""UWB time-of-arrival logs (SPEC section 4): reading, writing, grouping into transmissions.

A TOA CSV has a header line naming at least the columns ``time,tag,seq,reader,toa`` (any order;
extra columns are ignored):

- ``time``: reception time on the common timeline [s];
- ``tag``: tag id; ``seq``: transmission number of that tag (an integer);
- ``reader``: reader id;
- ``toa``: c times the arrival time on the reader clock [m], i.e.
  ``toa = tau + ||p_world_reader - p_world_tag|| + clock_offset + nlos + noise``.

Blank lines and lines starting with ``#`` are skipped. A blank or ``NaN`` toa is a missed
reception: the row is skipped and counted. Any other malformed value raises
:class:`~ikfusion.errors.InputError` naming the file, the line and the field.

Rows are grouped into transmissions by ``(tag, seq)``. Because tags count ``seq`` with a small
wrapping counter, rows of one ``(tag, seq)`` whose reception times lie more than ``max_span``
apart belong to different transmissions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..atomic import atomic_write_text
from ..errors import InputError

#: Columns every TOA CSV must have, in the order the writer uses.
TOA_COLUMNS = ("time", "tag", "seq", "reader", "toa")


@dataclass(frozen=True)
class ToaLog:
    """Receptions, one per row, in file order.

    Attributes:
        time: Reception time on the common timeline, shape (N,) [s].
        tag: Tag id per row, shape (N,) (str).
        seq: Transmission number per row, shape (N,) (int64).
        reader: Reader id per row, shape (N,) (str).
        toa: Time of arrival in metres of light travel, shape (N,) [m] (finite).
        line: 1-based line number in the source file per row, shape (N,) (zeros if built in
            memory).
        source: File the log was read from, if any.
        missed: Number of rows with a blank/NaN toa that were skipped.
    """

    time: np.ndarray
    tag: np.ndarray
    seq: np.ndarray
    reader: np.ndarray
    toa: np.ndarray
    line: np.ndarray
    source: Path | None = None
    missed: int = 0

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass(frozen=True)
class Transmissions:
    """Receptions grouped per transmission, as a matrix over the constellation's readers.

    Attributes:
        time: Earliest reception time of each transmission, shape (T,) [s].
        tag: Tag id, shape (T,) (str).
        seq: Transmission number, shape (T,) (int64).
        toa: Times of arrival, shape (T, M) [m]; NaN where reader m did not hear it.
        reader_ids: The M reader ids indexing the columns of ``toa``.
    """

    time: np.ndarray
    tag: np.ndarray
    seq: np.ndarray
    toa: np.ndarray
    reader_ids: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.time.shape[0])


def read_toa_csv(path: str | Path) -> ToaLog:
    """Read a TOA CSV file (see the module docstring).

    Raises:
        InputError: For a missing column or a malformed line, naming file, line and field.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as err:
        raise InputError(f"cannot read TOA log: {err.strerror}", path=path) from err
    except UnicodeDecodeError as err:
        raise InputError("not a text file (UTF-8 expected)", path=path) from err
    lines = text.splitlines()
    header_at = _first_content_line(lines)
    if header_at is None:
        raise InputError(f"empty file; expected a header {','.join(TOA_COLUMNS)}", path=path)
    header = [h.strip() for h in lines[header_at].split(",")]
    for name in TOA_COLUMNS:
        if name not in header:
            raise InputError(
                f"missing column; the header must name {','.join(TOA_COLUMNS)}, found "
                f"{','.join(header)}",
                path=path,
                line=header_at + 1,
                field=name,
            )
    col = {name: header.index(name) for name in TOA_COLUMNS}
    width = len(header)
    first = header_at + 1
    keep = [
        i
        for i, raw in enumerate(lines[first:], start=first)
        if raw and raw.lstrip()[:1] not in ("", "#")
    ]
    line_no = np.array(keep, dtype=np.int64) + 1
    if not keep:
        empty = np.zeros(0)
        return ToaLog(
            empty,
            np.zeros(0, dtype=object),
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=object),
            empty,
            line_no,
            source=path,
        )
    columns = _split_columns(lines, keep, width, path)
    toa = _floats(columns[col["toa"]], "toa", line_no, path, blank_is_nan=True)
    time = _floats(columns[col["time"]], "time", line_no, path, blank_is_nan=False)
    seq = _ints(columns[col["seq"]], "seq", line_no, path)
    tag = _names(columns[col["tag"]], "tag", line_no, path)
    reader = _names(columns[col["reader"]], "reader", line_no, path)
    heard = np.isfinite(toa)
    return ToaLog(
        time=time[heard],
        tag=tag[heard],
        seq=seq[heard],
        reader=reader[heard],
        toa=toa[heard],
        line=line_no[heard],
        source=path,
        missed=int(np.count_nonzero(~heard)),
    )


def write_toa_csv(path: str | Path, log: ToaLog) -> Path:
    """Write a TOA log as CSV with columns ``time,tag,seq,reader,toa`` (atomically).

    Times are written with 1 us resolution, times of arrival with 10 um.

    Returns:
        The path written.
    """
    out = [",".join(TOA_COLUMNS)]
    out.extend(
        f"{t:.6f},{g},{s},{r},{z:.5f}"
        for t, g, s, r, z in zip(
            log.time.tolist(),
            log.tag.tolist(),
            log.seq.tolist(),
            log.reader.tolist(),
            log.toa.tolist(),
        )
    )
    return atomic_write_text(Path(path), "\n".join(out) + "\n")


def toa_log_from_matrix(
    time: npt.ArrayLike,
    tag: npt.ArrayLike,
    seq: npt.ArrayLike,
    toa: npt.ArrayLike,
    reader_ids: Sequence[str],
) -> ToaLog:
    """Flatten per-transmission TOA rows into a log (NaN entries are not written).

    Args:
        time: Transmission (or reception) times, shape (T,) [s].
        tag: Tag id per transmission, shape (T,).
        seq: Transmission number per transmission, shape (T,).
        toa: Times of arrival, shape (T, M) [m], NaN for no reception.
        reader_ids: The M reader ids.
    """
    z = np.asarray(toa, dtype=float)
    t = np.asarray(time, dtype=float)
    if z.ndim != 2 or z.shape != (t.shape[0], len(reader_ids)):
        raise ValueError(f"toa must have shape (T, M) = ({t.shape[0]}, {len(reader_ids)})")
    rows, cols = np.nonzero(np.isfinite(z))
    tags = np.asarray(tag).astype(str).astype(object)
    return ToaLog(
        time=t[rows],
        tag=tags[rows],
        seq=np.asarray(seq, dtype=np.int64)[rows],
        reader=np.asarray(reader_ids, dtype=object)[cols],
        toa=z[rows, cols],
        line=np.zeros(rows.shape[0], dtype=np.int64),
    )


def group_transmissions(
    log: ToaLog, reader_ids: Sequence[str], *, max_span: float = 0.5
) -> Transmissions:
    """Group receptions by ``(tag, seq)`` into a (T, M) matrix over ``reader_ids``.

    Args:
        log: The receptions.
        reader_ids: Reader ids of the constellation; they index the matrix columns.
        max_span: Rows of one ``(tag, seq)`` more than this apart in ``time`` are different
            transmissions (a wrapped sequence counter) [s].

    Raises:
        InputError: For a reader id the constellation does not have, or a reader reporting one
            transmission twice (naming the line).
    """
    ids = list(reader_ids)
    m = len(ids)
    n = len(log)
    if n == 0:
        return Transmissions(
            np.zeros(0),
            np.zeros(0, dtype=object),
            np.zeros(0, dtype=np.int64),
            np.zeros((0, m)),
            tuple(ids),
        )
    id_index = {rid: j for j, rid in enumerate(ids)}
    known, reader_col = np.unique(log.reader.astype(str), return_inverse=True)
    known_to_col = np.empty(known.shape[0], dtype=np.int64)
    for k, rid in enumerate(known.tolist()):
        if rid not in id_index:
            row = int(np.flatnonzero(reader_col == k)[0])
            raise InputError(
                f"reader {rid!r} is not in the constellation ({', '.join(ids)})",
                path=log.source,
                line=int(log.line[row]) or None,
                field="reader",
            )
        known_to_col[k] = id_index[rid]
    col = known_to_col[reader_col]
    tag_names, tag_code = np.unique(log.tag.astype(str), return_inverse=True)
    order = np.lexsort((log.time, log.seq, tag_code))
    tc, sq, tm = tag_code[order], log.seq[order], log.time[order]
    new = np.ones(n, dtype=bool)
    new[1:] = (tc[1:] != tc[:-1]) | (sq[1:] != sq[:-1]) | (np.diff(tm) > max_span)
    group_sorted = np.cumsum(new) - 1
    group = np.empty(n, dtype=np.int64)
    group[order] = group_sorted
    n_groups = int(group_sorted[-1]) + 1
    cell = group * m + col
    uniq, first, counts = np.unique(cell, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup_cell = uniq[np.argmax(counts > 1)]
        rows = np.flatnonzero(cell == dup_cell)
        raise InputError(
            f"reader {ids[int(col[rows[0]])]!r} reports tag {log.tag[rows[0]]!r} seq "
            f"{int(log.seq[rows[0]])} twice (first on line {int(log.line[rows[0]])})",
            path=log.source,
            line=int(log.line[rows[1]]) or None,
            field="reader",
        )
    toa = np.full((n_groups, m), np.nan)
    toa[group, col] = log.toa
    time = np.full(n_groups, np.inf)
    np.minimum.at(time, group, log.time)
    starts = order[new]
    tags = tag_names[tag_code[starts]].astype(object)
    seqs = log.seq[starts]
    # Transmissions in time order (ties by tag then seq), the natural order of a fix log.
    by_time = np.lexsort((seqs, tag_code[starts], time))
    return Transmissions(
        time=time[by_time],
        tag=tags[by_time],
        seq=seqs[by_time],
        toa=toa[by_time],
        reader_ids=tuple(ids),
    )


def _split_columns(
    lines: Sequence[str], keep: Sequence[int], width: int, path: Path
) -> list[list[str]]:
    """Fields of the kept lines, column by column (one flat split, no list per line).

    Raises:
        InputError: Naming the first line whose field count differs from the header's.
    """
    commas = np.fromiter((lines[i].count(",") for i in keep), dtype=np.int64, count=len(keep))
    wrong = np.flatnonzero(commas != width - 1)
    if wrong.size:
        first = int(wrong[0])
        raise InputError(
            f"expected {width} comma-separated fields, found {int(commas[first]) + 1}",
            path=path,
            line=keep[first] + 1,
        )
    flat = ",".join(lines[i] for i in keep).split(",")
    return [flat[j::width] for j in range(width)]


def _first_content_line(lines: Sequence[str]) -> int | None:
    for i, raw in enumerate(lines):
        s = raw.strip()
        if s and not s.startswith("#"):
            return i
    return None


def _floats(
    values: Sequence[str], name: str, line_no: np.ndarray, path: Path, *, blank_is_nan: bool
) -> np.ndarray:
    """Parse a column of numbers: a vectorised pass, then a line-by-line one to name a fault."""
    if blank_is_nan:
        values = [v if v.strip() else "nan" for v in values]
    try:
        out = np.array(values, dtype=float)
    except ValueError:
        out = None
    if out is not None:
        bad = np.isinf(out) if blank_is_nan else ~np.isfinite(out)
        if not np.any(bad):
            return out
    slow = np.empty(len(values))
    for i, raw in enumerate(values):
        s = raw.strip()
        if not s:
            raise InputError("empty field; expected a number", path, int(line_no[i]), name)
        try:
            v = float(s)
        except ValueError:
            raise InputError(
                f"expected a number, found {s!r}", path, int(line_no[i]), name
            ) from None
        if math.isinf(v) or (math.isnan(v) and not blank_is_nan):
            raise InputError(f"expected a finite number, found {s!r}", path, int(line_no[i]), name)
        slow[i] = v
    return slow


def _ints(values: Sequence[str], name: str, line_no: np.ndarray, path: Path) -> np.ndarray:
    """Parse a column of integers (vectorised, with a line-by-line pass to name a fault)."""
    try:
        return np.array(values, dtype=np.int64)
    except (ValueError, OverflowError):
        pass
    slow = np.empty(len(values), dtype=np.int64)
    for i, raw in enumerate(values):
        s = raw.strip()
        try:
            slow[i] = int(s)
        except (ValueError, OverflowError):
            raise InputError(
                f"expected an integer, found {s!r}", path, int(line_no[i]), name
            ) from None
    return slow


def _names(values: Sequence[str], name: str, line_no: np.ndarray, path: Path) -> np.ndarray:
    out = np.empty(len(values), dtype=object)
    out[:] = [v.strip() for v in values]
    empty = np.flatnonzero(out == "")
    if empty.size:
        raise InputError("empty field; expected an id", path, int(line_no[empty[0]]), name)
    return out
