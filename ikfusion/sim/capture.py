"""A simulated capture in the real input formats (``ikfusion simulate``, SPEC section 5).

Writes ``imu/`` (MT Manager files, one per sensor, trial prefix ``SIM_``), ``sensors.yaml``
(the sensor map), ``body.yaml``, ``truth.npz`` and, with a constellation, the UWB files
(``readers.yaml``; TOA simulation comes with the UWB filter). Sensors are strapped with random
mountings; the motion starts with a still N-pose, as a real session does
(:mod:`ikfusion.sim.lead_in`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..atomic import atomic_folder
from ..errors import InputError
from ..io.mtmanager import read_mtmanager
from ..io.mtmanager_writer import write_mtmanager
from ..mocap.from_bvh import motion_from_bvh
from ..mocap.model_motion import TruthMotion
from ..model import SENSOR_SEGMENTS
from ..rotations import axis_rotation
from ..uwb.constellation import Constellation
from .gait import gait_preset, generate_gait
from .imu import ImuNoise, simulate_imus
from .lead_in import lead_in
from .truth import write_truth
from .uwb_capture import UwbCaptureOptions, simulate_uwb, smooth_truth, write_uwb_files

#: Trial prefix of simulated MT Manager files.
PREFIX = "SIM_"


@dataclass
class Capture:
    """Where a simulated capture was written."""

    folder: Path
    truth: TruthMotion

    @property
    def imu(self) -> Path:
        """The MT Manager trial prefix."""
        return self.folder / "imu" / PREFIX

    @property
    def sensor_map(self) -> Path:
        """The sensor map."""
        return self.folder / "sensors.yaml"

    @property
    def has_uwb(self) -> bool:
        """Whether UWB files were simulated (``toa.csv``, ``readers.yaml``, ``tags.yaml``)."""
        return (self.folder / "toa.csv").is_file()


def sensor_ids(segments: list[str]) -> dict[str, str]:
    """Stable fake Xsens ids per segment (``00B5xxxx``)."""
    return {s: f"00B5{i + 1:04X}" for i, s in enumerate(segments)}


def truth_motion(motion: str, seconds: float, rate: float, progress: bool = False) -> TruthMotion:
    """The truth of ``"gait"`` (circles), ``"gait:<walk>"`` or a BVH path (``.bvh``, ``.bvh.gz``).

    ``<walk>`` names a walk of :data:`ikfusion.sim.gait.GAIT_PRESETS` (``straight``, ``turns``,
    ``slow``, ``fast``, ``backwards``, ``sidestep``, ``turn-on-spot``, ``start-stop``, ``hop``,
    ``skip``, ``jump``, ...).
    Walks start with a 2 s N-pose; a BVH clip gets a 2 s N-pose and a way into its first frame
    (:func:`ikfusion.sim.lead_in.lead_in`: a step, or getting down onto a first pose that is
    not upright).

    Raises:
        InputError: An unknown walk name (the message lists the known ones).
    """
    if motion == "gait" or motion.startswith("gait:"):
        name = motion.split(":", 1)[1] if ":" in motion else "circle"
        try:
            params = gait_preset(name, seconds)
        except ValueError as err:
            raise InputError(str(err), field="motion") from None
        from ..model import HumanModel

        return generate_gait(HumanModel.default(), params, rate=rate, progress=progress)
    return lead_in(motion_from_bvh(motion, rate=rate, progress=progress))


def write_capture(folder: str | Path, truth: TruthMotion, noise: ImuNoise | None, seed: int,
                  segments: list[str] | None = None,
                  constellation: Constellation | None = None,
                  uwb: UwbCaptureOptions | None = None, force: bool = False) -> Capture:
    """Simulate the sensors on ``truth`` and write the capture folder atomically.

    With a ``constellation``, tags on HeadTop, LeftFootTop and RightFootTop are simulated too
    (``toa.csv``, ``readers.yaml``, ``tags.yaml``); the truth is then low-pass filtered first
    (:func:`ikfusion.sim.uwb_capture.smooth_truth`), so that its accelerations, which the
    inertial part of the UWB filter integrates, carry no frame-to-frame IK jitter. An existing
    ``folder`` is replaced only when ikfusion wrote it, or with ``force``.
    """
    segs = list(segments or SENSOR_SEGMENTS)
    rng = np.random.default_rng(seed)
    if constellation is not None:
        truth = smooth_truth(truth)
    imus = simulate_imus(truth.model, truth.time, truth.q, segs, rng, noise)
    ids = sensor_ids(segs)
    counter = 1000 + np.arange(len(truth.time))
    with atomic_folder(folder, "simulate", force) as tmp:
        for i, segment in enumerate(segs):
            write_mtmanager(tmp / "imu", PREFIX, ids[segment], counter, imus.R_world_sensor[i],
                            truth.rate, acc=imus.acc[i], gyr=imus.gyr[i])
        (tmp / "sensors.yaml").write_text(yaml.safe_dump(
            {"sensors": {ids[s]: s for s in segs}}, sort_keys=False))
        body = truth.model.body.to_dict() if truth.model.body is not None else {}
        (tmp / "body.yaml").write_text(yaml.safe_dump(
            {k: round(float(v), 4) for k, v in body.items()}, sort_keys=False))
        write_truth(tmp / "truth.npz", truth)
        if constellation is not None:
            write_uwb_files(tmp, simulate_uwb(truth, constellation, rng, uwb))
    return Capture(Path(folder), truth)


def add_heading_drift(imu_folder: str | Path, start: float, end: float,
                      deg_per_s: float) -> None:
    """Rewrite a capture's MT Manager files with a heading drift of the IMUs' own fusion.

    The drift grows in [``start``, ``end``) [s], as in a magnetically disturbed area:
    ``theta(t)`` grows at ``deg_per_s`` inside the window and keeps its final value after it.
    Reported orientations become ``Rz(theta) R_world_sensor``; gyroscopes get the rate that
    makes them consistent, ``theta'(t) R_world_sensor^T e_z`` (sensor frame) [rad/s].
    """
    recording = read_mtmanager(imu_folder)
    t = recording.time
    rate = np.radians(deg_per_s) * ((t >= start) & (t < end))
    theta = np.radians(deg_per_s) * np.clip(t - start, 0.0, end - start)
    R_drift = axis_rotation("z", theta)
    for sensor_id, stream in recording.sensors.items():
        if stream.acc is None or stream.gyr is None or stream.packet_counter is None:
            raise InputError("simulated files hold acc, gyr and PacketCounter; this one "
                             "does not", path=imu_folder, field=sensor_id)
        R = R_drift @ stream.R_world_sensor
        gyr = stream.gyr + rate[:, None] * R[:, 2, :]  # R^T e_z is the third row of R
        write_mtmanager(imu_folder, PREFIX, sensor_id, stream.packet_counter, R, recording.rate,
                        acc=stream.acc, gyr=gyr)
