"""Simulated versions of the seed paper's UWB experiments, printed next to the paper's numbers.

Run: ``.venv/bin/python benchmarks/bench_uwb_experiments.py [--seconds 30] [--seed 3]``.

One procedural walk (circles of 1.5 m radius after a 2 s N-pose, 60 Hz, 17 IMUs with the
default errors of ``ikfusion.sim.imu``) is generated once and reused:

(a) ``room``: its first ``--seconds`` s inside a 3 m x 3 m square of the 6 m x 8 m room of
    ``configs/constellations/room_6x8.yaml`` (10 readers on the border, random clock offsets).
(b) ``outside``: the whole walk (``--seconds`` s, ``--outside`` s "outside", ``--seconds`` s
    back). The generator only walks circles, so the actor stays in the room and "outside" is
    simulated as (1) no UWB reception at all during the stretch and (2) a heading drift of
    ``--drift`` deg/s of the IMUs' own fusion during the stretch, kept afterwards (the
    orientation error of a magnetically disturbed area). The drift is common to all sensors and
    written consistently: every reported orientation is rotated by ``Rz(theta(t))`` about the
    world vertical and every gyroscope sample gets the matching rate ``theta'(t)`` about the
    vertical (in the sensor frame), as a gyro bias the fusion did not remove would give.
    Accelerometers are untouched. Metrics are taken over the last ``--seconds`` s only.
(c) ``stage``: the first ``--seconds`` s near a corner (1-4 m from two edges) of a
    24 m x 10 m x 7 m stage: 8 readers on the ceiling (7 m) and 4 near the floor (0.3 m); the
    floor reader on the near short side stands behind a wall that blocks it 5 s out of every
    10 s.

Each capture is solved five times with ``ikfusion solve``: IMU only (evaluated after the
default start alignment), with UWB ``--correction slide`` and ``no-slide``, each with the tag
tracks smoothed over the recording (the default) and ``causal`` (evaluated as they are,
in the readers' frame). Columns: head (HeadTop) 3-D RMS [cm], joint-angle RMS [deg], foot slide
mean/max [mm] (``ikfusion.app.evaluate`` on the truth cut to the scored span), head RMS over every
frame of the capture (``head all``), the correction's remaining horizontal gap mean/max [cm]
(``summary.json``: ``uwb.gap_mean_m``, ``uwb.gap_max_m``, every frame), and the paper's head
error. The scored span of (a) and (c) starts at ``--skip`` s. The IMU-only start alignment is
always taken at the start of the capture.

(d) ``two actors``: the issue's acceptance: two people walking around each other for
``--pair-seconds`` s in the room (one session, ``ikfusion solve --session``); the RMS error of
their head-to-head distance [cm] and each head's RMS, per correction mode.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import Evaluation, evaluate
from ikfusion.cli import main as ikfusion_main
from ikfusion.mocap.model_motion import TruthMotion, site_positions
from ikfusion.paths import shipped_config
from ikfusion.sim.capture import add_heading_drift, truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.sim.session_capture import circling_pair, write_session_capture
from ikfusion.sim.uwb_capture import Blockage, UwbCaptureOptions
from ikfusion.uwb import load_constellation, make_constellation
from ikfusion.uwb.constellation import Constellation

#: Solves per capture: IMU only, the two corrections with smoothed tag tracks (the default for
#: recordings) and with causal ones (``--causal``: each instant from the past only, as live).
MODES = ("imu-only", "slide", "no-slide", "slide causal", "no-slide causal")


@dataclass(frozen=True)
class Experiment:
    """One capture and how to score it."""

    name: str
    truth: TruthMotion
    constellation: Constellation
    uwb: UwbCaptureOptions
    paper: dict[str, str]
    window: tuple[float, float]  # scored time span [s]
    drift: tuple[float, float, float] | None = None  # (start [s], end [s], rate [deg/s])


def _first_seconds(truth: TruthMotion, seconds: float) -> TruthMotion:
    """The first ``seconds`` of a truth motion."""
    n = int(np.searchsorted(truth.time, seconds - 1e-9))
    return TruthMotion(truth.model, truth.time[:n].copy(), truth.q[:n].copy(),
                       list(truth.contact_names), truth.contacts[:n].copy(), truth.source,
                       dict(truth.info))


def _shifted(truth: TruthMotion, dx: float, dy: float) -> TruthMotion:
    """The same motion moved horizontally by (dx, dy) [m]."""
    q = truth.q.copy()
    q[:, 0] += dx
    q[:, 1] += dy
    return TruthMotion(truth.model, truth.time.copy(), q, list(truth.contact_names),
                       truth.contacts.copy(), truth.source, dict(truth.info))


def _room(rng: np.random.Generator) -> Constellation:
    c = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    return make_constellation(c.positions, ids=c.ids, sigma=0.03, area=c.area, coverage=c.range,
                              clock_offsets=rng.uniform(-30.0, 30.0, len(c.readers)))


def _stage(rng: np.random.Generator) -> Constellation:
    """24 m x 10 m stage: 8 readers on the 7 m ceiling truss, 4 at 0.3 m mid-side."""
    ceiling = [[x, y, 7.0] for y in (0.0, 10.0) for x in (0.0, 8.0, 16.0, 24.0)]
    floor = [[12.0, 0.0, 0.3], [24.0, 5.0, 0.3], [12.0, 10.0, 0.3], [0.0, 5.0, 0.3]]
    return make_constellation(np.array(ceiling + floor), sigma=0.03, coverage=40.0,
                              area=[[0.0, 0.0], [24.0, 0.0], [24.0, 10.0], [0.0, 10.0]],
                              clock_offsets=rng.uniform(-30.0, 30.0, 12), name="stage_24x10")


def _wall(constellation: Constellation, reader: str, end: float) -> tuple[Blockage, ...]:
    """``reader`` blocked 5 s out of every 10 s (from t = 5 s), the others audible."""
    audible = tuple(r for r in constellation.ids if r != reader)
    return tuple(Blockage(t, t + 5.0, audible) for t in np.arange(5.0, end, 10.0))


def _solve(capture: Path, out: Path, mode: str) -> Path:
    args = ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml"), "--out", str(out), "--quiet"]
    if mode != "imu-only":
        args += ["--toa", str(capture / "toa.csv"), "--readers", str(capture / "readers.yaml"),
                 "--tags", str(capture / "tags.yaml"), "--correction", mode.split()[0]]
    if mode.endswith("causal"):
        args.append("--causal")
    with contextlib.redirect_stdout(io.StringIO()):
        code = ikfusion_main(args)
    if code != 0:
        raise RuntimeError(f"ikfusion solve ({mode}) failed with exit code {code}")
    return out


def _first_pelvis_xy(result: Path) -> np.ndarray:
    with (result / "segments.csv").open() as f:
        for row in csv.DictReader(f):
            if row["segment"] == "Pelvis":
                return np.array([float(row["px"]), float(row["py"])])
    raise RuntimeError(f"no Pelvis row in {result / 'segments.csv'}")


def _window_truth(truth_file: Path, out: Path, window: tuple[float, float],
                  shift_xy: np.ndarray) -> Path:
    """``truth.npz`` cut to ``window``, positions moved by ``-shift_xy`` (into the estimate's
    frame, so that ``evaluate(..., align="none")`` scores the window after a start alignment
    done at the start of the whole capture)."""
    data = dict(np.load(truth_file, allow_pickle=False))
    keep = (data["time"] >= window[0]) & (data["time"] <= window[1])
    n = keep.shape[0]
    cut = {k: (v[keep] if v.ndim >= 1 and v.shape[0] == n else v) for k, v in data.items()}
    for key in ("p_world_segment", "p_world_site"):
        cut[key] = cut[key].copy()
        cut[key][..., :2] -= shift_xy
    np.savez_compressed(out, **cut)
    return out


def _score(exp: Experiment, capture: Path, result: Path, mode: str, tmp: Path) -> Evaluation:
    truth_file = capture / "truth.npz"
    shift = np.zeros(2)
    if mode == "imu-only":  # what evaluate's default alignment does, at the capture's start
        truth = np.load(truth_file, allow_pickle=False)
        pelvis = [str(s) for s in truth["segment_names"]].index("Pelvis")
        shift = truth["p_world_segment"][0, pelvis, :2] - _first_pelvis_xy(result)
    window_file = _window_truth(truth_file, tmp / f"truth_{exp.name}_{mode}.npz", exp.window,
                                shift)
    return evaluate(result, window_file, align="none")


def _gap_cm(result: Path) -> tuple[float, float]:
    summary = json.loads((result / "summary.json").read_text())
    uwb = summary.get("uwb") or {}
    values = (uwb.get("gap_mean_m"), uwb.get("gap_max_m"))
    return tuple(np.nan if v is None else 100.0 * v for v in values)  # type: ignore[return-value]


def _row(name: str, mode: str, ev: Evaluation, head_all: float, gap: tuple[float, float],
         paper: str) -> str:
    gap_text = "      -       -" if mode == "imu-only" else f"{gap[0]:7.1f} {gap[1]:7.1f}"
    return (f"{name:<16s} {mode:<15s} {ev.head_position_rms_m * 100:7.1f} {head_all * 100:7.1f} "
            f"{ev.joint_angle_rms_deg:7.2f} {ev.foot_slide_mm:7.1f} {ev.foot_slide_max_mm:7.1f} "
            f"{gap_text}   {paper}")


def _run(exp: Experiment, seed: int, root: Path) -> list[str]:
    capture = root / exp.name / "capture"
    write_capture(capture, exp.truth, ImuNoise(), seed, constellation=exp.constellation,
                  uwb=exp.uwb)
    if exp.drift is not None:
        add_heading_drift(capture / "imu", *exp.drift)
    rows = []
    for mode in MODES:
        result = _solve(capture, root / exp.name / mode, mode)
        ev = _score(exp, capture, result, mode, root)
        whole = evaluate(result, capture / "truth.npz",
                         align="auto" if mode == "imu-only" else "none")
        gap = _gap_cm(result) if mode != "imu-only" else (np.nan, np.nan)
        rows.append(_row(exp.name, mode, ev, whole.head_position_rms_m, gap,
                         exp.paper[mode.split()[0]]))
    return rows


def two_actors(seconds: float, seed: int, root: Path) -> list[str]:
    """(d): head-to-head distance error of two actors circling each other, per mode."""
    truths = circling_pair(seconds, np.array([3.0, 4.0, 0.0]))
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    session = write_session_capture(root / "session", truths, room, ImuNoise(), seed)
    true = {n: site_positions(t.model, t.q, ["HeadTop"])[:, 0] for n, t in truths.items()}
    lines = [f"d two actors, {seconds:.0f} s   relative head distance RMS   each head RMS"]
    for mode in ("slide", "no-slide"):
        out = root / mode
        with contextlib.redirect_stdout(io.StringIO()):
            code = ikfusion_main(["solve", "--session", str(session), "--out", str(out),
                                  "--correction", mode, "--quiet"])
        if code != 0:
            raise RuntimeError(f"ikfusion solve --session ({mode}) failed with exit code {code}")
        heads = {n: _site_path(out / n, "HeadTop") for n in truths}
        n = min(len(v) for v in heads.values())
        d_est = np.linalg.norm(heads["alice"][:n] - heads["bob"][:n], axis=1)
        d_true = np.linalg.norm(true["alice"][:n] - true["bob"][:n], axis=1)
        each = "  ".join(f"{k} {100 * np.sqrt(np.mean(np.sum((v[:n] - true[k][:n]) ** 2, 1))):.1f}"
                         for k, v in heads.items())
        lines.append(f"  {mode:<9s} {100 * np.sqrt(np.mean((d_est - d_true) ** 2)):17.1f} cm"
                     f"   {each} cm   (issue: <= 5 cm)")
    return lines


def _site_path(result: Path, site: str) -> np.ndarray:
    """(N, 3) positions of a site from a result folder's ``sites.csv`` [m]."""
    with (result / "sites.csv").open() as f:
        return np.array([[float(r["x"]), float(r["y"]), float(r["z"])]
                         for r in csv.DictReader(f) if r["site"] == site])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="walk inside the readers' coverage [s] (a, c; twice in b)")
    parser.add_argument("--outside", type=float, default=20.0,
                        help="stretch without coverage in (b) [s]")
    parser.add_argument("--drift", type=float, default=1.0,
                        help="heading drift of the IMUs during that stretch [deg/s]")
    parser.add_argument("--rate", type=float, default=60.0, help="IMU rate [Hz]")
    parser.add_argument("--pair-seconds", type=float, default=60.0,
                        help="length of the two-actor session (d) [s]")
    parser.add_argument("--skip", type=float, default=0.0,
                        help="scored from this time on in (a) and (c) [s] (see the docstring)")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    if args.seconds <= 5.0 or args.outside <= 0.0:
        parser.error("--seconds must exceed 5 and --outside be positive")
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    total = 2.0 * args.seconds + args.outside
    print(f"generating a {total:.0f} s walk at {args.rate:.0f} Hz ...", flush=True)
    walk = truth_motion("gait", total, args.rate)
    print(f"  done in {time.perf_counter() - start:.0f} s", flush=True)
    in_room = _shifted(walk, 3.0, 2.5)  # circle spans x 1.5-4.5 m, y 2.5-5.5 m
    room = _room(rng)
    stage = _stage(rng)
    t_out, t_back = args.seconds, args.seconds + args.outside
    experiments = [
        Experiment("a room 3x3", _first_seconds(in_room, args.seconds), room,
                   UwbCaptureOptions(), window=(args.skip, args.seconds),
                   paper={"imu-only": "~10 cm", "slide": "~6.5 cm", "no-slide": "~6.5 cm"}),
        Experiment("b back inside", in_room, room,
                   UwbCaptureOptions(no_coverage=((t_out, t_back),)),
                   paper={"imu-only": "~77 cm", "slide": "~10 cm", "no-slide": "~10 cm"},
                   window=(t_back, walk.time[-1]), drift=(t_out, t_back, args.drift)),
        Experiment("c stage 24x10", _shifted(_first_seconds(walk, args.seconds), 2.5, 1.0),
                   stage, UwbCaptureOptions(blockages=_wall(stage, "R12", args.seconds)),
                   window=(args.skip, args.seconds),
                   paper={"imu-only": "-", "slide": "~7 cm", "no-slide": "~7 cm"}),
    ]
    header = (f"{'experiment':<16s} {'mode':<15s} {'head':>7s} {'head':>7s} {'joint':>7s} "
              f"{'slide':>7s} {'slide':>7s} {'gap':>7s} {'gap':>7s}   paper head")
    units = (f"{'':<16s} {'':<15s} {'RMS cm':>7s} {'all cm':>7s} {'RMS deg':>7s} {'mean mm':>7s} "
             f"{'max mm':>7s} {'mean cm':>7s} {'max cm':>7s}")
    lines = []
    with tempfile.TemporaryDirectory(prefix="bench_uwb_") as tmp:
        for exp in experiments:
            t0 = time.perf_counter()
            print(f"{exp.name}: {exp.truth.time[-1]:.0f} s, {len(exp.constellation.readers)} "
                  f"readers, {len(MODES)} solves ...", end=" ", flush=True)
            lines += _run(exp, args.seed, Path(tmp))
            print(f"{time.perf_counter() - t0:.0f} s", flush=True)
    print(header)
    print(units)
    for line in lines:
        print(line)
    print()
    with tempfile.TemporaryDirectory(prefix="bench_pair_") as tmp:
        for line in two_actors(args.pair_seconds, args.seed, Path(tmp)):
            print(line, flush=True)
    print(f"total {time.perf_counter() - start:.0f} s", flush=True)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
