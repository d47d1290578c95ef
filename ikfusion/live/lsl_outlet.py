"""A Lab Streaming Layer outlet per actor: a :class:`PoseSink`.

Stream ``ikfusion <actor>`` (type ``MoCap``, source id ``ikfusion-<actor>``, ``double64``,
nominal rate = the capture rate). One sample per frame; channels, in order:

* ``time`` [s]: the frame's capture time (the LSL timestamp is the sending time);
* per segment (model order): ``<Segment>_px, _py, _pz`` [m] (world frame, Z up) and
  ``<Segment>_qw, _qx, _qy, _qz`` (``R_world_segment``, scalar first);
* per joint-angle column: ``jRightKnee_flex`` ... [deg].

The stream's XML description holds ``<channels>`` (one ``<channel>`` with ``label``, ``unit``
and ``type`` each, the XDF mocap convention) and ``<skeleton>`` (each segment's ``name`` and
``parent``). Needs the ``live`` extra (``pylsl``; its wheels carry liblsl).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import InputError
from ..rotations import matrix_to_quat_wxyz
from .actor_pose import ActorPose


def require_pylsl(option: str) -> Any:
    """The ``pylsl`` module, or a clear error naming the missing package."""
    try:
        import pylsl
    except (ImportError, RuntimeError) as exc:  # RuntimeError: pylsl without liblsl
        raise InputError(f"Lab Streaming Layer needs the python package pylsl (with liblsl): "
                         f"pip install 'ikfusion[live]' ({exc})", field=option) from exc
    return pylsl


def lsl_channels(pose: ActorPose) -> list[tuple[str, str, str]]:
    """(label, unit, type) of every channel of an actor's stream."""
    out = [("time", "seconds", "Time")]
    for name in pose.segments:
        out += [(f"{name}_p{a}", "meters", f"Position{a.upper()}") for a in "xyz"]
        out += [(f"{name}_q{a}", "normalized", f"Orientation{k}")
                for a, k in zip("wxyz", "ABCD")]
    out += [(name, "degrees", "JointAngle") for name in pose.joint_names]
    return out


def lsl_values(pose: ActorPose) -> np.ndarray:
    """One sample of an actor's stream, in the order of :func:`lsl_channels`."""
    quats = matrix_to_quat_wxyz(pose.R_world_segment)
    per_segment = np.concatenate([pose.p_world_segment, quats], axis=1).ravel()
    return np.concatenate([[pose.time_s], per_segment, pose.joint_angles_deg])


class LslOutletSink:
    """Pushes every actor's frame to its own LSL outlet (created with the actor's first frame).

    Args:
        rate_hz: Nominal rate of the streams = the capture rate [Hz].
        name_prefix: Stream names are ``<name_prefix> <actor>``.
    """

    def __init__(self, rate_hz: float, name_prefix: str = "ikfusion") -> None:
        self._lsl = require_pylsl("--lsl-out")
        self.rate_hz = rate_hz
        self.name_prefix = name_prefix
        self._outlets: dict[str, Any] = {}

    def _outlet(self, pose: ActorPose) -> Any:
        if pose.actor not in self._outlets:
            lsl = self._lsl
            channels = lsl_channels(pose)
            info = lsl.StreamInfo(f"{self.name_prefix} {pose.actor}", "MoCap", len(channels),
                                  self.rate_hz, "double64", f"{self.name_prefix}-{pose.actor}")
            desc = info.desc()
            desc.append_child_value("actor", pose.actor)
            desc.append_child_value("character_id", str(pose.character_id))
            xml = desc.append_child("channels")
            for label, unit, kind in channels:
                ch = xml.append_child("channel")
                ch.append_child_value("label", label)
                ch.append_child_value("unit", unit)
                ch.append_child_value("type", kind)
            skeleton = desc.append_child("skeleton")
            for name, parent in zip(pose.segments, pose.parents):
                seg = skeleton.append_child("segment")
                seg.append_child_value("name", name)
                seg.append_child_value("parent", "" if parent < 0 else pose.segments[parent])
            self._outlets[pose.actor] = lsl.StreamOutlet(info)
        return self._outlets[pose.actor]

    def send(self, poses: Sequence[ActorPose]) -> None:
        """Push the poses of one instant (one sample per actor)."""
        for pose in poses:
            self._outlet(pose).push_sample(lsl_values(pose).tolist())

    def close(self) -> None:
        """Close the outlets."""
        self._outlets.clear()
