"""Simulated captures in the shipped UWB room, shared by the correction tests."""

from __future__ import annotations

from pathlib import Path

from ikfusion.paths import shipped_config
from ikfusion.sim.capture import truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation


def room_walk(folder: Path, seconds: float, seed: int) -> Path:
    """A generated walk of ``seconds`` [s] at 60 Hz with the default sensor errors, placed in
    the middle of ``room_6x8`` (the 1.5 m circle moved by (3.0, 2.5) m), written to ``folder``.
    """
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    truth = truth_motion("gait", seconds, 60.0)
    truth.q[:, :2] += [3.0, 2.5]
    write_capture(folder, truth, ImuNoise(), seed, constellation=room)
    return folder
