"""UDP packet format in: round trip over localhost, malformed datagrams counted and skipped."""

from __future__ import annotations

import socket
import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ikfusion.live.samples import ImuSample, ToaSample
from ikfusion.live.udp_source import (
    UdpDecoder,
    UdpSource,
    UdpStats,
    encode_datagrams,
    encode_record,
    encode_samples,
    end_record,
)


def make_samples(rng: np.random.Generator) -> list:
    out: list = []
    for k in range(60):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        t = 0.01 * k
        out.append(ImuSample("00B458EE", t, q, rng.normal(size=3), rng.normal(size=3),
                             (65530 + k) % 65536))
        out.append(ImuSample("LeftFoot", t, q))  # orientation only
        if k % 10 == 0:
            out.append(ImuSample("00B458F1", t, np.full(4, np.nan), counter=k))  # lost packet
            out.append(ToaSample(t + 0.001, "T1", k, "R3", 12.345678 + k))
    return out


def assert_same(got: list, sent: list) -> None:
    assert len(got) == len(sent)
    for a, b in zip(got, sent):
        assert type(a) is type(b)
        if isinstance(b, ToaSample):
            assert a == b
            continue
        assert (a.sensor, a.time_s, a.counter) == (b.sensor, b.time_s, b.counter)
        np.testing.assert_allclose(a.q_world_sensor, b.q_world_sensor, atol=1e-6)
        for x, y in ((a.acc, b.acc), (a.gyr, b.gyr)):
            assert (x is None) == (y is None)
            if y is not None:
                np.testing.assert_allclose(x, y, rtol=1e-6)


def send_all(port: int, datagrams: list[bytes]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for d in datagrams:
            s.sendto(d, ("127.0.0.1", port))


def through_udp(datagrams: list[bytes]) -> tuple[list, UdpStats]:
    """Send the datagrams to a UdpSource on localhost; its samples until the end record."""
    source = UdpSource(0, host="127.0.0.1", idle_timeout_s=5.0)
    try:
        send_all(source.port, datagrams)
        return list(source.samples()), source.stats
    finally:
        source.close()


def test_round_trip_over_udp(rng) -> None:
    sent = make_samples(rng)
    datagrams = encode_samples(sent) + encode_datagrams([end_record()])
    assert len(datagrams) < len(sent) / 5  # several samples per datagram
    got, stats = through_udp(datagrams)
    assert_same(got, sent)
    assert stats.malformed == 0 and stats.skipped == 0
    assert stats.samples == len(sent)


def test_malformed_datagrams_are_counted_and_skipped_good_data_kept(rng) -> None:
    good = make_samples(rng)[:20]
    records = [encode_record(s) for s in good]
    header = struct.pack("<4sBBH", b"IKFU", 1, 1, 0)
    bad_utf8 = bytearray(records[0])
    bad_utf8[4 + 8 + 1] = 0xFF  # first byte of the sensor name
    unknown_kind = struct.pack("<BBH", 7, 0, 8) + b"\0" * 4
    wrong_size = bytearray(records[1])
    wrong_size[2:4] = struct.pack("<H", 9999)
    datagrams = [
        encode_datagrams(records[0:5])[0],
        b"",  # empty
        b"garbage that is not a packet",  # wrong magic
        struct.pack("<4sBBH", b"IKFU", 2, 1, 0) + records[5],  # unknown version
        header + bytes(wrong_size),  # record size runs past the end: malformed
        encode_datagrams([records[5], bytes(bad_utf8), unknown_kind, records[6]])[0],
        encode_datagrams(records[7:20])[0][:-3],  # truncated: its last record is lost
        encode_datagrams([end_record()])[0],
    ]
    got, stats = through_udp(datagrams)
    assert_same(got, good[0:7] + good[7:19])
    assert stats.datagrams == len(datagrams)
    assert stats.malformed == 5  # empty, magic, version, size, truncated
    assert stats.skipped == 2  # bad UTF-8 name, unknown kind


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_decoder_never_raises_on_random_bytes(data: bytes) -> None:
    decoder = UdpDecoder()
    decoder.decode(data)
    decoder.decode(b"IKFU\x01" + data)
    assert decoder.stats.datagrams == 2


@settings(max_examples=300, deadline=None)
@given(st.integers(min_value=0, max_value=10_000), st.integers(min_value=0, max_value=255))
def test_decoder_never_raises_on_a_corrupted_byte(position: int, value: int) -> None:
    sample = ImuSample("00B458EE", 1.5, np.array([1.0, 0, 0, 0]), np.ones(3), np.ones(3), 7)
    toa = ToaSample(1.5, "T1", 3, "R1", 4.0)
    datagram = bytearray(encode_samples([sample, toa, sample])[0])
    datagram[position % len(datagram)] = value
    decoder = UdpDecoder()
    decoded = decoder.decode(bytes(datagram))
    assert len(decoded) + decoder.stats.skipped <= 3


def test_example_sender_reaches_the_source(tmp_path) -> None:
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    imu = tmp_path / "imu.csv"
    imu.write_text("time,sensor,qw,qx,qy,qz,ax,ay,az,gx,gy,gz\n"
                   "0.00,S1,1,0,0,0,0,0,9.81,0,0,0\n0.00,S2,0,1,0,0,0,0,9.81,0,0,0\n"
                   "0.01,S1,1,0,0,0,0,0,9.81,0,0,0.5\n")
    toa = tmp_path / "toa.csv"
    toa.write_text("time,tag,seq,reader,toa\n0.005,T1,0,R1,3.25\n")
    source = UdpSource(0, host="127.0.0.1", idle_timeout_s=20.0)
    try:
        subprocess.run([sys.executable, str(root / "examples" / "udp_sender.py"), str(imu),
                        "--toa", str(toa), "--port", str(source.port)], check=True,
                       env={"PYTHONPATH": str(root)}, timeout=60)
        got = list(source.samples())
    finally:
        source.close()
    assert [type(s).__name__ for s in got] == ["ImuSample", "ImuSample", "ToaSample",
                                               "ImuSample"]
    assert got[2] == ToaSample(0.005, "T1", 0, "R1", 3.25)
    np.testing.assert_allclose(got[3].gyr, [0, 0, 0.5])
