"""The C table reader (number_parse.c) against NumPy's loadtxt and the Python path: the same
doubles and NaNs to the bit, and the same errors and warnings for hostile export files."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import InputError
from ikfusion.io import table
from ikfusion.io.mtmanager import read_mtmanager_file
from ikfusion.io.parse_kernel import kernel_table


def _loadtxt(text: str, delimiter: str) -> np.ndarray:
    return np.loadtxt(io.StringIO(text), delimiter=delimiter, comments=None, ndmin=2,
                      dtype=float, quotechar=None)


@pytest.fixture
def kernel() -> None:
    if kernel_table("1", ",", 1) is None:
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
    got = kernel_table(text, ";", 6)
    assert got is not None
    want = _loadtxt(text, ";")
    assert got.tobytes() == want.tobytes()  # bits equal, signs of zeros included


def test_empty_fields_are_nan_as_the_python_path(kernel: None,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    for text in ["1\t\t2.5\n-3\t\t4", "\t1\t\n\t\t", "\t\n\t", "1  2\n 3 "]:
        d = "\t" if "\t" in text else " "
        got = kernel_table(text, d, 3 if text.count(d) > 3 else 2)
        assert got is not None
        monkeypatch.setattr(table, "kernel_table", lambda *args: None)
        want = table.parse_block(text, d, got.shape[1])
        monkeypatch.undo()
        assert want is not None and got.tobytes() == want.tobytes()


@pytest.mark.parametrize("text", ["1,2\n3", "1,2,3\n4,5", "1e3,2", "nan,1", " 1,2", "1,2\n",
                                  "-,1", "1.2.3,4", "x,1", "12345678901234567890,1",
                                  "9007199254740993,1", "1,2\r", "0.12345678901234567890123,1",
                                  "1,\u0662", "1,2\x00"])
def test_other_fields_are_left_to_loadtxt(kernel: None, text: str) -> None:
    assert kernel_table(text, ",", 2) is None


def test_a_blank_line_of_one_column_is_left_to_loadtxt(kernel: None) -> None:
    assert kernel_table("1\n\n2", ",", 1) is None  # loadtxt skips it: not a NaN row


_HOSTILE = ["1e999", "-1e999", "nan", "-nan", "inf", "-inf", "-0", "+0", "+.5", "-.5", ".5", "5.",
            ".", "-", "+", "+-1", "0x1A", "1,000", "1_000", "\u0661\u0662", "\uff11", "1\r", "\r",
            "1\t", " 1", "1 ", "1\x00", "", "1e5", "1.2.3", "12345678901234567",
            "9007199254740992", "9007199254740993", "18446744073709551616",
            "0.0000000000000000000001", "0.00000000000000000000001", "4.9e-324",
            "2.2250738585072014e-308", "0" * 300 + "1", "0." + "0" * 300, "1" * 40,
            "0.1234567890123456789", "\u22121", "1\u00a0", "1\x0b"]


def _plain(rng: np.random.Generator) -> str:
    digits = "".join(map(str, rng.integers(0, 10, int(rng.integers(0, 8)))))
    decimals = "".join(map(str, rng.integers(0, 10, int(rng.integers(0, 10)))))
    sign = ["", "-", "+"][int(rng.integers(0, 3))]
    return sign + digits + ("." + decimals if rng.random() < 0.7 else "")


def _field(rng: np.random.Generator, plain: float) -> str:
    if rng.random() < plain:
        return _plain(rng)
    return _HOSTILE[int(rng.integers(0, len(_HOSTILE)))]


def test_hostile_blocks_read_as_the_python_path_or_left_to_it(
        kernel: None, monkeypatch: pytest.MonkeyPatch) -> None:
    """Fuzz: whatever the kernel accepts, the Python path (loadtxt) reads to the same bits."""
    rng = np.random.default_rng(24)
    accepted = 0
    for _ in range(1500):
        delimiter = "\t;, "[int(rng.integers(0, 4))]
        width, lines = int(rng.integers(1, 6)), int(rng.integers(1, 5))
        plain = 0.97 if rng.random() < 0.5 else 0.6
        text = "\n".join(delimiter.join(_field(rng, plain) for _ in range(width))
                         for _ in range(lines))
        if rng.random() < 0.15:
            text = text[:int(rng.integers(0, len(text) + 1))]
        got = kernel_table(text, delimiter, width)
        if got is None:
            continue
        accepted += 1
        monkeypatch.setattr(table, "kernel_table", lambda *args: None)
        want = table.parse_block(text, delimiter, width)
        monkeypatch.undo()
        assert want is not None and got.shape == want.shape, repr(text)
        assert got.tobytes() == want.tobytes(), repr(text)
    assert accepted > 100  # the fuzz reaches the kernel's accepting path


def test_hostile_export_files_read_the_same_with_and_without_kernel(
        kernel: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Fuzz: an MT Manager export reads to the same array, numbers and warnings, or the same
    error naming file, line and column, with the C kernel and with loadtxt alone."""
    rng = np.random.default_rng(7)
    path = tmp_path / "MT_x_00B421E6.txt"
    for _ in range(120):
        d = "\t;, "[int(rng.integers(0, 4))]
        rows = []
        for k in range(int(rng.integers(1, 6))):
            fields = [f"{k:05d}", "", *(f"{v:.6f}" for v in rng.uniform(-20, 20, 3))]
            if rng.random() < 0.4:
                fields[int(rng.integers(2, 5))] = _field(rng, 0.0)
            rows.append(d.join(fields))
        text = f"// Update Rate: 100.0Hz\nPacketCounter{d}Year{d}Acc_X{d}Acc_Y{d}Acc_Z\n"
        text += "\n".join(rows)
        if rng.random() < 0.2:
            text = text[:int(rng.integers(len(text) - len(rows[-1]), len(text) + 1))]
        if rng.random() < 0.2:
            text = text.replace("\n", "\r\n")
        path.write_bytes(text.encode())
        outcomes = []
        for reader in (table.kernel_table, lambda *args: None):
            monkeypatch.setattr(table, "kernel_table", reader)
            try:
                got = read_mtmanager_file(path)
                outcomes.append((got.data.shape, got.data.tobytes(), got.line_numbers.tolist(),
                                 got.warnings))
            except InputError as err:
                outcomes.append(("error", str(err)))
        assert outcomes[0] == outcomes[1], repr(text)
