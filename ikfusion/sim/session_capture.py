"""A simulated session: several actors in one hall, heard by one constellation.

Each actor gets its own capture folder (``<name>/imu``, ``sensors.yaml``, ``body.yaml``,
``truth.npz``) as :func:`ikfusion.sim.capture.write_capture` writes it; their tags (head and both
feet, ids ``<name>-T1..T3``) transmit into one TOA log on the shared timeline, and
``session.yaml`` names it all for ``ikfusion solve --session`` (see :mod:`ikfusion.app.session`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import yaml

from ..atomic import atomic_folder
from ..errors import InputError
from ..mocap.model_motion import TruthMotion, moved_configurations
from ..model import Body, HumanModel
from ..output_folders import folder_name_problem
from ..rotations import axis_rotation
from ..uwb.constellation import Constellation, save_constellation
from ..uwb.toa_log import ToaLog, write_toa_csv
from ..uwb.tracking import TagInfo, save_tags
from .capture import write_capture
from .gait import GaitParameters, generate_gait
from .imu import ImuNoise
from .uwb_capture import UwbCaptureOptions, default_tags, simulate_uwb, smooth_truth


def circling_pair(seconds: float, centre: np.ndarray, radius: float = 1.5,
                  rate: float = 60.0) -> dict[str, TruthMotion]:
    """Two people walking around each other, always on opposite sides of one circle.

    ``alice`` (1.70 m) and ``bob`` (1.85 m) on a circle of ``radius`` [m] about ``centre``
    (3,) [m].
    """
    out = {}
    for name, height, turn in (("alice", 1.70, 0.0), ("bob", 1.85, np.pi)):
        walk = GaitParameters(path="circle", radius=radius, duration=seconds, stand=2.0,
                              speed=1.0, step_length=0.6)
        truth = generate_gait(HumanModel.from_body(Body.from_height(height)), walk, rate=rate)
        R = axis_rotation("z", turn)
        # the generator's circle turns left about (0, radius): move that point to the centre
        truth.q = moved_configurations(truth.q, R, centre - R @ np.array([0.0, radius, 0.0]))
        out[name] = truth
    return out


def actor_tags(actor: str) -> dict[str, TagInfo]:
    """The head and feet tags of one actor, ids ``<actor>-T1..T3``."""
    return {f"{actor}-{tid}": TagInfo(f"{actor}-{tid}", actor, tag.site)
            for tid, tag in default_tags(actor).items()}


def write_session_capture(folder: str | Path, truths: Mapping[str, TruthMotion],
                          constellation: Constellation, noise: ImuNoise | None, seed: int,
                          uwb: UwbCaptureOptions | None = None, force: bool = False) -> Path:
    """Simulate every actor's sensors and tags; write the session folder atomically.

    Args:
        folder: The session folder.
        truths: Actor name -> its motion (all on one timeline, in the readers' frame).
        constellation: The readers.
        noise: IMU errors (None: perfect sensors).
        seed: Random seed.
        uwb: UWB simulation settings.
        force: Replace ``folder`` even when ikfusion did not write it.

    Returns:
        The path of ``session.yaml``.
    """
    rng = np.random.default_rng(seed)
    logs: list[ToaLog] = []
    tags: dict[str, TagInfo] = {}
    actors = {}
    for name in truths:
        problem = folder_name_problem(name)
        if problem is not None:
            raise InputError(f"actor name {name!r} cannot name a folder: {problem}",
                             field="actors")
    with atomic_folder(folder, "simulate", force) as tmp:
        for k, (name, truth) in enumerate(truths.items()):
            smooth = smooth_truth(truth)  # as write_capture does for a capture with tags
            write_capture(tmp / name, smooth, noise, seed + 1 + k)
            sim = simulate_uwb(smooth, constellation, rng, uwb, tags=actor_tags(name))
            logs.append(sim.log)
            tags.update(sim.tags)
            actors[name] = {"imu": f"{name}/imu", "map": f"{name}/sensors.yaml",
                            "body": f"{name}/body.yaml"}
        write_toa_csv(tmp / "toa.csv", _merged(logs))
        save_constellation(constellation, tmp / "readers.yaml")
        save_tags(tags, tmp / "tags.yaml")
        (tmp / "session.yaml").write_text(yaml.safe_dump(
            {"toa": "toa.csv", "readers": "readers.yaml", "tags": "tags.yaml",
             "correction": "no-slide", "actors": actors}, sort_keys=False))
    return Path(folder) / "session.yaml"


def _merged(logs: list[ToaLog]) -> ToaLog:
    """One log of every reception, in time order."""
    def joined(name: str) -> np.ndarray:
        return np.concatenate([getattr(log, name) for log in logs])

    order = np.argsort(joined("time"), kind="stable")
    return ToaLog(time=joined("time")[order], tag=joined("tag")[order], seq=joined("seq")[order],
                  reader=joined("reader")[order], toa=joined("toa")[order],
                  line=np.zeros(len(order), dtype=np.int64))
