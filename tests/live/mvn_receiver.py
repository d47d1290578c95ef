"""A receiver of the MVN real-time network streaming protocol, written from the specification.

Independent of ikfusion's encoder on purpose (it imports nothing from ikfusion): it reads the
24-byte big-endian header field by field, joins split messages (datagram counter, bit 7 = last)
and decodes MXTP02, MXTP12, MXTP13, MXTP20 and MXTP25 payloads.
"""

from __future__ import annotations

import socket
import struct
from dataclasses import dataclass, field
from typing import Any

#: The protocol's segment numbering (specification, "segment IDs").
SPEC_SEGMENT_IDS = {
    1: "Pelvis", 2: "L5", 3: "L3", 4: "T12", 5: "T8", 6: "Neck", 7: "Head",
    8: "RightShoulder", 9: "RightUpperArm", 10: "RightForeArm", 11: "RightHand",
    12: "LeftShoulder", 13: "LeftUpperArm", 14: "LeftForeArm", 15: "LeftHand",
    16: "RightUpperLeg", 17: "RightLowerLeg", 18: "RightFoot", 19: "RightToe",
    20: "LeftUpperLeg", 21: "LeftLowerLeg", 22: "LeftFoot", 23: "LeftToe",
}


@dataclass
class Header:
    message_type: str
    sample_counter: int
    datagram_index: int
    is_last: bool
    items: int
    time_code_ms: int
    character_id: int
    body_segments: int
    props: int
    fingers: int
    payload_size: int


def read_header(data: bytes) -> Header:
    ident = data[0:6].decode("ascii")
    if not ident.startswith("MXTP"):
        raise ValueError(f"not an MVN datagram: {ident!r}")
    (sample,) = struct.unpack(">I", data[6:10])
    counter = data[10]
    items = data[11]
    (tc,) = struct.unpack(">I", data[12:16])
    (payload_size,) = struct.unpack(">H", data[22:24])
    return Header(ident[4:], sample, counter & 0x7F, bool(counter & 0x80), items, tc, data[16],
                  data[17], data[18], data[19], payload_size)


def _string(buf: bytes, at: int) -> tuple[str, int]:
    (n,) = struct.unpack_from(">i", buf, at)
    return buf[at + 4:at + 4 + n].decode("utf-8"), at + 4 + n


def decode_pose(payload: bytes) -> dict[str, tuple[tuple[float, ...], tuple[float, ...]]]:
    """Segment name -> (position [m], quaternion w, x, y, z)."""
    out = {}
    for at in range(0, len(payload), 32):
        seg_id, *values = struct.unpack(">i7f", payload[at:at + 32])
        out[SPEC_SEGMENT_IDS[seg_id]] = (tuple(values[:3]), tuple(values[3:]))
    return out


def decode_meta(payload: bytes) -> dict[str, str]:
    lines = payload.decode("utf-8").split("\n")
    return dict(line.split(":", 1) for line in lines if ":" in line)


def decode_scale(payload: bytes) -> dict[str, Any]:
    """One scale datagram's payload (each is whole: segments and/or points)."""
    (n_seg,) = struct.unpack_from(">i", payload, 0)
    at = 4
    null_pose = {}
    for _ in range(n_seg):
        name, at = _string(payload, at)
        null_pose[name] = struct.unpack_from(">3f", payload, at)
        at += 12
    (n_points,) = struct.unpack_from(">i", payload, at)
    at += 4
    points = []
    for _ in range(n_points):
        seg_id, point_id = struct.unpack_from(">HH", payload, at)
        name, at = _string(payload, at + 4)
        flags, x, y, z = struct.unpack_from(">I3f", payload, at)
        at += 16
        points.append({"segment": SPEC_SEGMENT_IDS[seg_id], "point_id": point_id, "name": name,
                       "flags": flags, "position": (x, y, z)})
    assert at == len(payload), "scale payload has trailing bytes"
    return {"null_pose": null_pose, "points": points}


def decode_joint_angles(payload: bytes) -> list[dict[str, Any]]:
    out = []
    for at in range(0, len(payload), 20):
        parent, child, rx, ry, rz = struct.unpack(">ii3f", payload[at:at + 20])
        out.append({"parent": (SPEC_SEGMENT_IDS[parent >> 8], parent & 0xFF),
                    "child": (SPEC_SEGMENT_IDS[child >> 8], child & 0xFF),
                    "rotation_deg": (rx, ry, rz)})
    return out


def decode_time_code(payload: bytes) -> str:
    """A protocol string (i32 length + 12 characters, as Xsens' receivers read it)."""
    text, _ = _string(payload, 0)
    assert len(text) == 12
    return text


DECODERS = {"02": decode_pose, "12": decode_meta, "13": decode_scale,
            "20": decode_joint_angles, "25": decode_time_code}


@dataclass
class Message:
    message_type: str
    character_id: int
    sample_counter: int
    time_code_ms: int
    datagrams: int
    items: int
    content: Any


@dataclass
class MvnReceiver:
    """Joins datagrams into messages and decodes them."""

    messages: list[Message] = field(default_factory=list)
    _parts: dict[tuple[str, int, int], list[tuple[Header, bytes]]] = field(default_factory=dict)

    def feed(self, data: bytes) -> None:
        header = read_header(data)
        payload = data[24:]
        assert len(payload) == header.payload_size, "payload size field disagrees"
        key = (header.message_type, header.character_id, header.sample_counter)
        parts = self._parts.setdefault(key, [])
        parts.append((header, payload))
        if not header.is_last:
            return
        del self._parts[key]
        parts.sort(key=lambda p: p[0].datagram_index)
        assert [p[0].datagram_index for p in parts] == list(range(len(parts))), "lost part"
        if header.message_type == "13":  # spec 2.6.2: every datagram a whole payload
            decoded = [decode_scale(p[1]) for p in parts]
            content: Any = {"null_pose": {k: v for d in decoded for k, v in d["null_pose"].items()},
                            "points": [pt for d in decoded for pt in d["points"]]}
        else:
            content = DECODERS[header.message_type](b"".join(p[1] for p in parts))
        self.messages.append(Message(header.message_type, header.character_id,
                                     header.sample_counter, header.time_code_ms, len(parts),
                                     sum(p[0].items for p in parts), content))

    def receive(self, sock: socket.socket, count: int) -> None:
        """Read ``count`` datagrams from a bound socket."""
        for _ in range(count):
            data, _ = sock.recvfrom(65536)
            self.feed(data)
