"""IMU + UWB filter (``ikfusion.uwb.tracking.track_tags``) against per-transmission fixes.

Run: ``.venv/bin/python benchmarks/bench_ekf.py [--seconds 60] [--rate 60] [--seed 5]``.
A simulated walk (circles of 1.5 m radius after a 2 s N-pose, smoothed truth) in the 6 m x 8 m
room of ``configs/constellations/room_6x8.yaml`` (10 readers, random clock offsets), sigma 3 cm,
tags on HeadTop, LeftFootTop and RightFootTop at 10 Hz each, 10 % NLOS (0.2-2 m), IMUs with
the default errors of ``ikfusion.sim.imu``. Cases: ``clean``; ``2 readers`` (all but R1 and R6
blocked for 5 s from t = 12 s; the filter row uses the tag-height aid); ``no UWB`` (20 s without
any reception from t = 8 s, when the walk is long enough).

Rows: the causal ``filter`` (each instant from the past only), the ``smoothed`` track (the
filter and its Rauch-Tung-Striebel pass backward, what ``solve`` uses) and ``locate``.
Columns: RMS and p95 of the 3-D error [cm] (filter at every IMU frame after its start, locate
at each transmission with a fix), ``max in window`` the largest error inside the case's window,
``avail`` the fraction of IMU frames (filter) or of the tag's transmissions (locate) with a
position, NLOS precision/recall over receptions, and the filter's time per IMU sample [us].
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import HumanModel
from ikfusion.paths import shipped_config
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.imu import simulate_imus
from ikfusion.sim.uwb_capture import (
    Blockage,
    UwbCaptureOptions,
    default_tags,
    imu_units_from_simulation,
    simulate_uwb,
    smooth_truth,
)
from ikfusion.uwb import group_transmissions, load_constellation, locate, make_constellation
from ikfusion.uwb.ekf import EkfOptions
from ikfusion.uwb.tracking import track_tags


def _constellation(rng: np.random.Generator):
    c = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    return make_constellation(c.positions, ids=c.ids, sigma=0.03, area=c.area,
                              clock_offsets=rng.uniform(-30.0, 30.0, len(c.readers)))


def _precision_recall(rejected: np.ndarray, delayed: np.ndarray) -> tuple[float, float]:
    hit = float((rejected & delayed).sum())
    return hit / max(int(rejected.sum()), 1), hit / max(int(delayed.sum()), 1)


def _row(name: str, err: np.ndarray, window: np.ndarray, avail: float, pr: tuple[float, float],
         us: float | None) -> str:
    ok = err[np.isfinite(err)]
    rms = np.sqrt(np.mean(ok**2)) * 100 if ok.size else np.nan
    p95 = np.percentile(ok, 95) * 100 if ok.size else np.nan
    inside = err[window & np.isfinite(err)]
    worst = f"{inside.max() * 100:7.1f}" if inside.size else "      -"
    speed = f"{us:8.0f}" if us is not None else "       -"
    return (f"{name:<34s} {rms:6.1f} {p95:6.1f} {worst}  {avail * 100:5.1f}%"
            f"  {pr[0]:5.2f} {pr[1]:5.2f} {speed}")


def _case(label, truth, imus, c, options, window, rng_seed, use_height) -> list[str]:
    tags = default_tags()
    sim = simulate_uwb(truth, c, np.random.default_rng(rng_seed), options, tags)
    units = imu_units_from_simulation(truth, imus, tags)
    runs = {}
    for name, smooth in (("filter", False), ("smoothed", True)):
        start = time.perf_counter()
        runs[name] = track_tags(sim.log, c, tags, units, use_height=use_height,
                                options=EkfOptions(smooth=smooth))
        runs[name + " us"] = (time.perf_counter() - start) / (len(tags) * len(truth.time)) * 1e6
    p_true = site_positions(truth.model, truth.q, [t.site for t in tags.values()])
    grouped = group_transmissions(sim.log, c.ids)
    fixes = locate(grouped.toa, c)
    rows = []
    in_window = (truth.time >= window[0]) & (truth.time < window[1])
    for j, (tag_id, tag) in enumerate(tags.items()):
        mine = sim.tx_tag == tag_id
        delayed = sim.nlos_delay[mine] > 0
        for name in ("filter", "smoothed"):
            track = runs[name][tag_id]
            err = np.linalg.norm(track.p_world_tag - p_true[:, j], axis=1)
            avail = float(np.isfinite(track.p_world_tag[:, 0]).mean())
            rows.append(_row(f"{label} {tag.site} {name}", err, in_window, avail,
                             _precision_recall(track.tx_rejected, delayed), runs[name + " us"]))
        sel = grouped.tag.astype(str) == tag_id
        fix_err = np.linalg.norm(fixes.p_world_tag[sel] - sim.p_world_tag[mine], axis=1)
        fix_err[~fixes.ok[sel]] = np.nan
        expected = (truth.time[-1] - truth.time[0]) * options.tx_rate
        fix_window = (grouped.time[sel] >= window[0]) & (grouped.time[sel] < window[1])
        rows.append(_row(f"{label} {tag.site} locate", fix_err, fix_window,
                         float(fixes.ok[sel].sum()) / expected,
                         _precision_recall(fixes.rejected[sel], delayed), None))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--rate", type=float, default=60.0, help="IMU rate [Hz]")
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    model = HumanModel.default()
    t0 = time.perf_counter()
    params = GaitParameters(path="circle", radius=1.5, duration=args.seconds, stand=2.0,
                            speed=1.1, step_length=0.6)
    truth = generate_gait(model, params, rate=args.rate)
    truth.q[:, 0] += 3.0
    truth.q[:, 1] += 2.5
    truth = smooth_truth(truth)
    print(f"walk: {args.seconds:.0f} s at {args.rate:.0f} Hz ({time.perf_counter() - t0:.0f} s "
          "to generate)")
    imus = simulate_imus(model, truth.time, truth.q, ["Head", "LeftFoot", "RightFoot"], rng)
    c = _constellation(rng)
    cases = [("clean", UwbCaptureOptions(), (0.0, np.inf), False),
             ("2 readers", UwbCaptureOptions(blockages=(Blockage(12.0, 17.0, ("R1", "R6")),)),
              (12.0, 17.0), True)]
    if args.seconds >= 35.0:
        cases.append(("no UWB", UwbCaptureOptions(no_coverage=((8.0, 28.0),)), (8.0, 28.0),
                      False))
    print(f"{'case':<34s} {'rms':>6s} {'p95':>6s} {'max in':>7s}  {'avail':>6s}  "
          f"{'prec':>5s} {'rec':>5s} {'us/smp':>8s}")
    print(f"{'':<34s} {'[cm]':>6s} {'[cm]':>6s} {'window':>7s}")
    for i, (label, options, window, use_height) in enumerate(cases):
        for row in _case(label, truth, imus, c, options, window, args.seed + i, use_height):
            print(row)


if __name__ == "__main__":
    main()
