"""UWB reader calibration on simulated halls: accuracy, predicted vs actual error, solve time.

The issue-7 scenario: 12 readers along the walls of a 20 x 20 m hall (heights 1-3 m, clock
offsets +-30 m), 60 s of wand at 10 Hz, range sigma 3 cm, NLOS on 5 % (or 20 %) of receptions
(0.2-2 m late), 2 % missed receptions, each reader's calibration tag beaconing every 5 s
(``--beacon-rate``). Wand paths: ``hall`` (a figure of eight through the whole hall) and
``centre`` (a 1 m circle at the centre). ``links`` uses the reader-to-reader transmissions in the
joint problem too (the default); ``wand-only`` uses them for the first estimate only.

Errors are RMS over the readers after a rigid 2-D alignment on all readers (horizontal
positions) and with the common offset removed (clock offsets, in metres of range); ``pred`` is
the calibration's own prediction of the same quantity from its posterior covariance.

Run: .venv/bin/python benchmarks/bench_calibration.py [--seeds 3] [--beacon-rate 0.2]
"""

from __future__ import annotations

import argparse

import numpy as np

from ikfusion.uwb import (
    CalibrationError,
    calibrate,
    hall_constellation,
    simulate_calibration_log,
    wand_path,
)
from ikfusion.uwb.calibration_frame import fit_rigid_2d

SCENARIOS = (
    ("hall", 0.05, True),
    ("hall", 0.20, True),
    ("centre", 0.05, True),
    ("hall", 0.05, False),
    ("hall", 0.20, False),
    ("centre", 0.05, False),
)


def errors(cal, truth) -> tuple[float, float]:
    est = cal.constellation.positions
    fit = fit_rigid_2d(est, truth.positions, allow_mirror=True)
    err = fit.apply(est)[:, :2] - truth.positions[:, :2]
    clock = cal.constellation.clock_offsets - truth.clock_offsets
    clock -= clock.mean()
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1)))), float(np.sqrt(np.mean(clock**2)))


def run(path: str, nlos: float, links: bool, seed: int, beacon_rate: float) -> dict | str:
    rng = np.random.default_rng(seed)
    truth = hall_constellation(rng)
    t, p = wand_path(path)
    sim = simulate_calibration_log(truth, t, p, rng, nlos_fraction=nlos, reader_rate=beacon_rate)
    try:
        cal = calibrate(sim.log, sim.heights, reader_links=links)
    except CalibrationError as err:
        return err.reason.split(":")[0]
    pos, clock = errors(cal, truth)
    return {
        "pos": pos, "pos_pred": cal.predicted_rms, "clock": clock,
        "clock_pred": cal.predicted_clock_rms, "outliers": cal.outliers.fraction,
        "rounds": cal.rounds, "iterations": cal.iterations, "solve": cal.timings["solve"],
        "total": cal.timings["total"], "receptions": len(sim.log),
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="seeds per scenario (1, 2, ...)")
    parser.add_argument("--beacon-rate", type=float, default=0.2, help="reader-tag rate [Hz]")
    args = parser.parse_args()
    print(f"12 readers, 60 s wand at 10 Hz, sigma 3 cm, beacons {args.beacon_rate} Hz; "
          f"{args.seeds} seed(s) each; errors in cm (actual / predicted)")  # fmt: skip
    head = (f"{'path':7s} {'NLOS':>5s} {'joint':9s} {'seed':>4s} {'pos cm':>13s} "
            f"{'clock cm':>13s} {'outl %':>6s} {'rnd':>3s} {'it':>3s} {'solve s':>7s} "
            f"{'total s':>7s}")  # fmt: skip
    print(head)
    print("-" * len(head))
    for path, nlos, links in SCENARIOS:
        for seed in range(1, args.seeds + 1):
            r = run(path, nlos, links, seed, args.beacon_rate)
            label = f"{path:7s} {100 * nlos:4.0f}% {'links' if links else 'wand-only':9s} {seed:4d}"
            if isinstance(r, str):
                print(f"{label} refused: {r}")
                continue
            print(f"{label} {100 * r['pos']:6.2f}/{100 * r['pos_pred']:5.2f} "
                  f"{100 * r['clock']:6.2f}/{100 * r['clock_pred']:5.2f} "
                  f"{100 * r['outliers']:6.1f} {r['rounds']:3d} {r['iterations']:3d} "
                  f"{r['solve']:7.2f} {r['total']:7.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
