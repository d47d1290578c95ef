"""The MVN real-time network streaming protocol (Xsens) over UDP: a :class:`PoseSink`.

What MVN Animate/Analyze sends to its live plugins (Unity, Unreal, MotionBuilder), as the
public "MVN real-time network streaming protocol specification" defines it. Every datagram is a
24-byte big-endian header and a payload:

====== ===== ==========================================================================
bytes  type  field
====== ===== ==========================================================================
0-5    char  ID string ``MXTP`` + two-digit message type (``MXTP02``)
6-9    u32   sample counter (our frame number; equal in every datagram of one frame)
10     u8    datagram counter: index of the datagram within the message, bit 7 set on
             the last one (a message in one datagram has ``0x80``)
11     u8    number of items in this datagram
12-15  u32   time code: milliseconds since the start of the capture
16     u8    character id (one per actor, 0, 1, ... in session order)
17     u8    number of body segments (23)
18     u8    number of props (0)
19     u8    number of finger tracking segments (0)
20-21  --    reserved (0)
22-23  u16   payload size of this datagram [bytes]
====== ===== ==========================================================================

Messages (payloads big-endian; a *string* is an i32 byte count then UTF-8 bytes, spec 2.5.12):

* ``MXTP02`` pose, quaternion: per segment i32 segment id, position x, y, z (f32) and
  orientation q1..q4 (f32, scalar first: ``R_world_segment`` as w, x, y, z), Z up,
  right-handed: our world frame (SPEC section 1), so nothing is converted. Positions are in
  metres: the spec's section 2.5.6 still says centimetres, but MVN sends metres in this message
  (MVN user manual, "position units are in meters") and Xsens' own receivers read metres.
* ``MXTP12`` character meta data: tag lines ``tag:value``, each ended by a newline: ``name``
  (the actor's name) and ``timeOffset`` (0; read by Xsens' Blender receiver).
* ``MXTP13`` scale information: i32 segment count, then per segment a string (name) and its
  origin with every segment orientation the identity (our N-pose; 3 f32, metres); i32 point
  count, then per point u16 segment id, u16 point id, a string (name), u32 characteristics (0)
  and the point relative to its segment origin (3 f32, metres). As the spec says, the first
  datagram holds the segments (point count 0) and the next ones the points (segment count 0),
  each datagram a whole payload. Our points are the joints' connection points on the parent
  segment (named like the joint, point ids 1, 2, ... per segment); a joint's child connection
  is point 0 of the child, its origin.
* ``MXTP20`` joint angles: per joint i32 parent connection point id (256 x segment id + point
  id), i32 child connection point id, then the rotation about the segment's x, y and z axes
  (3 f32, degrees, right-handed): our anatomical angles placed on their axes with their signs
  (``configs/joints.yaml``: e.g. ``jRightKnee_flex`` about y, ``-jRightKnee_abd`` about x).
* ``MXTP25`` time code: the string ``HH:MM:SS.mmm`` (capture time; sent with its i32 length as
  every protocol string, which is how Xsens' receivers read it).

Item messages (02, 20) larger than ``max_payload`` bytes are split between items over several
datagrams with the same sample counter (spec 2.4.1.3). For messages that are not lists of
items (12, 13, 25) the number of items is the number of segments (13: of segments + points in
that datagram). Meta data and scale are sent with an actor's first frame and then every
``meta_period_s`` seconds of capture time, so a receiver started later picks them up.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Mapping, Sequence

import numpy as np

from ..model.joints import SEGMENTS, JointSpec, load_joint_specs
from ..rotations import matrix_to_quat_wxyz
from .actor_pose import ActorPose

#: MVN segment ids (the protocol's numbering, Pelvis = 1 ... LeftToe = 23) by segment name.
MVN_SEGMENT_IDS: dict[str, int] = {name: i + 1 for i, name in enumerate(SEGMENTS)}

HEADER = struct.Struct(">6sIBBIBBBBHH")
POSE_ITEM = struct.Struct(">i3f4f")
JOINT_ITEM = struct.Struct(">ii3f")
LAST_DATAGRAM = 0x80
#: Default payload bound: a datagram stays under a 1500-byte Ethernet MTU.
MAX_PAYLOAD = 1400
DEFAULT_PORT = 9763
_AXES = {"x": 0, "y": 1, "z": 2}


def mvn_string(text: str) -> bytes:
    """A protocol string: i32 byte count, then the UTF-8 bytes."""
    raw = text.encode("utf-8")
    return struct.pack(">i", len(raw)) + raw


def time_code(time_s: float) -> str:
    """``HH:MM:SS.mmm`` of a capture time [s] (hours wrap at 24)."""
    ms = int(round(max(time_s, 0.0) * 1000.0))
    hours, rest = divmod(ms, 3_600_000)
    minutes, rest = divmod(rest, 60_000)
    seconds, millis = divmod(rest, 1000)
    return f"{hours % 24:02d}:{minutes:02d}:{seconds:02d}.{millis:03d}"


def null_pose_from(pose: ActorPose) -> np.ndarray:
    """Segment origins with every segment orientation the identity, from one solved pose.

    The offset of a segment's origin in its parent's frame is fixed by the skeleton; with
    identity orientations (our N-pose) the origins are those offsets chained from the pelvis.
    The pelvis is placed above the world origin with the lowest origin at z = 0.

    Returns:
        (S, 3) origins [m] in the order of ``pose.segments``.
    """
    p = np.zeros((len(pose.segments), 3))
    for i, parent in enumerate(pose.parents):
        if parent < 0:
            continue
        bone = pose.p_world_segment[i] - pose.p_world_segment[parent]
        p[i] = p[parent] + pose.R_world_segment[parent].T @ bone
    p[:, 2] -= p[:, 2].min()
    return p


def _chunks(items: Sequence[bytes], max_payload: int) -> list[list[bytes]]:
    """Items grouped so that each group's bytes fit in ``max_payload`` (at least one item)."""
    groups: list[list[bytes]] = [[]]
    size = 0
    for item in items:
        if groups[-1] and size + len(item) > max_payload:
            groups.append([])
            size = 0
        groups[-1].append(item)
        size += len(item)
    return groups


class MvnDatagrams:
    """Builds the datagrams of one actor's messages (no socket; see :class:`MvnStreamSink`).

    Args:
        max_payload: Largest payload of one datagram [bytes]; bigger item messages are split
            (the scale message's segment datagram, ~650 bytes for 23 segments, is one datagram
            whatever the bound, as the spec has it).
        joints: Joint definitions (parent, child, angle axes and signs); the shipped
            ``configs/joints.yaml`` by default.
    """

    def __init__(self, max_payload: int = MAX_PAYLOAD,
                 joints: Mapping[str, JointSpec] | None = None) -> None:
        if max_payload < POSE_ITEM.size:
            raise ValueError(f"max_payload must hold one pose item ({POSE_ITEM.size} bytes), "
                             f"got {max_payload}")
        self.max_payload = max_payload
        self.joints = dict(load_joint_specs() if joints is None else joints)
        self._points: dict[str, int] = {}
        for name, spec in self.joints.items():  # point ids 1, 2, ... on each parent segment
            self._points[name] = 1 + sum(s.parent == spec.parent for s in self.joints.values()
                                         if s.name in self._points)

    def _datagrams(self, kind: int, pose: ActorPose,
                   groups: Sequence[tuple[bytes, int]]) -> list[bytes]:
        """Header + payload for each (payload, number of items) part of one message."""
        out = []
        n_segments = min(len(pose.segments), 255)
        for k, (payload, n_items) in enumerate(groups):
            counter = (k & 0x7F) | (LAST_DATAGRAM if k == len(groups) - 1 else 0)
            header = HEADER.pack(f"MXTP{kind:02d}".encode("ascii"), pose.frame & 0xFFFFFFFF,
                                 counter, min(n_items, 255),
                                 int(round(pose.time_s * 1000.0)) & 0xFFFFFFFF,
                                 pose.character_id & 0xFF, n_segments, 0, 0, 0, len(payload))
            out.append(header + payload)
        return out

    def _items(self, kind: int, pose: ActorPose, items: Sequence[bytes]) -> list[bytes]:
        groups = _chunks(items, self.max_payload)
        return self._datagrams(kind, pose, [(b"".join(g), len(g)) for g in groups])

    def pose_quaternion(self, pose: ActorPose) -> list[bytes]:
        """``MXTP02``: every MVN segment's position [m] and orientation (w, x, y, z)."""
        quats = matrix_to_quat_wxyz(pose.R_world_segment)
        items = [POSE_ITEM.pack(MVN_SEGMENT_IDS[name], *pose.p_world_segment[i], *quats[i])
                 for i, name in enumerate(pose.segments) if name in MVN_SEGMENT_IDS]
        return self._items(2, pose, items)

    def meta_data(self, pose: ActorPose) -> list[bytes]:
        """``MXTP12``: the actor's name."""
        text = f"name:{pose.actor}\ntimeOffset:0\n"
        return self._datagrams(12, pose, [(text.encode("utf-8"), len(pose.segments))])

    def _present(self, pose: ActorPose) -> list[JointSpec]:
        """The joints whose parent and child segments the pose has."""
        names = set(pose.segments)
        return [s for s in self.joints.values()
                if s.parent in names and s.child in names and s.parent in MVN_SEGMENT_IDS
                and s.child in MVN_SEGMENT_IDS]

    def scale(self, pose: ActorPose, null_pose: np.ndarray) -> list[bytes]:
        """``MXTP13``: null-pose segment origins [m], then the joints' connection points."""
        index = {name: i for i, name in enumerate(pose.segments)}
        segments = b"".join(mvn_string(name) + struct.pack(">3f", *null_pose[i])
                            for i, name in enumerate(pose.segments))
        parts = [(struct.pack(">i", len(pose.segments)) + segments + struct.pack(">i", 0),
                  len(pose.segments))]
        points = []
        for spec in self._present(pose):
            offset = null_pose[index[spec.child]] - null_pose[index[spec.parent]]
            points.append(struct.pack(">HH", MVN_SEGMENT_IDS[spec.parent], self._points[spec.name])
                          + mvn_string(spec.name) + struct.pack(">I3f", 0, *offset))
        room = self.max_payload - 8  # the two counts
        for group in _chunks(points, room) if points else []:
            parts.append((struct.pack(">ii", 0, len(group)) + b"".join(group), len(group)))
        return self._datagrams(13, pose, parts)

    def joint_angles(self, pose: ActorPose) -> list[bytes]:
        """``MXTP20``: per joint the rotation [deg] about the segment's x, y and z axes."""
        column = {name: k for k, name in enumerate(pose.joint_names)}
        items = []
        for spec in self._present(pose):
            keys = [spec.column(a.name) for a in spec.angles]
            if not all(k in column for k in keys):
                continue
            about = [0.0, 0.0, 0.0]
            for a, key in zip(spec.angles, keys):
                about[_AXES[a.axis]] = a.sign * float(pose.joint_angles_deg[column[key]])
            parent_id = 256 * MVN_SEGMENT_IDS[spec.parent] + self._points[spec.name]
            child_id = 256 * MVN_SEGMENT_IDS[spec.child]
            items.append(JOINT_ITEM.pack(parent_id, child_id, *about))
        return self._items(20, pose, items) if items else []

    def time_code(self, pose: ActorPose) -> list[bytes]:
        """``MXTP25``: the capture time as ``HH:MM:SS.mmm``."""
        return self._datagrams(25, pose, [(mvn_string(time_code(pose.time_s)),
                                           len(pose.segments))])


class MvnStreamSink:
    """Sends every actor's pose as MVN network streaming datagrams over UDP.

    Per frame and actor: ``MXTP02`` (pose), ``MXTP20`` (joint angles) and ``MXTP25`` (time
    code); ``MXTP12`` (meta data) and ``MXTP13`` (scale) with the actor's first frame and then
    every ``meta_period_s`` of capture time.

    Args:
        host: Receiver host name or address.
        port: Receiver UDP port (MVN's default is 9763).
        meta_period_s: Capture time between two repeats of meta data and scale [s].
        max_payload: Largest payload of one datagram [bytes] (see :class:`MvnDatagrams`).
        null_pose: Segment name -> null-pose origin [m] (MXTP13); by default rebuilt from each
            actor's first pose (:func:`null_pose_from`).
    """

    def __init__(self, host: str, port: int = DEFAULT_PORT, meta_period_s: float = 1.0,
                 max_payload: int = MAX_PAYLOAD,
                 null_pose: dict[str, np.ndarray] | None = None) -> None:
        self.address = (host, port)
        self.meta_period_s = meta_period_s
        self.datagrams = MvnDatagrams(max_payload)
        self._null_pose = null_pose
        self._meta_sent_at: dict[int, float] = {}
        self._null_poses: dict[int, np.ndarray] = {}
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0

    def _null_pose_of(self, pose: ActorPose) -> np.ndarray:
        if pose.character_id not in self._null_poses:
            if self._null_pose is None:
                p = null_pose_from(pose)
            else:
                p = np.array([self._null_pose[name] for name in pose.segments], dtype=float)
            self._null_poses[pose.character_id] = p
        return self._null_poses[pose.character_id]

    def messages(self, pose: ActorPose) -> list[bytes]:
        """The datagrams this sink sends for one actor's frame, in sending order."""
        out: list[bytes] = []
        last = self._meta_sent_at.get(pose.character_id)
        if last is None or pose.time_s - last >= self.meta_period_s or pose.time_s < last:
            out += self.datagrams.meta_data(pose)
            out += self.datagrams.scale(pose, self._null_pose_of(pose))
            self._meta_sent_at[pose.character_id] = pose.time_s
        out += self.datagrams.pose_quaternion(pose)
        out += self.datagrams.joint_angles(pose)
        out += self.datagrams.time_code(pose)
        return out

    def send(self, poses: Sequence[ActorPose]) -> None:
        """Send the poses of one instant (one per actor)."""
        for pose in poses:
            for datagram in self.messages(pose):
                self._socket.sendto(datagram, self.address)
                self.sent += 1

    def close(self) -> None:
        """Close the socket."""
        self._socket.close()
