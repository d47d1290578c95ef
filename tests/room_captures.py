"""Simulated captures (most in the shipped UWB room) and their solves, shared by the tests."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

from ikfusion.app.evaluate import Evaluation, evaluate
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


def room_clip_solved(clip: Path, seconds: float, folder: Path, correction: str
                     ) -> tuple[Path, Path]:
    """The first ``seconds`` [s] of a BVH ``clip`` (lead-in included, as the motion benchmark
    builds it) at 60 Hz with the default sensor errors (seed 1), placed in ``room_6x8`` and
    written to ``folder/capture``, then solved with UWB and ``correction`` into
    ``folder/<correction>``.

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
                 "--quiet"]) == 0
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
