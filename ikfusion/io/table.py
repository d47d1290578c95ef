"""Delimited numeric tables (MT Manager exports, CSV): text lines to a float array, fast.

The rows are checked for their field count line by line (a truncated line is an error naming
the line and the first missing column), then the whole block is converted by NumPy's C parser
in one call. Empty fields and the spellings ``NaN``, ``nan``, ``-nan(ind)``, ``1.#QNAN`` become
NaN; a field that is not a number is reported with its line and column. Space-delimited tables
use exactly one space between fields, so a run of k + 1 spaces holds k empty fields; a line
whose fields are instead padded with several spaces and that has no empty field is accepted
too. With a semicolon, tab or space delimiter a decimal comma (``9,81``) is read as a decimal
point.
"""

from __future__ import annotations

import io
import re
from collections.abc import Sequence
from itertools import repeat
from pathlib import Path

import numpy as np

from ..errors import InputError
from .parse_kernel import kernel_table

#: Candidate delimiters, in the order they are looked for in a header line.
DELIMITERS: tuple[str, ...] = ("\t", ";", ",", " ")
_ODD_NAN = re.compile(r"[-+]?(?:nan\([a-z0-9_]*\)|1\.#(?:qnan|snan|ind|inf)0*)", re.IGNORECASE)


def detect_delimiter(header: str) -> str:
    """The delimiter of a header line: tab, semicolon, comma, else space."""
    for d in DELIMITERS[:-1]:
        if d in header:
            return d
    return " "


def split_header(header: str, delimiter: str) -> list[str]:
    """Column names of a header line (trailing empty names dropped, unnamed ones numbered)."""
    text = header.strip("\r\n")
    names = text.split() if delimiter == " " else [c.strip() for c in text.split(delimiter)]
    while names and names[-1] == "":
        names.pop()
    return [n or f"(unnamed column {k + 1})" for k, n in enumerate(names)]


def short_quote(text: str, limit: int = 20) -> str:
    """A field quoted for a message when short, else only its length (no file content echoed)."""
    text = text.strip()
    if len(text) <= limit and text.isprintable():
        return repr(text)
    return f"a field of {len(text)} characters"


def delimiter_name(delimiter: str) -> str:
    """A readable name for a delimiter (for messages)."""
    return {"\t": "tab", ",": "comma", ";": "semicolon", " ": "space"}.get(delimiter,
                                                                         repr(delimiter))


def _normalize_fields(text: str, delimiter: str) -> str:
    """Drop padding blanks, read decimal commas as points and odd NaN spellings as ``nan``."""
    if delimiter != " ":
        if " " in text:
            text = text.replace(" ", "")
        if delimiter != "\t" and "\t" in text:
            text = text.replace("\t", "")
    if delimiter != "," and "," in text:
        text = text.replace(",", ".")
    if "(" in text or "#" in text:
        text = _ODD_NAN.sub("nan", text)
    return text


def _fill_empty(body: str, delimiter: str) -> str:
    """Write ``nan`` into every empty field of a block of lines joined by newlines."""
    d = delimiter
    pair = d + d
    filled = d + "nan" + d
    for _ in range(2):  # the first pass fills every other field of a run, the second the rest
        if pair in body:
            body = body.replace(pair, filled)
    if "\n" + d in body:
        body = body.replace("\n" + d, "\nnan" + d)
    if d + "\n" in body:
        body = body.replace(d + "\n", d + "nan\n")
    if body.startswith(d):
        body = "nan" + body
    if body.endswith(d):
        body = body + "nan"
    return body


def fit_fields(lines: list[str], numbers: Sequence[int], delimiter: str, columns: Sequence[str],
               path: Path) -> list[str]:
    """Check that every line has one field per column; return the lines ready to parse.

    A trailing delimiter after the last column is dropped. In a space-delimited table, a line
    whose fields are separated by several spaces is re-joined with one space when it then has
    exactly one field per column.

    Raises:
        InputError: A line with fewer fields (truncated) or more fields than the header, naming
            the line and the column.
    """
    d = delimiter
    width = len(columns)
    if d == " ":
        lines = [ln.lstrip(" ") for ln in lines]
    counts = np.fromiter(map(str.count, lines, repeat(d)), dtype=np.int64, count=len(lines))
    bad = np.flatnonzero(counts != width - 1)
    for i in (int(k) for k in bad):
        line = lines[i]
        if counts[i] == width and line.endswith(d):
            lines[i] = line[:-1]
            continue
        if d == " " and len(line.split()) == width:
            lines[i] = " ".join(line.split())
            continue
        found = int(counts[i]) + 1
        hint = (" (in a space-delimited file one space separates fields, so a run of k + 1 "
                "spaces holds k empty fields)" if d == " " else "")
        if found < width:
            raise InputError(f"truncated line: {found} fields where the header has {width} "
                             f"({delimiter_name(d)}-delimited); the line ends before column "
                             f"{columns[found]!r}{hint}", path=path, line=int(numbers[i]),
                             field=columns[found])
        raise InputError(f"{found} fields where the header has {width} "
                         f"({delimiter_name(d)}-delimited){hint}", path=path, line=int(numbers[i]),
                         field=f"column {width + 1} (after {columns[-1]})")
    return lines


def parse_numeric(lines: list[str], numbers: Sequence[int], delimiter: str,
                  columns: Sequence[str], path: Path) -> np.ndarray:
    """Convert checked lines (see :func:`fit_fields`) into a float array.

    Args:
        lines: Data lines with exactly ``len(columns)`` fields each.
        numbers: 1-based line number of each line in the file (for messages).
        delimiter: The field delimiter.
        columns: Column names.
        path: The file (for messages).

    Returns:
        (len(lines), len(columns)) float array, NaN for empty and NaN fields.

    Raises:
        InputError: A field that is not a number, naming its line and column.
    """
    width = len(columns)
    if not lines:
        return np.zeros((0, width))
    body = _fill_empty(_normalize_fields("\n".join(lines), delimiter), delimiter)
    try:
        table = np.loadtxt(io.StringIO(body), delimiter=delimiter, comments=None, ndmin=2,
                           dtype=float, quotechar=None)
    except ValueError as err:
        _raise_first_bad_field(lines, numbers, delimiter, columns, path, err)
        raise  # pragma: no cover - _raise_first_bad_field always raises
    if table.shape != (len(lines), width):  # pragma: no cover - fit_fields guarantees it
        raise InputError(f"expected {len(lines)} x {width} values, parsed {table.shape}",
                         path=path)
    return table


def parse_block(body: str, delimiter: str, width: int) -> np.ndarray | None:
    """Fast path: a block of clean data lines (no comments, no blank lines) in one call.

    Args:
        body: The data lines joined by newlines (no trailing newline).
        delimiter: The field delimiter.
        width: Columns of the header.

    Returns:
        (rows, width) floats, or None when anything is off (a line with another field count,
        a field that is not a number, padding): the caller then parses line by line, which
        finds and names the culprit.
    """
    if not body:
        return np.zeros((0, width))
    text = _normalize_fields(body, delimiter)
    table = kernel_table(text, delimiter, width)
    if table is not None:  # the C kernel: the numbers and NaNs of the path below
        return table
    raw = np.frombuffer(text.encode(), np.uint8)
    lines = int(np.count_nonzero(raw == ord("\n"))) + 1  # (str.count is several times slower)
    empty = _empty_columns(raw, delimiter, width, lines)
    if empty is not None:
        return _parse_filled_columns(text, delimiter, empty, lines)
    text = _fill_empty(text, delimiter)
    try:
        table = np.loadtxt(io.StringIO(text), delimiter=delimiter, comments=None, ndmin=2,
                           dtype=float, quotechar=None)
    except ValueError:
        return None
    if table.shape != (lines, width):
        return None
    return table


def _empty_columns(raw: np.ndarray, delimiter: str, width: int,
                   lines: int) -> np.ndarray | None:
    """The columns (width,) empty in every line of a block whose other fields are all filled.

    None when the block is not so (a line with another field count, an empty field in a
    column that is filled elsewhere, no column empty throughout, a space delimiter): the
    caller then writes ``nan`` into the empty fields. Found from the delimiter positions in
    a few array operations; MT Manager exports hold many such columns (UTC, Year, ...).
    ``raw`` is the block's text as bytes, ``lines`` its line count.
    """
    if delimiter == " " or len(delimiter) != 1:
        return None
    ends = np.flatnonzero((raw == ord(delimiter)) | (raw == ord("\n")))
    if len(ends) + 1 != lines * width or not (raw[ends[width - 1::width]] == ord("\n")).all():
        return None
    empty = (np.diff(ends, prepend=-1, append=len(raw)) == 1).reshape(lines, width)
    throughout = empty.all(axis=0)
    if not throughout.any() or empty[:, ~throughout].any():
        return None
    return throughout


def repeated_byte(raw: np.ndarray, byte: int) -> bool:
    """Whether ``byte`` occurs twice in a row in ``raw`` (bytes as uint8).

    ``"//" in text`` on a 300 kB export takes about half a millisecond (str's search for two
    characters); this a tenth of that.
    """
    hit = raw == byte
    return bool((hit[1:] & hit[:-1]).any())


def _parse_filled_columns(text: str, delimiter: str, empty: np.ndarray,
                          lines: int) -> np.ndarray | None:
    """:func:`parse_block` of ``lines`` lines whose ``empty`` columns are all empty (NaN)."""
    filled = np.flatnonzero(~empty).tolist()
    try:
        values = np.loadtxt(io.StringIO(text), delimiter=delimiter, comments=None, ndmin=2,
                            dtype=float, quotechar=None, usecols=filled)
    except ValueError:
        return None
    if values.shape != (lines, len(filled)):
        return None
    table = np.full((lines, len(empty)), np.nan)
    table[:, filled] = values
    return table


def _raise_first_bad_field(lines: list[str], numbers: Sequence[int], delimiter: str,
                           columns: Sequence[str], path: Path, err: Exception) -> None:
    for line, number in zip(lines, numbers):
        for name, raw in zip(columns, line.split(delimiter)):
            text = _normalize_fields(raw, delimiter)
            if text == "":
                continue
            try:
                float(text)
            except ValueError:
                raise InputError(f"not a number: {short_quote(raw)} (a number, NaN or an empty "
                                 "field was expected)", path=path, line=int(number),
                                 field=name) from None
    raise InputError(f"could not read the numbers: {err}", path=path)
