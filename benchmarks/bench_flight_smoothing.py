"""Does the simulated capture's smoothing hide flights from the flight detector?

``write_capture`` low-pass filters the truth (Gaussian, ``sigma`` 50 ms) whenever UWB is
simulated (:func:`ikfusion.sim.uwb_capture.smooth_truth`), and the IMUs, the UWB ranges and
``truth.npz`` all come from that smoothed motion. This benchmark simulates perfect IMUs on a
clip of ``benchmarks/motions/library.yaml`` from its truth smoothed with several ``sigma`` (0:
the raw truth) and runs :func:`ikfusion.imu.flight.detect_flight` on them.

Columns: flights of the truth (runs of at least 3 frames without a contact), how many of them
the detector flags at all, the share of the truth's flight frames flagged (recall), the share
of its ground frames flagged (false), the median over flights of the pelvis ``|f|`` minimum
[m/s^2] (free fall reads 0; the detector needs < 5), and the 99th percentile of the pelvis
``|f|`` on the ground [m/s^2] (what the raw truth's frame-to-frame jitter adds).

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_flight_smoothing.py [--clips gen-skip
cmu-02-03-run ...] [--seconds 15] [--sigmas-ms 0 17 50]``
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from benchmarks.bench_motions import RATE, clip_truth, load_library
from ikfusion.imu.flight import detect_flight
from ikfusion.model import SENSOR_SEGMENTS
from ikfusion.sim.imu import ImuNoise, simulate_imus
from ikfusion.sim.uwb_capture import smooth_truth

FEET = ("LeftFoot", "RightFoot")


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` of the runs of True in ``mask``."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def main(argv: Sequence[str] | None = None) -> int:
    """Print one row per clip and smoothing; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clips", nargs="+", default=["gen-skip", "gen-hop", "cmu-02-03-run",
                                                       "amp-run", "cmu-01-01-jumps"])
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--sigmas-ms", nargs="+", type=float, default=[0.0, 17.0, 50.0])
    args = parser.parse_args(argv)
    library = {c.name: c for c in load_library().clips}
    segments = list(SENSOR_SEGMENTS)
    print(f"{'clip':<18s} {'sigma ms':>8s} {'flights':>7s} {'found':>5s} {'recall':>6s} "
          f"{'false':>6s} {'min |f|':>7s} {'p99 gnd':>7s}")
    for name in args.clips:
        truth = clip_truth(library[name], args.seconds)
        flying = ~truth.contacts.any(axis=1)
        flights = [(a, b) for a, b in runs(flying) if b - a >= 3]
        for sigma_ms in args.sigmas_ms:
            motion = truth if sigma_ms <= 0 else smooth_truth(truth, sigma_ms / 1000.0)
            imus = simulate_imus(motion.model, motion.time, motion.q, segments,
                                 np.random.default_rng(1), ImuNoise.none())
            acc = dict(zip(segments, imus.acc))
            gyr = dict(zip(segments, imus.gyr))
            airborne = detect_flight(RATE, acc["Pelvis"], {f: acc[f] for f in FEET},
                                     {f: gyr[f] for f in FEET}).airborne
            pelvis = np.linalg.norm(acc["Pelvis"], axis=1)
            found = sum(bool(airborne[a:b].any()) for a, b in flights)
            lowest = np.median([pelvis[a:b].min() for a, b in flights]) if flights else np.nan
            recall = airborne[flying].mean() if flying.any() else np.nan
            print(f"{name:<18s} {sigma_ms:8.0f} {len(flights):7d} {found:5d} {recall:6.2f} "
                  f"{airborne[~flying].mean():6.3f} {lowest:7.1f} "
                  f"{np.percentile(pelvis[~flying], 99):7.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
