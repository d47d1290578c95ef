"""PacketCounter damage never becomes a huge timeline: out-of-order rows, restarts, swaps, spikes.

The expected placement is worked out here from the rows written (sorted counters, the rows
whose counters were damaged), independently of the reader.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.io import read_mtmanager, write_mtmanager
from ikfusion.rotations import random_rotations

HEADER_LINES = 2  # "// Update Rate" + the header line of the hand-written files below


def write_acc_file(path: Path, counter: np.ndarray, acc_x: np.ndarray,
                   fine: np.ndarray | None = None, rate: float = 100.0) -> Path:
    """An export with PacketCounter[, SampleTimeFine], Acc_X..Z, rows in the order given."""
    head = "PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z" if fine is not None \
        else "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z"
    rows = []
    for k, (c, a) in enumerate(zip(counter, acc_x)):
        t = "" if fine is None else f"{int(fine[k])}\t"
        rows.append(f"{int(c) % 65536:05d}\t{t}{a:.3f}\t0.0\t9.8")
    path.write_text(f"// Update Rate: {rate:g}Hz\n{head}\n" + "\n".join(rows) + "\n")
    return path


def test_blocks_out_of_order_with_sample_time_fine_are_sorted(tmp_path: Path) -> None:
    """Old code: the backward SampleTimeFine step read as 4e9 ticks -> a 43 M-sample timeline."""
    true_counter = 1000 + np.arange(300)
    order = np.concatenate([np.arange(150, 300), np.arange(150)])  # second half written first
    acc = np.arange(300) * 0.01
    write_acc_file(tmp_path / "B_00B40001.txt", true_counter[order], acc[order],
                   fine=5_000_000 + true_counter[order] * 100.0)
    rec = read_mtmanager(tmp_path / "B_")
    s = rec.sensors["00B40001"]
    assert len(rec) == 300 and s.rows == 300 and s.lost == 0
    np.testing.assert_allclose(s.acc[:, 0], acc, atol=1e-9)
    assert any("backwards 1 time" in w and "SampleTimeFine agrees" in w and "sorted" in w
               for w in rec.warnings)


def test_counter_going_back_across_a_wrap_with_fine(tmp_path: Path) -> None:
    """A backward step of 40 000 packets looks like +25 536 to a 16-bit counter alone."""
    true_counter = np.concatenate([np.arange(100), 40000 + np.arange(100)])
    order = np.concatenate([np.arange(100, 200), np.arange(100)])
    acc = np.arange(200) * 0.01
    write_acc_file(tmp_path / "C_00B40002.txt", true_counter[order], acc[order],
                   fine=true_counter[order] * 100.0)
    s = read_mtmanager(tmp_path / "C_").sensors["00B40002"]
    assert s.span == (0, 40100) and s.lost == 39900
    np.testing.assert_allclose(s.acc[s.received, 0], acc, atol=1e-9)


def test_counter_restart_while_time_goes_on_is_refused(tmp_path: Path) -> None:
    counter = np.concatenate([np.arange(100), np.arange(100)])  # restarted at row 101
    path = write_acc_file(tmp_path / "R_00B40003.txt", counter, np.zeros(200),
                          fine=np.arange(200) * 100.0)
    with pytest.raises(InputError, match="restarted") as err:
        read_mtmanager(path)
    assert err.value.line == HEADER_LINES + 101 and err.value.field == "PacketCounter"


def test_swapped_counter_columns_are_refused(tmp_path: Path) -> None:
    """Old code: a 'PacketCounter' stepping by 100 ticks gave a timeline 100 times too long."""
    n = 400
    ticks = 2**32 - 20_000 + np.arange(n) * 100  # SampleTimeFine wraps inside the file
    path = tmp_path / "S_00B40004.txt"
    rows = [f"{np.mod(t, 2**32)}\t{c}\t0.1\t0.2\t9.8" for c, t in zip(np.arange(n), ticks)]
    path.write_text("// Update Rate: 100Hz\nPacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z\n"
                    + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match="look swapped") as err:
        read_mtmanager(path)
    assert err.value.line == 2 and err.value.field == "PacketCounter"
    assert main(["inspect", str(path)]) == 2


def test_single_corrupted_counters_are_skipped_and_the_rest_kept(tmp_path: Path) -> None:
    n = 800  # an 8 s trial
    counter = np.arange(n)
    damaged = np.array([100, 401, 650])
    written = counter.copy()
    written[damaged] = [40000, 20000, 61234]  # far from both neighbours
    acc = np.arange(n) * 0.01
    path = write_acc_file(tmp_path / "K_00B40005.txt", written, acc)
    rec = read_mtmanager(path)
    s = rec.sensors["00B40005"]
    expected = np.ones(n, dtype=bool)
    expected[damaged] = False
    assert len(rec) == n
    np.testing.assert_array_equal(s.received, expected)
    np.testing.assert_allclose(s.acc[expected, 0], acc[expected], atol=1e-9)
    lines = [str(HEADER_LINES + 1 + k) for k in damaged]
    assert any("corrupted counters" in w and all(x in w for x in lines) for w in rec.warnings)


@pytest.mark.parametrize("scrambled", [(0, 800), (300, 600)])
def test_a_scrambled_counter_is_refused_naming_the_line(tmp_path: Path, rng,
                                                        scrambled: tuple[int, int]) -> None:
    """Old code: random counters unwrapped into a timeline of millions of samples."""
    n = 800
    written = np.arange(n)
    a, b = scrambled
    written[a:b] = rng.integers(0, 65536, size=b - a)
    path = write_acc_file(tmp_path / "Z_00B40006.txt", written, np.zeros(n))
    with pytest.raises(InputError, match="jumps from") as err:
        read_mtmanager(path)
    assert err.value.field == "PacketCounter" and err.value.line is not None
    assert HEADER_LINES + a < err.value.line <= HEADER_LINES + b + 1  # a line of the damage


def test_repeated_rows_are_dropped_but_a_restart_without_fine_is_refused(tmp_path: Path) -> None:
    acc = np.arange(300) * 0.01
    counter = np.concatenate([np.arange(200), np.arange(150, 200), np.arange(200, 250)])
    again = np.concatenate([acc[:200], acc[150:200], acc[200:250]])  # rows 150-199 re-exported
    rec = read_mtmanager(write_acc_file(tmp_path / "D_00B4000B.txt", counter, again))
    s = rec.sensors["00B4000B"]
    assert len(rec) == 250 and s.lost == 0
    np.testing.assert_allclose(s.acc[:, 0], acc[:250], atol=1e-9)
    assert any("50 row(s) repeat" in w and "the same data again" in w for w in rec.warnings)
    restart = np.concatenate([np.arange(100), np.arange(100)])  # a restart: other data
    path = write_acc_file(tmp_path / "E_00B4000C.txt", restart, acc[:200])
    with pytest.raises(InputError, match="restarted") as err:
        read_mtmanager(path)
    assert err.value.line == HEADER_LINES + 101 and err.value.field == "PacketCounter"


def test_real_long_gaps_are_still_lost_packets(tmp_path: Path, rng) -> None:
    """The bound leaves room for true losses: 5 % loss and a 20 s drop-out without fine."""
    n = 6000
    keep = rng.random(n) > 0.05
    keep[2000:4000] = False
    keep[[0, -1]] = True
    write_mtmanager(tmp_path, "L_", "00B40007", np.arange(n)[keep],
                    random_rotations(int(keep.sum()), rng), 100.0, sample_time_fine=False)
    s = read_mtmanager(tmp_path / "L_").sensors["00B40007"]
    np.testing.assert_array_equal(s.received, keep)
    assert s.lost == int((~keep).sum())


def test_files_of_different_recordings_are_refused(tmp_path: Path, rng) -> None:
    """A 32-bit counter file far from the trial's 16-bit ones: not one recording."""
    for sid in ("00B40008", "00B4000A"):
        write_mtmanager(tmp_path, "M_", sid, np.arange(100), random_rotations(100, rng), 100.0)
    far = tmp_path / "M_00B40009.txt"
    far.write_text("// Update Rate: 100Hz\nPacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n"
                   + "\n".join(f"{5_000_000 + k}\t0\t0\t9.8" for k in range(100)) + "\n")
    with pytest.raises(InputError, match="do not come from one recording") as err:
        read_mtmanager(tmp_path / "M_")
    assert err.value.path == far


@pytest.mark.parametrize("bad_tick", [1e30, -5.0, 2.0**32 + 7, 123.5])
def test_an_impossible_sample_time_fine_confirms_no_gap(tmp_path: Path, bad_tick: float) -> None:
    """Found by the fuzz campaign: one SampleTimeFine of 1e30 "confirmed" a gap of millions of
    packets (a 5 M-sample timeline, 2 GB). A value that is not a 32-bit tick count is ignored."""
    counter = 1000 + np.arange(200)
    fine = 5_000_000 + counter * 100.0
    fine[57] = bad_tick
    path = tmp_path / "F_00B40009.txt"
    head = "PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z"
    rows = [f"{c:05d}\t{f:.10g}\t0.1\t0.0\t9.8" for c, f in zip(counter, fine)]
    path.write_text(f"// Update Rate: 100Hz\n{head}\n" + "\n".join(rows) + "\n")
    rec = read_mtmanager(tmp_path / "F_")
    s = rec.sensors["00B40009"]
    assert len(rec) == 200 and s.lost == 0
    assert any("SampleTimeFine value(s) that are not a 32-bit tick count" in w and "line 60" in w
               for w in rec.warnings)
