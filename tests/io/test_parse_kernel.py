"""The C table reader (number_parse.c) against NumPy's loadtxt: the same doubles, to the bit."""

from __future__ import annotations

import io

import numpy as np
import pytest

from ikfusion.io.parse_kernel import kernel_table


def _loadtxt(text: str, delimiter: str) -> np.ndarray:
    return np.loadtxt(io.StringIO(text), delimiter=delimiter, comments=None, ndmin=2,
                      dtype=float, quotechar=None)


@pytest.fixture
def kernel() -> None:
    if kernel_table("1", ",", np.ones(1, bool), 1) is None:
        pytest.skip("no C kernel (no compiler or IKFUSION_NO_COMPILE): loadtxt reads")


def test_plain_fields_read_as_loadtxt_to_the_bit(kernel: None) -> None:
    rng = np.random.default_rng(3)
    values = np.concatenate([rng.normal(0, 10, 3000), rng.uniform(-1, 1, 3000) * 1e-6,
                             rng.integers(-10**12, 10**12, 3000).astype(float)])
    decimals = np.r_[rng.integers(0, 12, 6000), rng.integers(0, 4, 3000)]
    fields = [f"{v:.{d}f}" for v, d in zip(values, decimals)]
    fields += [f"{v:.{d}f}" for v, d in zip(rng.uniform(-1e-7, 1e-7, 3000),
                                            rng.integers(16, 23, 3000))]  # 10**22 at most
    fields += ["-0.000000", "+1.5", "1.", ".5", "00472", "9007199254740992",
               "0.123456789012345", "12345678.9012345"]
    fields += ["0"] * (-len(fields) % 6)
    text = "\n".join(";".join(fields[i:i + 6]) for i in range(0, len(fields), 6))
    got = kernel_table(text, ";", np.ones(6, bool), len(fields) // 6)
    assert got is not None
    want = _loadtxt(text, ";")
    assert got.tobytes() == want.tobytes()  # bits equal, signs of zeros included


def test_kept_columns(kernel: None) -> None:
    text = "1\t\t2.5\n-3\t\t4"
    got = kernel_table(text, "\t", np.array([True, False, True]), 2)
    assert got is not None and got.tolist() == [[1.0, 2.5], [-3.0, 4.0]]


@pytest.mark.parametrize("text", ["1,2\n3", "1,2,3\n4,5", "1e3,2", "nan,1", " 1,2", "1,",
                                  "-,1", "1.2.3,4", "x,1", "12345678901234567890,1",
                                  "9007199254740993,1", "1,2\r", "0.12345678901234567890123,1"])
def test_other_fields_are_left_to_loadtxt(kernel: None, text: str) -> None:
    assert kernel_table(text, ",", np.ones(2, bool), text.count("\n") + 1) is None
