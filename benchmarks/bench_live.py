"""Latency of ``ikfusion live``: a sample's arrival to its pose datagram leaving.

A walk in circles with 17 sensors and three UWB tags in the 6 m x 8 m room of
``configs/constellations/room_6x8.yaml`` is simulated at each rate asked for, then replayed in
real time (``--replay``, speed 1) through the live pipeline in this process: frames assembled,
each actor solved causally, every pose packed into a UDP datagram sent to a local socket. The
latency of a frame is the time from the arrival of its first sample (the reader thread's time
stamp) to the return of ``sendto`` of its pose; the start-up buffer (the calibration seconds)
is not solved (as ``live`` does with a paced source), every later frame is counted.

Columns: latency p50, p99 and max [ms]; frames counted; frames dropped because the solver fell
behind (``latency_budget_s`` of ``configs/live.yaml``), and apart (``start``) those that arrived
while the start-up buffer was calibrated; frames released with a sensor missing
(``deadline``); CPU time of the loop's thread per frame, p50 and p99 [ms] (solve and outputs:
the latency on an idle machine, less the waiting); ``load``, the mean CPU time per sample
period over all actors (above 1 one core cannot keep up, whatever else runs). Wall-clock
figures depend on what else the machine runs: give its load average with them.

Cases: ``RATExACTORS``, e.g. ``60x1`` (one actor at 60 Hz), ``240x1``, ``60x4`` (four actors in
one process: a session whose actors replay the same capture, IMU only).

``--check`` also compares ``live --replay --speed 0`` with ``solve --causal`` (largest
difference of the joint angles) and the head 3-D RMS of the live and the offline ``solve``
results, on the demo capture (``ikfusion demo``'s 60 s walk, or ``--seconds``).

Run: .venv/bin/python benchmarks/bench_live.py [--cases 60x1,240x1,60x4] [--seconds 12]
     [--check] [--work DIR]
"""

from __future__ import annotations

import argparse
import os
import socket
import struct
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml

from ikfusion.app.demo import simulate_demo_capture
from ikfusion.app.evaluate import evaluate
from ikfusion.cli import main as cli
from ikfusion.live.actor_pose import ActorPose
from ikfusion.live.actor_stream import ActorStream
from ikfusion.live.frames import FrameAssembler
from ikfusion.live.kinematics import PoseKinematics
from ikfusion.live.replay import ReplaySource
from ikfusion.live.run import LiveActor, LiveLoop
from ikfusion.live.settings import LiveSettings
from ikfusion.live.setup import replay_setups
from ikfusion.paths import shipped_config

ROOM = shipped_config("constellations/room_6x8.yaml")


class DatagramSink:
    """Every pose as one UDP datagram (segment positions and quaternions) to a local socket."""

    def __init__(self) -> None:
        self.receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.receiver.bind(("127.0.0.1", 0))
        self.receiver.setblocking(False)
        self.address = self.receiver.getsockname()
        self.sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0

    def send(self, poses: Sequence[ActorPose]) -> None:
        for pose in poses:
            body = np.concatenate([pose.p_world_segment.ravel(),
                                   pose.R_world_segment.ravel()]).astype("<f4").tobytes()
            self.sender.sendto(struct.pack("<iif", pose.character_id, pose.frame,
                                           pose.time_s) + body, self.address)
            self.sent += 1
            try:  # keep the receive buffer from filling
                while True:
                    self.receiver.recv(65536)
            except BlockingIOError:
                pass

    def close(self) -> None:
        self.sender.close()
        self.receiver.close()


def capture(work: Path, rate: float, seconds: float) -> Path:
    """The simulated capture at ``rate`` (made once per work folder)."""
    folder = work / f"capture_{rate:g}hz_{seconds:g}s"
    if not (folder / "toa.csv").is_file():
        assert cli(["simulate", "--motion", "gait", "--seconds", str(seconds), "--rate",
                    str(rate), "--readers", str(ROOM), "--seed", "4", "--out", str(folder),
                    "--quiet", "--force"]) == 0
    return folder


def session(work: Path, folder: Path, actors: int) -> Path:
    """A session file whose ``actors`` actors replay the same capture (IMU only)."""
    path = work / f"session_{folder.name}_{actors}.yaml"
    path.write_text(yaml.safe_dump({"actors": {
        f"actor{i}": {"imu": str(folder / "imu"), "map": str(folder / "sensors.yaml"),
                      "body": str(folder / "body.yaml")} for i in range(actors)}}))
    return path


def run_case(work: Path, rate: float, actors: int, seconds: float) -> dict[str, float]:
    """Replay one case in real time; latency percentiles [ms] and frame counts."""
    folder = capture(work, rate, seconds)
    source = folder if actors == 1 else session(work, folder, actors)
    setups, toa = replay_setups(source, None, None, None, None)
    settings = LiveSettings.load()
    live = []
    for i, s in enumerate(setups):
        stream = ActorStream(s.model, s.sensor_map, s.rate, correction_for=s.uwb,
                             settings=settings, solve_startup=False)
        assembler = FrameAssembler(s.sensor_map, s.rate, settings.deadline_periods,
                                   settings.clock_jump_s, settings.deadline_periods / s.rate)
        live.append(LiveActor(s.name, i, stream, assembler, PoseKinematics(s.model)))
    sink = DatagramSink()
    loop = LiveLoop(live, [sink], paced=True, latency_budget_s=settings.latency_budget_s)
    streams = [s.samples(named=actors > 1) for s in setups]
    loop.run(ReplaySource([*streams, *([toa] if toa is not None else [])], speed=1.0))
    sink.close()
    latency = np.array([v for a in live for _, v in a.latency_s] or [np.nan]) * 1e3
    cpu = np.array([v for a in live for v in a.cpu_s] or [np.nan]) * 1e3
    return {"p50": float(np.percentile(latency, 50)), "p99": float(np.percentile(latency, 99)),
            "cpu_p50": float(np.percentile(cpu, 50)), "cpu_p99": float(np.percentile(cpu, 99)),
            "cpu_per_period": float(np.mean(cpu) * actors * rate / 1e3),
            "max": float(latency.max()), "steady": float(np.isfinite(latency).sum()),
            "solved": float(sum(a.frames for a in live)),
            "dropped": float(sum(a.dropped for a in live)),
            "startup": float(sum(a.dropped_startup for a in live)),
            "on_deadline": float(sum(a.assembler.counters.on_deadline for a in live))}


def check(work: Path, seconds: float) -> None:
    """Live replay vs ``solve --causal`` and the head RMS against offline ``solve``."""
    folder = work / f"demo_{seconds:g}s"
    if not (folder / "toa.csv").is_file():
        simulate_demo_capture(folder, seconds, 7, False, True)
    uwb = ["--toa", str(folder / "toa.csv"), "--readers", str(folder / "readers.yaml"),
           "--tags", str(folder / "tags.yaml")]
    base = ["solve", "--imu", str(folder / "imu"), "--map", str(folder / "sensors.yaml"),
            "--body", str(folder / "body.yaml"), *uwb, "--quiet", "--force"]
    live, causal, offline = work / "check_live", work / "check_causal", work / "check_offline"
    assert cli(["live", "--replay", str(folder), "--speed", "0", "--record", str(live),
                "--quiet", "--force"]) == 0
    assert cli([*base, "--causal", "--out", str(causal)]) == 0
    assert cli([*base, "--out", str(offline)]) == 0
    a = np.loadtxt(live / "joint_angles.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(causal / "joint_angles.csv", delimiter=",", skiprows=1)
    truth = folder / "truth.npz"
    heads = {name: evaluate(path, truth, align="none").head_position_rms_m
             for name, path in (("live", live), ("causal", causal), ("offline", offline))}
    print(f"demo capture {seconds:g} s: live vs solve --causal: {len(a)} / {len(b)} frames, "
          f"largest joint-angle difference {np.abs(a - b).max():.2e} deg")
    print("head 3-D RMS [m]: " + ", ".join(f"{k} {v:.4f}" for k, v in heads.items())
          + f"; live / offline = {heads['live'] / heads['offline']:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="60x1,240x1,60x4")
    parser.add_argument("--seconds", type=float, default=12.0,
                        help="capture length [s] (the first calibration_s calibrate)")
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--check-seconds", type=float, default=60.0)
    parser.add_argument("--work", type=Path, default=None)
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_live_"))
    work.mkdir(parents=True, exist_ok=True)
    print("machine load average (1, 5, 15 min): "
          + ", ".join(f"{v:.2f}" for v in os.getloadavg()))
    print(f"{'case':>8} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} {'frames':>7} "
          f"{'dropped':>8} {'start':>6} {'deadline':>8} {'cpu p50':>8} {'cpu p99':>8} "
          f"{'load':>5}")
    for case in args.cases.split(","):
        rate, actors = case.split("x")
        r = run_case(work, float(rate), int(actors), args.seconds)
        print(f"{case:>8} {r['p50']:8.2f} {r['p99']:8.2f} {r['max']:8.2f} "
              f"{int(r['steady']):7d} {int(r['dropped']):8d} {int(r['startup']):6d} "
              f"{int(r['on_deadline']):8d} "
              f"{r['cpu_p50']:8.2f} {r['cpu_p99']:8.2f} {r['cpu_per_period']:5.2f}")
    if args.check:
        check(work, args.check_seconds)


if __name__ == "__main__":
    main()
