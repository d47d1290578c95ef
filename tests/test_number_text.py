"""Fixed-decimal text built by NumPy: the same bytes as Python's ``%`` for every value.

Every test runs twice: with the digits written by the C kernel (``number_text.c``) and by
NumPy (the path without a compiler).
"""

from __future__ import annotations

import numpy as np
import pytest

import ikfusion.number_text
from ikfusion.number_kernel import kernel_text
from ikfusion.number_text import BLOCK_VALUES, fixed_row_parts, format_rows, format_rows_bytes

#: Values whose text is easy to get wrong: signed zeros, exact and near halves, non-finite,
#: integers too large for the fast path, the largest and smallest floats.
AWKWARD = [0.0, -0.0, -1e-9, 1e-9, 0.5e-6, -0.5e-6, 2.5e-6, 1.0000005, 0.0078125, -0.0234375,
           0.125, 2.5, -3.5, 1e15, 4503599627370495.5, 9007199254740993.0, 1e300, -1e-300,
           np.nan, np.inf, -np.inf, 0.1 + 0.2, 99.9999995, 999999.9999999, 1.7976931348623157e308,
           5e-324]


@pytest.fixture(autouse=True, params=["kernel", "numpy"])
def digits_by(request, monkeypatch) -> str:
    """Which path writes the digits: the C kernel (skipped without one) or NumPy."""
    if request.param == "numpy":
        monkeypatch.setattr(ikfusion.number_text, "kernel_text", lambda *args: None)
    else:
        layout = fixed_row_parts("%.1f")
        assert layout is not None
        if kernel_text(ikfusion.number_text._Layout(*layout).literals, 1, np.ones((1, 1)),
                       np.ones((1, 1))) is None:
            pytest.skip("no C kernel (no compiler or IKFUSION_NO_COMPILE): NumPy writes")
    return str(request.param)


def percent(row_format: str, table: np.ndarray) -> str:
    """The reference: one ``%`` operation per row."""
    return "".join(row_format % tuple(row) for row in np.asarray(table).tolist())


@pytest.mark.parametrize("decimals", range(10))
def test_every_magnitude_and_awkward_value_as_percent_writes_it(decimals: int, rng) -> None:
    row_format = ",".join([f"%.{decimals}f"] * 6) + "\n"
    scales = 10.0 ** rng.integers(-10, 13, (400, 1))
    table = np.concatenate([rng.normal(size=(400, 6)) * scales,
                            np.resize(np.array(AWKWARD), (9, 6)),
                            (rng.integers(-10**6, 10**6, (200, 6)) + 0.5) / 10**decimals,
                            rng.integers(-10**6, 10**6, (200, 6)) / 2.0 ** rng.integers(0, 30,
                                                                                        (200, 6))])
    rng.shuffle(table)
    assert format_rows(row_format, table) == percent(row_format, table)


@pytest.mark.parametrize("digits", range(7, 12))
def test_blocks_of_nine_to_eleven_digits_as_percent_writes_them(digits: int, rng) -> None:
    # a block's largest value sets its digit count (decimals included): 9 and 10 digits take
    # their leading ones by division, 11 and more by a second pass of eight
    row_format = " ".join(["%.6f"] * 5) + "\n"
    top = 10.0 ** (digits - 6)
    table = rng.uniform(-top, top, (300, 5))
    table[::7] = rng.normal(size=(43, 5))
    table[0, 0] = np.nextafter(top, 0.0)
    table[1, :4] = [-0.0, 0.5e-6, -(top - 0.5e-6), top / 10.0]
    assert format_rows(row_format, table) == percent(row_format, table)


def test_names_percent_signs_and_blocks(rng) -> None:
    """Literals of several lengths (a long table's names, ``%%``), over many blocks."""
    row_format = "%.6f,Pelvis,%.6f,%.6f\n%.6f,odd%%name,%.6f,%.6f\n%.6f\t%.6f x\n"
    table = rng.normal(size=(2 * BLOCK_VALUES // 8 + 3, 8)) * 50.0
    table[5, 2] = np.nan  # a row written by `%` in the middle of a block
    assert format_rows(row_format, table) == percent(row_format, table)


@pytest.mark.parametrize("row_format", ["%.3f\n", "%.3f%.3f\n", "a%.3f,%.3f,%.3f;b%.3f\n",
                                        "%.3f,name,%.3f,%.3f,%.3f\n%.3f,n,%.3f,%.3f,%.3f\n"])
def test_runs_of_evenly_spaced_fields(row_format: str, rng) -> None:
    """One field, adjacent fields, and runs of evenly spaced fields broken by longer literals."""
    k = row_format.count("%")
    table = rng.normal(size=(300, k)) * 10.0 ** rng.integers(-2, 5, (300, k))
    assert format_rows(row_format, table) == percent(row_format, table)


def test_other_formats_are_written_by_percent(rng) -> None:
    table = np.column_stack([np.arange(20) / 100.0, rng.normal(size=20),
                             rng.integers(0, 9, 20)]).astype(float)
    for row_format in ("%.6f,%.4f,%d\n", "%.6f,%.6f,%g\n", "%.6f,%.6f,%.12f\n"):
        assert fixed_row_parts(row_format) is None
        assert format_rows(row_format, table) == percent(row_format, table)
    assert format_rows("%.6f\n", np.empty((0, 1))) == ""


def test_parts_of_a_format() -> None:
    assert fixed_row_parts("%.3f,a%%b,%.3f\n") == (["", ",a%b,", "\n"], 3)
    assert fixed_row_parts("no fields\n") is None
    with pytest.raises(TypeError):
        format_rows("%.6f,%.6f\n", np.zeros((2, 3)))


def test_mixed_decimal_and_integer_fields_as_percent_writes_them(rng) -> None:
    # contacts.csv and solve_time.csv: "%.6f" then "%d" fields (and "%.4f"); a "%d" field
    # truncates a float and writes -0.0 as "0": such rows (and halves, huge values) go to %
    row_format = "%.6f,%d,%.4f,%d,%d\n"
    table = np.column_stack([rng.normal(0, 50, 3000), rng.integers(-5, 5, 3000),
                             rng.normal(0, 1, 3000) * 10.0 ** rng.integers(-6, 8, 3000),
                             rng.integers(0, 2, 3000), rng.integers(-10**12, 10**12, 3000)])
    table = table.astype(float)
    table[:20, 1] = [-0.0, 0.0, 1.5, -1.5, 2.999, -2.5, 1e17, -1e17, 4503599627370497.0, 0.5,
                     1e-300, -1e-300, 7, -7, 0.9999999, 2 ** 52, -(2 ** 52), 3, 1e15, 0.0]
    table[20:29, 2] = AWKWARD[:9]
    assert format_rows(row_format, table) == percent(row_format, table)
    assert format_rows("t=%d;%.3f%%\n", table[:, :2]) == percent("t=%d;%.3f%%\n", table[:, :2])


@pytest.mark.parametrize("row_format", ["%.6f,Pelvis,%.6f\n%.6f,h\u00e9,%.6f\n", "%.4f,%d\n",
                                        "%.6f,%g\n"])
def test_bytes_are_the_text_encoded(row_format: str, rng) -> None:
    """The fast path, the mixed fields, ``%`` alone; a non-ASCII literal; rows by ``%``."""
    k = row_format.count("%")
    table = rng.normal(size=(3000, k)) * 10.0 ** rng.integers(-3, 6, (3000, 1))
    table[:, 1::2] = np.round(table[:, 1::2])
    table[7, :2] = [0.5e-6, -0.0]
    expected = percent(row_format, table).encode()
    assert format_rows_bytes(row_format, table) == expected
    assert format_rows_bytes(row_format, table[:0]) == b""


def test_mixed_fields_with_nan_in_an_integer_field_fail_as_percent() -> None:
    with pytest.raises(ValueError, match="NaN"):
        format_rows("%.6f,%d\n", np.array([[1.0, 2.0], [0.5, np.nan]]))
