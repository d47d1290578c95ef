"""Send a generic IMU CSV (and a UWB TOA CSV) to ``ikfusion live --udp PORT`` in real time.

The packet format is README's "UDP packet format" (ikfusion.live.udp_source); a board would
fill the same little-endian records in C. Usage::

    python examples/udp_sender.py imu.csv [--toa toa.csv] [--host 127.0.0.1] [--port 9000]

``imu.csv`` has the columns ``time,sensor,qw,qx,qy,qz`` and optionally ``ax,ay,az,gx,gy,gz``
(SPEC section 4); ``toa.csv`` the columns ``time,tag,seq,reader,toa``.
"""

from __future__ import annotations

import argparse
import csv
import socket
import time

import numpy as np

from ikfusion.live.samples import ImuSample, Sample, ToaSample
from ikfusion.live.udp_source import encode_datagrams, encode_samples, end_record


def _vector(row: dict[str, str], *keys: str) -> np.ndarray | None:
    """The columns ``keys`` of a row as a vector, or None when the file has no such columns."""
    return np.array([float(row[k]) for k in keys]) if keys[0] in row else None


def read_samples(imu_csv: str, toa_csv: str | None) -> list[Sample]:
    """Every row as a sample, in time order."""
    samples: list[Sample] = []
    with open(imu_csv, newline="") as f:
        for row in csv.DictReader(f):
            q = np.array([float(row[k]) for k in ("qw", "qx", "qy", "qz")])
            samples.append(ImuSample(row["sensor"], float(row["time"]), q,
                                     _vector(row, "ax", "ay", "az"),
                                     _vector(row, "gx", "gy", "gz")))
    if toa_csv:
        with open(toa_csv, newline="") as f:
            samples += [ToaSample(float(r["time"]), r["tag"], int(r["seq"]), r["reader"],
                                  float(r["toa"])) for r in csv.DictReader(f)]
    return sorted(samples, key=lambda s: s.time_s)


def main() -> None:
    """Send the samples of each instant in one datagram (or a few), paced by their times."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("imu_csv")
    parser.add_argument("--toa")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=9000)
    args = parser.parse_args()
    samples = read_samples(args.imu_csv, args.toa)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start = time.monotonic() - samples[0].time_s if samples else 0.0
    k = 0
    while k < len(samples):
        t = samples[k].time_s
        batch = [s for s in samples[k:k + 64] if s.time_s == t]
        time.sleep(max(0.0, start + t - time.monotonic()))
        for datagram in encode_samples(batch):
            sock.sendto(datagram, (args.host, args.port))
        k += len(batch)
    for datagram in encode_datagrams([end_record()]):
        sock.sendto(datagram, (args.host, args.port))


if __name__ == "__main__":
    main()
