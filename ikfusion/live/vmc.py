"""The VMC protocol (Virtual Motion Capture) over OSC/UDP: a :class:`PoseSink`.

Per frame, one OSC bundle with:

* ``/VMC/Ext/OK 1`` (a model is loaded) and ``/VMC/Ext/T <time>`` (capture time [s]);
* ``/VMC/Ext/Root/Pos "root" px py pz qx qy qz qw``: the avatar root, kept at the origin with
  no rotation (the hips carry the body's position and heading);
* ``/VMC/Ext/Bone/Pos <HumanBodyBones name> px py pz qx qy qz qw`` per mapped segment: the
  bone's *local* position [m] and rotation in its parent bone (``Hips``: in the root).

Frames: Unity's left-handed, Y-up frame (x right, y up, z forward). Ours is right-handed, Z up,
X forward, Y left, so a vector maps as ``(x_u, y_u, z_u) = (-y, z, x)`` and a rotation as
``M R M^T`` with that matrix ``M``. Rotations are relative to the T-pose of a normalised
humanoid (every bone's rotation the identity in the T-pose, as VRM/UniVRM models and VMC
receivers expect): our segment frames are the identity in the N-pose (arms down), so the arm
segments are turned by 90 deg about the forward axis (right arm ``Rx(-90 deg)``, left arm
``Rx(+90 deg)``) between the two rest poses.

Segment -> HumanBodyBones: Pelvis -> Hips, L5 -> Spine, T12 -> Chest, T8 -> UpperChest (L3 has
no Unity bone: its rotation is carried by Chest), Neck -> Neck, Head -> Head,
<Side>Shoulder -> <Side>Shoulder, <Side>UpperArm -> <Side>UpperArm, <Side>ForeArm ->
<Side>LowerArm, <Side>Hand -> <Side>Hand, <Side>UpperLeg -> <Side>UpperLeg, <Side>LowerLeg ->
<Side>LowerLeg, <Side>Foot -> <Side>Foot, <Side>Toe -> <Side>Toes. A bone's parent is the
nearest mapped segment up our tree. Needs the ``live`` extra (``python-osc``).
"""

from __future__ import annotations

import socket
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..rotations import axis_rotation, matrix_to_quat_wxyz
from .actor_pose import ActorPose

if TYPE_CHECKING:
    from pythonosc.osc_message import OscMessage

#: Our segment -> Unity HumanBodyBones name.
UNITY_BONES: dict[str, str] = {
    "Pelvis": "Hips", "L5": "Spine", "T12": "Chest", "T8": "UpperChest",
    "Neck": "Neck", "Head": "Head",
    **{f"{side}{ours}": f"{side}{unity}" for side in ("Left", "Right")
       for ours, unity in (("Shoulder", "Shoulder"), ("UpperArm", "UpperArm"),
                           ("ForeArm", "LowerArm"), ("Hand", "Hand"),
                           ("UpperLeg", "UpperLeg"), ("LowerLeg", "LowerLeg"),
                           ("Foot", "Foot"), ("Toe", "Toes"))},
}
#: ``v_unity = M_UNITY_OURS @ v_ours``: x right = -y left, y up = z up, z forward = x forward.
M_UNITY_OURS = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
DEFAULT_PORT = 39539


def npose_to_tpose(segment: str) -> np.ndarray:
    """Rotation (world frame, ours) from a segment's N-pose frame to its T-pose frame."""
    if segment.startswith("Right") and segment[5:] in ("UpperArm", "ForeArm", "Hand"):
        return axis_rotation("x", -np.pi / 2)
    if segment.startswith("Left") and segment[4:] in ("UpperArm", "ForeArm", "Hand"):
        return axis_rotation("x", np.pi / 2)
    return np.eye(3)


def bone_parents(pose: ActorPose) -> dict[str, str | None]:
    """Mapped segment -> its nearest mapped ancestor (None for the root)."""
    out: dict[str, str | None] = {}
    for i, name in enumerate(pose.segments):
        if name not in UNITY_BONES:
            continue
        parent = pose.parents[i]
        while parent >= 0 and pose.segments[parent] not in UNITY_BONES:
            parent = pose.parents[parent]
        out[name] = None if parent < 0 else pose.segments[parent]
    return out


def unity_bones(pose: ActorPose) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(HumanBodyBones name, local position [m], local rotation x, y, z, w) in Unity's frame.

    The bone's world rotation (ours) is ``R_world_segment @ npose_to_tpose(segment)^T``, so a
    segment in the N-pose gives a T-pose bone turned back to the N-pose.
    """
    index = {name: i for i, name in enumerate(pose.segments)}
    R_bone = {name: pose.R_world_segment[index[name]] @ npose_to_tpose(name).T
              for name in UNITY_BONES if name in index}
    out = []
    for name, parent in bone_parents(pose).items():
        p = pose.p_world_segment[index[name]]
        R = R_bone[name]
        if parent is not None:
            p = R_bone[parent].T @ (p - pose.p_world_segment[index[parent]])
            R = R_bone[parent].T @ R
        R_u = M_UNITY_OURS @ R @ M_UNITY_OURS.T
        w, x, y, z = matrix_to_quat_wxyz(R_u)
        out.append((UNITY_BONES[name], M_UNITY_OURS @ p, np.array([x, y, z, w])))
    return out


def _require_python_osc() -> None:
    """Raise a clear error when the optional ``python-osc`` package is missing."""
    try:
        import pythonosc  # noqa: F401
    except ImportError as exc:
        raise InputError("VMC output needs the python package python-osc: "
                         "pip install 'ikfusion[live]'", field="--vmc") from exc


def _message(address: str, *args: str | int | float) -> OscMessage:
    """One OSC message; Python floats are sent as OSC float32."""
    from pythonosc.osc_message_builder import OscMessageBuilder

    builder = OscMessageBuilder(address=address)
    for arg in args:
        kind = "s" if isinstance(arg, str) else "i" if isinstance(arg, int) else "f"
        builder.add_arg(arg, kind)
    return builder.build()


def vmc_bundle(pose: ActorPose) -> bytes:
    """The OSC bundle of one actor's frame, as sent (OK, T, Root/Pos, Bone/Pos per bone)."""
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder

    bundle = OscBundleBuilder(IMMEDIATELY)
    bundle.add_content(_message("/VMC/Ext/OK", 1))
    bundle.add_content(_message("/VMC/Ext/T", float(pose.time_s)))
    bundle.add_content(_message("/VMC/Ext/Root/Pos", "root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
    for name, p, q in unity_bones(pose):
        bundle.add_content(_message("/VMC/Ext/Bone/Pos", name, *map(float, p), *map(float, q)))
    return bundle.build().dgram


class VmcSink:
    """Sends every frame as one VMC bundle over OSC/UDP.

    VMC has no actor id: with several actors, give each its own sink (port) via ``actor``.

    Args:
        host: Receiver host name or address.
        port: Receiver UDP port (VMC's default is 39539).
        actor: Only this actor's poses are sent; None: the first pose of each instant.
    """

    def __init__(self, host: str, port: int = DEFAULT_PORT, actor: str | None = None) -> None:
        _require_python_osc()
        self.address = (host, port)
        self.actor = actor
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0

    def send(self, poses: Sequence[ActorPose]) -> None:
        """Send the chosen actor's pose of one instant."""
        chosen = [p for p in poses if self.actor is None or p.actor == self.actor][:1]
        for pose in chosen:
            self._socket.sendto(vmc_bundle(pose), self.address)
            self.sent += 1

    def close(self) -> None:
        """Close the socket."""
        self._socket.close()
