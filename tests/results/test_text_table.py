"""Block formatting of number tables: the same text as formatting each value on its own."""

from __future__ import annotations

import io

import numpy as np

from ikfusion.results.text_table import BLOCK_ROWS, long_rows, write_csv, write_rows

#: Values whose text is easy to get wrong: signed zeros, rounding edges, non-finite, extremes.
AWKWARD = [0.0, -0.0, -1e-9, 1e-9, 0.5e-6, -0.5e-6, 2.5e-6, 1.0000005, -123456.7890125,
           1e300, -1e-300, np.nan, np.inf, -np.inf, 0.1 + 0.2]


def reference_rows(table: np.ndarray) -> str:
    """One value at a time, as the result files were written before."""
    return "".join(",".join(f"{v:.6f}" for v in row) + "\n" for row in table)


def test_write_rows_matches_value_by_value_text(rng) -> None:
    table = np.concatenate([np.array(AWKWARD * 3).reshape(-1, 5),
                            rng.normal(scale=10.0 ** rng.integers(-8, 8, (40, 1)), size=(40, 5))])
    out = io.BytesIO()
    write_rows(out, ",".join(["%.6f"] * 5) + "\n", table)
    assert out.getvalue().decode() == reference_rows(table)


def test_write_rows_across_blocks_and_empty() -> None:
    table = np.arange(3 * (BLOCK_ROWS + 7), dtype=float).reshape(-1, 3) / 7.0
    out = io.BytesIO()
    write_rows(out, "%.6f,%.6f,%.6f\n", table)
    assert out.getvalue().decode() == reference_rows(table)
    empty = io.BytesIO()
    write_rows(empty, "%.6f\n", np.empty((0, 1)))
    assert empty.getvalue() == b""


def test_long_rows_time_major_with_names(rng) -> None:
    time = np.array([0.0, 0.01, 0.02])
    names = ["Pelvis", "odd%name"]
    values = rng.normal(size=(3, 2, 3))
    values[1, 1, 2] = -0.0
    out = io.BytesIO()
    long_rows(out, time, names, values)
    expected = "".join(f"{t:.6f},{name}," + ",".join(f"{v:.6f}" for v in values[k, i]) + "\n"
                       for k, t in enumerate(time) for i, name in enumerate(names))
    assert out.getvalue() == expected.encode()


def test_write_csv_writes_what_savetxt_wrote(rng, tmp_path) -> None:
    table = np.column_stack([np.arange(30) / 100.0, rng.normal(size=30) * 1e3,
                             rng.integers(0, 2, 30), rng.integers(0, 9, 30)]).astype(float)
    table[3, 1] = -0.0
    formats = ["%.6f", "%.4f", "%d", "%d"]
    names = ["time", "solve_time_ms", "contact", "steps"]
    np.savetxt(tmp_path / "before.csv", table, delimiter=",", fmt=formats,
               header=",".join(names), comments="")
    write_csv(tmp_path / "now.csv", names, formats, table)
    assert (tmp_path / "now.csv").read_bytes() == (tmp_path / "before.csv").read_bytes()
