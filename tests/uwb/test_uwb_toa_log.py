"""TOA CSV logs: reading, writing, grouping into transmissions, errors naming line and field."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ikfusion.errors import InputError
from ikfusion.uwb import (
    ToaLog,
    group_transmissions,
    read_toa_csv,
    toa_log_from_matrix,
    write_toa_csv,
)

GOOD = """time,tag,seq,reader,toa
# a comment line
0.100000,T1,0,R1,12.50000
0.100001,T1,0,R2,13.25000

0.100002,T1,0,R3,
0.100003,T1,0,R4,NaN
0.200000,T2,0,R1,40.00000
0.200001,T1,1,R2,20.00000
"""


def test_read_skips_missed_receptions_and_keeps_line_numbers(tmp_path):
    path = tmp_path / "toa.csv"
    path.write_text(GOOD)
    log = read_toa_csv(path)
    assert len(log) == 4 and log.missed == 2
    assert log.line.tolist() == [3, 4, 8, 9]
    np.testing.assert_allclose(log.toa, [12.5, 13.25, 40.0, 20.0])
    assert log.tag.tolist() == ["T1", "T1", "T2", "T1"]
    assert log.seq.tolist() == [0, 0, 0, 1]


def test_columns_in_any_order_with_extra_columns(tmp_path):
    path = tmp_path / "toa.csv"
    path.write_text("reader,toa,rssi,seq,tag,time\nR2,5.5,-80,7,A,1.25\n")
    log = read_toa_csv(path)
    assert log.reader.tolist() == ["R2"] and log.toa.tolist() == [5.5]
    assert log.seq.tolist() == [7] and log.time.tolist() == [1.25]


@pytest.mark.parametrize(
    ("row", "field", "message"),
    [
        ("0.3,T1,2,R1,abc", "toa", "expected a number"),
        ("0.3,T1,2,R1,inf", "toa", "finite"),
        ("x,T1,2,R1,1.0", "time", "expected a number"),
        (",T1,2,R1,1.0", "time", "empty field"),
        ("0.3,T1,2.5,R1,1.0", "seq", "integer"),
        ("0.3,,2,R1,1.0", "tag", "empty field"),
        ("0.3,T1,2,,1.0", "reader", "empty field"),
        ("0.3,T1,2,R1", None, "expected 5 comma-separated fields"),
    ],
)
def test_bad_line_names_file_line_and_field(tmp_path, row, field, message):
    path = tmp_path / "toa.csv"
    path.write_text(GOOD + row + "\n0.4,T1,3,R1,1.0\n")
    with pytest.raises(InputError, match=message) as info:
        read_toa_csv(path)
    err = info.value
    assert err.path == path and err.line == 10 and err.field == field
    assert "line 10" in str(err) and str(path) in str(err)


def test_missing_column_and_empty_file(tmp_path):
    path = tmp_path / "toa.csv"
    path.write_text("time,tag,reader,toa\n1,T,R1,2\n")
    with pytest.raises(InputError, match="missing column") as info:
        read_toa_csv(path)
    assert info.value.field == "seq" and info.value.line == 1
    path.write_text("\n# nothing\n")
    with pytest.raises(InputError, match="empty file"):
        read_toa_csv(path)
    with pytest.raises(InputError, match="cannot read"):
        read_toa_csv(tmp_path / "absent.csv")


def test_grouping_into_transmissions(tmp_path):
    path = tmp_path / "toa.csv"
    path.write_text(GOOD)
    tx = group_transmissions(read_toa_csv(path), ["R1", "R2", "R3", "R4"])
    assert len(tx) == 3
    assert list(zip(tx.tag.tolist(), tx.seq.tolist())) == [("T1", 0), ("T2", 0), ("T1", 1)]
    np.testing.assert_allclose(tx.time, [0.1, 0.2, 0.200001])
    expected = np.array(
        [[12.5, 13.25, np.nan, np.nan], [40.0, np.nan, np.nan, np.nan],
         [np.nan, 20.0, np.nan, np.nan]]
    )  # fmt: skip
    np.testing.assert_array_equal(tx.toa, expected)


def test_wrapped_sequence_numbers_are_separate_transmissions():
    toa = np.array([[1.0, 2.0], [3.0, 4.0]])
    log = toa_log_from_matrix([10.0, 75.0], ["T", "T"], [5, 5], toa, ["A", "B"])
    tx = group_transmissions(log, ["A", "B"])
    assert len(tx) == 2
    np.testing.assert_array_equal(tx.toa, toa)


def test_unknown_reader_and_duplicates_name_the_line(tmp_path):
    path = tmp_path / "toa.csv"
    path.write_text(GOOD + "0.3,T1,2,R9,1.0\n")
    with pytest.raises(InputError, match="not in the constellation") as info:
        group_transmissions(read_toa_csv(path), ["R1", "R2", "R3", "R4"])
    assert info.value.line == 10 and info.value.field == "reader"
    path.write_text(GOOD + "0.100004,T1,0,R1,12.6\n")
    with pytest.raises(InputError, match="twice") as info:
        group_transmissions(read_toa_csv(path), ["R1", "R2", "R3", "R4"])
    assert info.value.line == 10


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(0, 1e5, allow_nan=False),
            st.sampled_from(["T1", "T2", "HeadTop"]),
            st.integers(0, 255),
            st.sampled_from(["R1", "R2", "R3"]),
            st.floats(-1e6, 1e9, allow_nan=False),
        ),
        max_size=30,
    )
)
def test_write_read_round_trip(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("rt") / "toa.csv"
    cols = list(zip(*rows)) if rows else [[], [], [], [], []]
    log = ToaLog(
        time=np.array(cols[0], dtype=float),
        tag=np.array(cols[1], dtype=object),
        seq=np.array(cols[2], dtype=np.int64),
        reader=np.array(cols[3], dtype=object),
        toa=np.array(cols[4], dtype=float),
        line=np.zeros(len(rows), dtype=np.int64),
    )
    write_toa_csv(path, log)
    back = read_toa_csv(path)
    assert back.tag.tolist() == log.tag.tolist() and back.reader.tolist() == log.reader.tolist()
    assert back.seq.tolist() == log.seq.tolist()
    np.testing.assert_allclose(back.time, log.time, atol=1e-6)
    np.testing.assert_allclose(back.toa, log.toa, atol=1e-5)
    assert back.line.tolist() == list(range(2, len(rows) + 2))
