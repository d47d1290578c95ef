"""IMU samples and UWB times of arrival over UDP: the packet format, its codec and a source.

Binary, little-endian, versioned (README "UDP packet format"). Binary rather than JSON lines:
the senders are small boards (an ESP32 beside each sensor, a UWB reader) that fill a C struct
and send it; a sample is 60 bytes instead of ~200 characters of text, floats arrive bit-exact,
and little-endian is what those processors (and x86) store natively.

Datagram = header + records::

    header (8 bytes): magic "IKFU" | u8 version (1) | u8 record count | u16 reserved (0)
    record:           u8 kind | u8 flags | u16 record size [bytes, these 4 included] | body

    kind 1, IMU sample:  f64 time [s] | str sensor | 4 x f32 quaternion w, x, y, z
                         (R_world_sensor; NaN = no valid orientation)
                         [flags & 1: 3 x f32 acc, sensor frame, m/s^2]
                         [flags & 2: 3 x f32 gyr, sensor frame, rad/s]
                         [flags & 4: u16 packet counter]
    kind 2, UWB TOA:     f64 time [s] | u32 seq | f64 toa [m] | str tag | str reader
    kind 255, end:       no body: the stream ends (the source's iterator stops)
    str = u8 byte count + UTF-8 bytes (1..255 bytes)

One datagram may carry several records of any kinds. The decoder never raises on what arrives:
a datagram with a wrong magic, version or count, or a record whose size runs past the end, is
counted in :attr:`UdpStats.malformed` (records decoded before the fault are kept); a record of
an unknown kind or with an undecodable body is skipped and counted in :attr:`UdpStats.skipped`.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from .samples import ImuSample, Sample, ToaSample

MAGIC = b"IKFU"
VERSION = 1
HEADER = struct.Struct("<4sBBH")
RECORD = struct.Struct("<BBH")
KIND_IMU = 1
KIND_TOA = 2
KIND_END = 255
FLAG_ACC = 1
FLAG_GYR = 2
FLAG_COUNTER = 4
#: Largest datagram the encoder builds [bytes] (under a 1500-byte Ethernet MTU).
MAX_DATAGRAM = 1400


def _text(value: str) -> bytes:
    raw = value.encode("utf-8")
    if not 0 < len(raw) < 256:
        raise ValueError(f"a name must be 1 to 255 UTF-8 bytes, got {value!r}")
    return bytes([len(raw)]) + raw


def encode_record(sample: Sample) -> bytes:
    """One record (kind, flags, size, body) of an IMU sample or a TOA."""
    if isinstance(sample, ImuSample):
        flags = 0
        body = struct.pack("<d", sample.time_s) + _text(sample.sensor)
        body += struct.pack("<4f", *np.asarray(sample.q_world_sensor, dtype=float))
        if sample.acc is not None:
            flags |= FLAG_ACC
            body += struct.pack("<3f", *np.asarray(sample.acc, dtype=float))
        if sample.gyr is not None:
            flags |= FLAG_GYR
            body += struct.pack("<3f", *np.asarray(sample.gyr, dtype=float))
        if sample.counter is not None:
            flags |= FLAG_COUNTER
            body += struct.pack("<H", sample.counter & 0xFFFF)
        kind = KIND_IMU
    else:
        flags = 0
        body = (struct.pack("<dId", sample.time_s, sample.seq & 0xFFFFFFFF, sample.toa_m)
                + _text(sample.tag) + _text(sample.reader))
        kind = KIND_TOA
    return RECORD.pack(kind, flags, RECORD.size + len(body)) + body


def end_record() -> bytes:
    """The record that ends a stream."""
    return RECORD.pack(KIND_END, 0, RECORD.size)


def encode_datagrams(records: Iterable[bytes], max_size: int = MAX_DATAGRAM) -> list[bytes]:
    """Pack records into as few datagrams of at most ``max_size`` bytes as they fit in."""
    out: list[bytes] = []
    batch: list[bytes] = []
    size = HEADER.size

    def flush() -> None:
        if batch:
            out.append(HEADER.pack(MAGIC, VERSION, len(batch), 0) + b"".join(batch))

    for record in records:
        if batch and (size + len(record) > max_size or len(batch) == 255):
            flush()
            batch, size = [], HEADER.size
        batch.append(record)
        size += len(record)
    flush()
    return out


def encode_samples(samples: Iterable[Sample], max_size: int = MAX_DATAGRAM) -> list[bytes]:
    """Datagrams carrying the samples in order (several per datagram)."""
    return encode_datagrams((encode_record(s) for s in samples), max_size)


@dataclass
class UdpStats:
    """What the decoder saw.

    Attributes:
        datagrams: Datagrams received.
        samples: Samples decoded.
        malformed: Datagrams with a bad header or a record running past the end.
        skipped: Records of an unknown kind or with an undecodable body.
    """

    datagrams: int = 0
    samples: int = 0
    malformed: int = 0
    skipped: int = 0


class _Reader:
    """Reads fields from a record body; raises ValueError past its end."""

    def __init__(self, body: bytes) -> None:
        self.body = body
        self.at = 0

    def take(self, fmt: str) -> tuple[float | int, ...]:
        size = struct.calcsize(fmt)
        if self.at + size > len(self.body):
            raise ValueError("record body too short")
        values = struct.unpack_from(fmt, self.body, self.at)
        self.at += size
        return values

    def text(self) -> str:
        (n,) = self.take("<B")
        if n == 0 or self.at + int(n) > len(self.body):
            raise ValueError("bad name length")
        raw = self.body[self.at:self.at + int(n)]
        self.at += int(n)
        return raw.decode("utf-8")


def _decode_body(kind: int, flags: int, body: bytes) -> Sample:
    """One sample from a record body (ValueError/UnicodeDecodeError when it does not hold)."""
    r = _Reader(body)
    if kind == KIND_IMU:
        (time_s,) = r.take("<d")
        sensor = r.text()
        q = np.array(r.take("<4f"), dtype=float)
        acc = np.array(r.take("<3f"), dtype=float) if flags & FLAG_ACC else None
        gyr = np.array(r.take("<3f"), dtype=float) if flags & FLAG_GYR else None
        counter = int(r.take("<H")[0]) if flags & FLAG_COUNTER else None
        sample: Sample = ImuSample(sensor, float(time_s), q, acc, gyr, counter)
    elif kind == KIND_TOA:
        time_s, seq, toa = r.take("<dId")
        sample = ToaSample(float(time_s), r.text(), int(seq), r.text(), float(toa))
    else:
        raise ValueError(f"unknown record kind {kind}")
    if r.at != len(body):
        raise ValueError("record body longer than its fields")
    if not np.isfinite(sample.time_s):
        raise ValueError("time is not finite")
    return sample


class UdpDecoder:
    """Decodes datagrams into samples, counting and skipping what does not hold."""

    def __init__(self) -> None:
        self.stats = UdpStats()
        self.ended = False

    def decode(self, datagram: bytes) -> list[Sample]:
        """The samples of one datagram (never raises on its content)."""
        self.stats.datagrams += 1
        if len(datagram) < HEADER.size:
            self.stats.malformed += 1
            return []
        magic, version, count, _ = HEADER.unpack_from(datagram, 0)
        if magic != MAGIC or version != VERSION or count == 0:
            self.stats.malformed += 1
            return []
        out: list[Sample] = []
        at = HEADER.size
        for _ in range(count):
            if at + RECORD.size > len(datagram):
                self.stats.malformed += 1
                break
            kind, flags, size = RECORD.unpack_from(datagram, at)
            if size < RECORD.size or at + size > len(datagram):
                self.stats.malformed += 1
                break
            body = datagram[at + RECORD.size:at + size]
            at += size
            if kind == KIND_END:
                self.ended = True
                break
            try:
                out.append(_decode_body(kind, flags, body))
            except (ValueError, UnicodeDecodeError):
                self.stats.skipped += 1
        else:
            if at != len(datagram):
                self.stats.malformed += 1
        self.stats.samples += len(out)
        return out


class UdpSource:
    """A :class:`~ikfusion.live.samples.SampleSource` listening on a UDP port.

    Args:
        port: UDP port to listen on (0: any free port, see :attr:`port`).
        host: Address to bind (all interfaces by default).
        idle_timeout_s: The stream ends after this long without a datagram [s]; None: only an
            end record or :meth:`close` ends it.
    """

    def __init__(self, port: int, host: str = "0.0.0.0", idle_timeout_s: float | None = None
                 ) -> None:
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self._socket.bind((host, port))
        self._socket.settimeout(0.2)
        self.port: int = self._socket.getsockname()[1]
        self.idle_timeout_s = idle_timeout_s
        self.decoder = UdpDecoder()
        self._closed = False

    @property
    def stats(self) -> UdpStats:
        """Counts of datagrams, samples, malformed datagrams and skipped records."""
        return self.decoder.stats

    def samples(self) -> Iterator[Sample]:
        """Samples in arrival order until an end record, the idle timeout or :meth:`close`."""
        idle = 0.0
        while not self._closed and not self.decoder.ended:
            try:
                datagram = self._socket.recv(65536)
            except TimeoutError:
                idle += 0.2
                if self.idle_timeout_s is not None and idle >= self.idle_timeout_s:
                    return
                continue
            except OSError:
                return  # closed from another thread
            idle = 0.0
            yield from self.decoder.decode(datagram)

    def close(self) -> None:
        """Stop listening."""
        self._closed = True
        self._socket.close()
