"""Simulated captures (most in the shipped UWB room) and their solves, shared by the tests."""

from __future__ import annotations

import contextlib
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import Evaluation, evaluate, joint_angle_jump
from ikfusion.cli import main
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.paths import shipped_config
from ikfusion.sim.area_fit import DEFAULT_MARGIN, place_in_area
from ikfusion.sim.capture import truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation
from ikfusion.uwb.dop import capture_area


def room_walk(folder: Path, seconds: float, seed: int) -> Path:
    """A generated walk of ``seconds`` [s] at 60 Hz with the default sensor errors, placed in
    the middle of ``room_6x8`` (the 1.5 m circle moved by (3.0, 2.5) m), written to ``folder``.
    """
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    truth = truth_motion("gait", seconds, 60.0)
    truth.q[:, :2] += [3.0, 2.5]
    write_capture(folder, truth, ImuNoise(), seed, constellation=room)
    return folder


def room_capture(truth: TruthMotion, folder: Path) -> Path:
    """``truth`` placed in ``room_6x8``'s capture area (as the motion benchmark places a clip)
    and written to ``folder`` with the default sensor errors, seed 1."""
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    truth, _ = place_in_area(truth, capture_area(room), DEFAULT_MARGIN)
    write_capture(folder, truth, ImuNoise(), 1, constellation=room)
    return folder


def room_clip_solved(clip: Path, seconds: float, folder: Path, correction: str,
                     causal: bool = False) -> tuple[Path, Path]:
    """The first ``seconds`` [s] of a BVH ``clip`` (lead-in included, as the motion benchmark
    builds it) at 60 Hz with the default sensor errors (seed 1), placed in ``room_6x8`` and
    written to ``folder/capture``, then solved with UWB and ``correction`` (``causal``: tag
    tracks from the past only, ``--causal``) into ``folder/<correction>``.

    Returns:
        The capture folder and the solve's output folder.
    """
    whole = truth_motion(str(clip), seconds, 60.0)
    n = int(seconds * 60.0) + 1
    truth = TruthMotion(whole.model, whole.time[:n].copy(), whole.q[:n].copy(),
                        list(whole.contact_names), whole.contacts[:n].copy(), whole.source,
                        dict(whole.info))
    capture = room_capture(truth, folder / "capture")
    out = folder / correction
    assert main(["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
                 "--body", str(capture / "body.yaml"), "--toa", str(capture / "toa.csv"),
                 "--readers", str(capture / "readers.yaml"), "--tags",
                 str(capture / "tags.yaml"), "--correction", correction, "--out", str(out),
                 "--quiet", *(["--causal"] if causal else [])]) == 0
    return capture, out


def solved_scored(capture: Path, out: Path, *options: str) -> Evaluation:
    """The capture in folder ``capture`` solved IMU-only (plus ``options``) into ``out``, quietly,
    and scored against its truth."""
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
                     "--body", str(capture / "body.yaml"), "--out", str(out), "--quiet",
                     *options])
    assert code == 0
    return evaluate(out, capture / "truth.npz")


def joint_error_jump(capture: Path, out: Path, joints: Sequence[str] | None = None,
                     start: float = 0.0) -> tuple[float, str]:
    """The largest one-frame change of a joint's error against the truth of ``capture``, of
    the solve in ``out`` (``evaluate``'s measure, toes left out) [deg], and where.

    Args:
        capture: The capture folder (its ``truth.npz``).
        out: The solve's output folder (its ``joint_angles.csv``).
        joints: Only these joints (``"jLeftAnkle"``...; None: all).
        start: From this time on [s].
    """
    truth = np.load(capture / "truth.npz")
    names = [str(n) for n in truth["joint_angle_names"]]
    columns = [n for n in names if joints is None or n.rsplit("_", 1)[0] in joints]
    lines = (out / "joint_angles.csv").read_text().splitlines()
    header = lines[0].split(",")
    solved = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    time = truth["time"]
    estimated = np.stack([np.interp(time, solved[:, 0], solved[:, header.index(c)])
                          for c in columns], axis=1)
    true = truth["joint_angles"][:, [names.index(c) for c in columns]]
    window = time >= start
    return joint_angle_jump(time[window], estimated[window], true[window], columns)
