"""Number tables as text, fast: whole blocks of rows formatted at once.

Formatting values one by one in Python (``",".join(f"{v:.6f}" for v in row)``) costs about a
microsecond per value; the result files hold over a million. Here a row's format string
(``"%.6f,%.6f"`` and a newline) applies to a block of rows at once: through NumPy
(:func:`ikfusion.number_text.format_rows`) when every field is the same ``%.<d>f``, else
through one ``%`` operation per block. Both write the same text as formatting each value
(``"%.6f" % v`` and ``f"{v:.6f}"`` agree for every float, ``nan``, ``inf`` and ``-0.0``
included). The files are written in binary mode, the text as UTF-8 bytes with newline line
ends (what text mode writes on POSIX), without decoding the digits and encoding them again.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np

from ..number_text import format_rows_bytes

#: Rows formatted per ``%`` operation (bounds the size of the temporary strings).
BLOCK_ROWS = 2048


def literal(text: str) -> str:
    """``text`` escaped for use inside a ``%`` format string."""
    return text.replace("%", "%%")


def write_rows(out: BinaryIO, row_format: str, table: np.ndarray) -> None:
    """Write every row of ``table`` (N, k) through ``row_format`` (k ``%`` fields, newline).

    Args:
        out: A file open for writing bytes (the text in UTF-8).
        row_format: The format of one row, e.g. ``"%.6f,%.6f"`` and a newline.
        table: The values, one row per line.
    """
    rows = np.asarray(table, dtype=float)
    if rows.size == 0:
        return
    rows = rows.reshape(len(rows), -1)
    for start in range(0, len(rows), BLOCK_ROWS):
        out.write(format_rows_bytes(row_format, rows[start:start + BLOCK_ROWS]))


def long_rows(out: BinaryIO, time: np.ndarray, names: Sequence[str], values: np.ndarray,
              number: str = "%.6f") -> None:
    """Write ``time,name,v0,v1,...`` for every time and name (time-major, names in order).

    Args:
        out: A file open for writing bytes (the text in UTF-8).
        time: (N,) [s].
        names: The names of the second column.
        values: (N, len(names), k) values of each name at each time.
        number: Format of every number.
    """
    n, m, k = values.shape
    frame_format = "".join(f"{number},{literal(name)}," + ",".join([number] * k) + "\n"
                           for name in names)
    stamped = np.concatenate(
        [np.broadcast_to(np.asarray(time, dtype=float)[:, None, None], (n, m, 1)), values],
        axis=2)
    write_rows(out, frame_format, stamped.reshape(n, m * (k + 1)))


def write_csv(path: str | Path, header: Sequence[str], formats: Sequence[str],
              table: np.ndarray) -> None:
    """A CSV file: the ``header`` line, then each row of ``table`` with a format per column.

    Args:
        path: The file.
        header: Column names.
        formats: One ``%`` format per column (``"%.6f"``, ``"%d"``, ...).
        table: (N, len(formats)) values.
    """
    with Path(path).open("wb") as out:
        out.write((",".join(header) + "\n").encode())
        write_rows(out, ",".join(formats) + "\n", table)
