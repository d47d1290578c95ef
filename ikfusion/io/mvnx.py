"""Xsens MVN MVNX (XML) files: segment poses, sensor orientations, joint angles, foot contacts.

MVN users can re-solve a take with ikfusion from its sensor orientations
(:meth:`MvnxRecording.imu_recording`, sensor ids = the segment labels) and compare with MVN's
own segment poses and joint angles.

What the file holds (MVNX version 4; any XML namespace):

* ``<subject frameRate=...>`` with ``<segments>`` (each with named points ``pos_b`` [m] in the
  segment frame), ``<sensors>``, ``<joints>``, ``<footContactDefinition>``;
* ``<frame type="identity|tpose|tpose-isb">``: reference poses; ``<frame type="normal">``: the
  take, each with ``orientation`` (segment quaternions, **w, x, y, z**), ``position`` [m],
  ``sensorOrientation`` (w, x, y, z), ``sensorFreeAcceleration`` [m/s^2, world],
  ``sensorMagneticField`` [a.u., sensor frame], ``jointAngle`` [deg, ZXY], ``footContacts``.

The world is Z up (checked from the reference pose: the head must be above the pelvis along Z;
a Y-up file is turned to Z up and said so in ``warnings``). MVN's arm segment frames are
parallel to the world in the T-pose, not in the N-pose of SPEC section 1 (the file's identity
pose has the arms sideways): :meth:`MvnxRecording.R_world_segment` converts them (upper arms,
forearms and hands: ``R_ours = R_mvn @ Rx(+90 deg)`` on the left, ``Rx(-90 deg)`` on the right);
trunk, legs and shoulders are the same in both conventions.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..rotations import axis_rotation, matrix_to_quat_wxyz, quat_wxyz_to_matrix
from .bad_samples import Kind, bad_samples, bridge_channel
from .orientation_columns import R_from_quat
from .recording import ImuRecording, SensorStream, build_stream

__all__ = ["MvnxRecording", "read_mvnx"]


def mvn_arm_offsets_deg() -> dict[str, float]:
    """Rotation about X [deg] from MVN's T-pose-aligned arm frames to ours (N-pose aligned)."""
    return {"LeftUpperArm": 90.0, "LeftForeArm": 90.0, "LeftHand": 90.0,
            "RightUpperArm": -90.0, "RightForeArm": -90.0, "RightHand": -90.0}


@dataclass
class MvnxRecording:
    """The frames of an MVNX take.

    Attributes:
        path: The file.
        version: The ``mvnx`` version attribute.
        frame_rate: [Hz].
        time: (N,) [s] from the first normal frame (from the frame index and rate).
        frame_index: (N,) the frames' ``index`` attributes.
        segments: Segment labels (MVN names, the same as ours).
        p_world_segment: (N, S, 3) segment origins [m].
        quat_wxyz_world_segment: (N, S, 4) segment orientations in MVN's convention (w, x, y, z).
        sensors: Labels of the segments that carry a sensor.
        quat_wxyz_world_sensor: (N, K, 4) sensor orientations (w, x, y, z).
        free_acc_world_sensor: (N, K, 3) sensor accelerations without gravity, world [m/s^2]
            (NaN when absent).
        mag_sensor: (N, K, 3) magnetic field, sensor frame [a.u.] (NaN when absent).
        joints: Joint labels.
        joint_angles_deg: (N, J, 3) MVN joint angles [deg] (ZXY sequence), NaN when absent.
        contacts: Contact point labels (``LeftFoot_Heel`` ...).
        foot_contacts: (N, C) bool.
        subject: Attributes of the ``subject`` element (label, frameRate, configuration, ...).
        segment_points: Segment -> point label -> position in the segment frame [m].
        reference_poses: Frame type (``identity``, ``tpose``, ``tpose-isb``) ->
            (quat_wxyz (S, 4), position (S, 3)).
        warnings: Remarks made while reading.
    """

    path: Path
    version: str
    frame_rate: float
    time: np.ndarray
    frame_index: np.ndarray
    segments: list[str]
    p_world_segment: np.ndarray
    quat_wxyz_world_segment: np.ndarray
    sensors: list[str]
    quat_wxyz_world_sensor: np.ndarray
    free_acc_world_sensor: np.ndarray
    mag_sensor: np.ndarray
    joints: list[str]
    joint_angles_deg: np.ndarray
    contacts: list[str]
    foot_contacts: np.ndarray
    subject: dict[str, str] = field(default_factory=dict)
    segment_points: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    reference_poses: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.time)

    def R_world_segment(self, segment: str) -> np.ndarray:
        """(N, 3, 3) orientation of a segment in OUR convention (N-pose parallel frames).

        Raises:
            InputError: An unknown segment label.
        """
        if segment not in self.segments:
            raise InputError(f"no segment {segment!r} in the MVNX; segments: "
                             f"{', '.join(self.segments)}", path=self.path, field="segment")
        R = quat_wxyz_to_matrix(self.quat_wxyz_world_segment[:, self.segments.index(segment)])
        offset = mvn_arm_offsets_deg().get(segment)
        if offset is not None:
            R = R @ axis_rotation("x", np.radians(offset))
        return R

    def segment_poses(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Segment -> (``R_world_segment`` (N, 3, 3) in our convention, ``p_world`` (N, 3) [m])."""
        return {s: (self.R_world_segment(s), self.p_world_segment[:, k])
                for k, s in enumerate(self.segments)}

    def joint_angles(self) -> dict[str, np.ndarray]:
        """Joint label -> (N, 3) MVN joint angles [deg] (ZXY: about Z, X, then Y)."""
        return {j: self.joint_angles_deg[:, k] for k, j in enumerate(self.joints)}

    def sensor_map(self) -> dict[str, str]:
        """Sensor id -> segment for :meth:`imu_recording` (ids are the segment labels)."""
        return {s: s for s in self.sensors}

    def body_dimensions(self) -> dict[str, float]:
        """Subject dimensions [m] from the segment points, with the keys of a body file.

        ``upper_arm, forearm, hand, upper_leg, lower_leg, foot_length, ankle_height, hip_width,
        shoulder_width`` from the points of the segments (mean of left and right);
        ``height, hip_height, shoulder_height`` from the neutral pose built by chaining the
        segments' joint points (all frames at identity).
        """
        pts = self.segment_points
        out: dict[str, float] = {}

        def length(segment: str, point: str) -> float | None:
            values = [np.linalg.norm(pts[f"{side}{segment}"][f"{p}"])
                      for side in ("Left", "Right")
                      if f"{side}{segment}" in pts
                      for p in [point.replace("*", side)] if p in pts[f"{side}{segment}"]]
            return float(np.mean(values)) if values else None

        for key, segment, point in (("upper_arm", "UpperArm", "j*Elbow"),
                                    ("forearm", "ForeArm", "j*Wrist"),
                                    ("hand", "Hand", "p*TopOfHand"),
                                    ("upper_leg", "UpperLeg", "j*Knee"),
                                    ("lower_leg", "LowerLeg", "j*Ankle")):
            value = length(segment, point)
            if value is not None:
                out[key] = value
        pelvis = pts.get("Pelvis", {})
        if "jRightHip" in pelvis and "jLeftHip" in pelvis:
            out["hip_width"] = float(np.linalg.norm(pelvis["jRightHip"] - pelvis["jLeftHip"]))
        neutral = self._neutral_positions()
        foot = pts.get("RightFoot", {})
        toe = pts.get("RightToe", {})
        if {"pRightHeelFoot", "jRightBallFoot"} <= set(foot) and "pRightToe" in toe:
            tip = foot["jRightBallFoot"] + toe["pRightToe"]
            out["foot_length"] = float(tip[0] - foot["pRightHeelFoot"][0])
        if "pRightHeelCenter" in foot:
            out["ankle_height"] = float(-foot["pRightHeelCenter"][2])
        if {"RightUpperArm", "LeftUpperArm"} <= set(neutral):
            out["shoulder_width"] = float(np.linalg.norm(neutral["RightUpperArm"]
                                                         - neutral["LeftUpperArm"]))
        if "RightFoot" in neutral and "ankle_height" in out:
            floor = neutral["RightFoot"][2] - out["ankle_height"]
            head = pts.get("Head", {})
            if "Head" in neutral and "pTopOfHead" in head:
                out["height"] = float(neutral["Head"][2] + head["pTopOfHead"][2] - floor)
            if "RightUpperLeg" in neutral:
                out["hip_height"] = float(neutral["RightUpperLeg"][2] - floor)
            if "RightUpperArm" in neutral:
                out["shoulder_height"] = float(neutral["RightUpperArm"][2] - floor)
        return out

    def _neutral_positions(self) -> dict[str, np.ndarray]:
        """Segment origins with every frame at identity, chained through the joint points."""
        pts = self.segment_points
        if not self.segments:
            return {}
        positions = {self.segments[0]: np.zeros(3)}
        for segment in self.segments[1:]:
            origin = next((label for label, p in pts.get(segment, {}).items()
                           if label.startswith("j") and np.linalg.norm(p) < 1e-9), None)
            parent = next((s for s in positions if origin is not None
                           and origin in pts.get(s, {})), None)
            if origin is not None and parent is not None:
                positions[segment] = positions[parent] + pts[parent][origin]
        return positions

    def imu_recording(self) -> ImuRecording:
        """The sensor orientations (and free accelerations, magnetic field) as a recording.

        Sensor ids are the segment labels; frames missing from the index sequence are gaps.
        """
        index = self.frame_index - self.frame_index[0]
        n = int(index[-1]) + 1 if len(index) else 0
        sensors: dict[str, SensorStream] = {}
        for k, label in enumerate(self.sensors):
            R, _ = R_from_quat(self.quat_wxyz_world_sensor[:, k])
            free = self.free_acc_world_sensor[:, k]
            mag = self.mag_sensor[:, k]
            vectors = {"free_acc": free if np.isfinite(free).any() else None,
                       "mag": mag if np.isfinite(mag).any() else None}
            channels = ["sensorOrientation"] + [c for c, v in (
                ("sensorFreeAcceleration", vectors["free_acc"]),
                ("sensorMagneticField", vectors["mag"])) if v is not None]
            sensors[label] = build_stream(label, index, n, R, vectors, rows=len(index),
                                          channels=channels, orientation_source="Quat",
                                          path=self.path)
        return ImuRecording(time=np.arange(n) / self.frame_rate, rate=self.frame_rate,
                            sensors=sensors, coordinate_system="ENU",
                            source_coordinate_system="MVN (Z up)", source=[self.path],
                            warnings=list(self.warnings))


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _numbers(element: ET.Element | None, what: str, frame: str, size: int | None,
             path: Path) -> np.ndarray:
    if element is None or element.text is None:
        raise InputError(f"frame {frame} has no <{what}>", path=path, field=what)
    try:
        values = np.array(element.text.split(), dtype=float)
    except ValueError:
        bad = next(t for t in element.text.split() if not _is_number(t))
        raise InputError(f"frame {frame}: <{what}> holds {bad!r}, not a number", path=path,
                         field=what) from None
    if size is not None and values.size != size:
        raise InputError(f"frame {frame}: <{what}> has {values.size} numbers, expected {size}",
                         path=path, field=what)
    return values


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclass
class _Collected:
    """What the streaming parse gathers before the arrays are stacked."""

    version: str = ""
    subject: dict[str, str] = field(default_factory=dict)
    segments: list[str] = field(default_factory=list)
    points: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    sensors: list[str] = field(default_factory=list)
    joints: list[str] = field(default_factory=list)
    contacts: list[str] = field(default_factory=list)
    reference: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    frames: dict[str, list[np.ndarray]] = field(default_factory=dict)
    index: list[float] = field(default_factory=list)
    ms: list[float] = field(default_factory=list)


def _frame(elem: ET.Element, c: _Collected, path: Path) -> None:
    kind = elem.get("type", "normal")
    label = elem.get("index", elem.get("time", "?"))
    children = {_local(ch.tag): ch for ch in elem}
    S, K, J = len(c.segments), len(c.sensors), len(c.joints)
    if kind != "normal":
        q = _numbers(children.get("orientation"), "orientation", kind, 4 * S, path)
        p = _numbers(children.get("position"), "position", kind, 3 * S, path)
        c.reference[kind] = (q.reshape(S, 4), p.reshape(S, 3))
        return
    wanted = {"orientation": 4 * S, "position": 3 * S}
    optional = {"sensorOrientation": 4 * K, "sensorFreeAcceleration": 3 * K,
                "sensorMagneticField": 3 * K, "jointAngle": 3 * J,
                "footContacts": len(c.contacts)}
    for name, size in wanted.items():
        c.frames.setdefault(name, []).append(_numbers(children.get(name), name, label, size,
                                                      path))
    for name, size in optional.items():
        if size and name in children:
            values = _numbers(children[name], name, label, size, path)
        else:
            values = np.full(size, np.nan)
        c.frames.setdefault(name, []).append(values)
    c.index.append(float(elem.get("index", "nan")))
    c.ms.append(float(elem.get("time", "nan")))


def _parse(file: Path) -> _Collected:
    c = _Collected()
    try:
        for event, elem in ET.iterparse(file, events=("start", "end")):
            tag = _local(elem.tag)
            if event == "start":
                if tag == "mvnx":
                    c.version = elem.get("version", "")
                elif tag == "subject":
                    c.subject = dict(elem.attrib)
                continue
            if tag == "segment":
                c.segments.append(elem.get("label", ""))
                c.points[c.segments[-1]] = {
                    p.get("label", ""): np.array((_find_text(p, "pos_b") or "0 0 0").split(),
                                                 dtype=float)
                    for p in elem.iter() if _local(p.tag) == "point"}
            elif tag == "sensor":
                c.sensors.append(elem.get("label", ""))
            elif tag == "joint":
                c.joints.append(elem.get("label", ""))
            elif tag == "contactDefinition":
                c.contacts.append(elem.get("label", ""))
            elif tag == "frame":
                _frame(elem, c, file)
                elem.clear()
    except ET.ParseError as err:
        line = err.position[0] if hasattr(err, "position") else None
        raise InputError(f"not a readable MVNX (XML) file: {err}", path=file, line=line) from err
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", path=file) from err
    except ValueError as err:
        raise InputError(f"a segment point holds something that is not a number: {err}",
                         path=file, field="pos_b") from err
    return c


def _find_text(element: ET.Element, name: str) -> str | None:
    for child in element:
        if _local(child.tag) == name:
            return child.text
    return None


def _up_axis(c: _Collected) -> int:
    """World axis (0, 1, 2) along which the head is above the pelvis in a reference pose."""
    pose = c.reference.get("identity") or c.reference.get("tpose")
    if pose is None or "Head" not in c.segments or "Pelvis" not in c.segments:
        return 2
    up = pose[1][c.segments.index("Head")] - pose[1][c.segments.index("Pelvis")]
    return int(np.argmax(np.abs(up)))


def read_mvnx(path: str | Path) -> MvnxRecording:
    """Read an MVNX file (version 4 layout; any XML namespace), streaming its frames.

    Bad samples (NaN, infinite, a position far beyond any hall, a quaternion that is not a
    rotation) of a segment's ``orientation`` or ``position`` are bridged over short runs as
    :mod:`ikfusion.io.bad_samples` says, with a warning naming the frames, lines and segment;
    bad ``sensorOrientation`` samples become missing samples (NaN), as lost packets are.

    Raises:
        InputError: Not XML, no subject or no normal frames, a frame whose arrays do not
            match the segment, sensor and joint counts (naming the frame and element), or a
            segment whose bad samples cannot be bridged honestly (file, line, element).
    """
    file = Path(path)
    c = _parse(file)
    if not c.subject:
        raise InputError("no <subject> element: not an MVNX file", path=file, field="subject")
    if not c.index:
        raise InputError("no normal frames (<frame type=\"normal\">)", path=file, field="frame")
    warnings: list[str] = []
    frames = {k: np.stack(v) for k, v in c.frames.items()}
    n, S, K = len(c.index), len(c.segments), len(c.sensors)
    rate = float(c.subject.get("frameRate", "nan") or "nan")
    index = np.asarray(c.index)
    ms = np.asarray(c.ms)
    if not np.isfinite(index).all():
        index = np.arange(n, dtype=float)
        if np.isfinite(ms).all() and n > 1:
            step = float(np.median(np.diff(ms)))
            index = np.round((ms - ms[0]) / step)
    if not np.isfinite(rate) or rate <= 0:
        if np.isfinite(ms).all() and n > 1:
            rate = round(1000.0 * (index[-1] - index[0]) / (ms[-1] - ms[0]), 3)
            warnings.append(f"no frameRate attribute: {rate:g} Hz from the frame times")
        else:
            raise InputError("no frameRate attribute and no frame times", path=file,
                             field="frameRate")
    q_seg = frames["orientation"].reshape(n, S, 4)
    p_seg = frames["position"].reshape(n, S, 3)
    q_sen = frames["sensorOrientation"].reshape(n, K, 4)
    free = frames["sensorFreeAcceleration"].reshape(n, K, 3)
    mag = frames["sensorMagneticField"].reshape(n, K, 3)
    up = _up_axis(c)
    if up != 2:
        turn = axis_rotation("x", np.pi / 2) if up == 1 else axis_rotation("y", -np.pi / 2)
        warnings.append(f"the reference pose is {'XYZ'[up]}-up; turned to Z up")
        q_seg = _turn_quat(turn, q_seg)
        q_sen = _turn_quat(turn, q_sen)
        p_seg = p_seg @ turn.T
        free = free @ turn.T
    order = index - index[0]
    if np.any(np.diff(order) <= 0):
        raise InputError("frame indices do not increase", path=file, field="index")
    labels = index.astype(np.int64)
    q_seg = _bridge_segments(file, "orientation", q_seg, c.segments, rate, labels, warnings)
    p_seg = _bridge_segments(file, "position", p_seg, c.segments, rate, labels, warnings)
    q_sen = _drop_bad_sensor_samples(file, q_sen, c.sensors, labels, warnings)
    return MvnxRecording(
        path=file, version=c.version, frame_rate=rate, time=order / rate,
        frame_index=index.astype(np.int64), segments=c.segments, p_world_segment=p_seg,
        quat_wxyz_world_segment=q_seg, sensors=c.sensors, quat_wxyz_world_sensor=q_sen,
        free_acc_world_sensor=free, mag_sensor=mag, joints=c.joints,
        joint_angles_deg=frames["jointAngle"].reshape(n, len(c.joints), 3),
        contacts=c.contacts, foot_contacts=frames["footContacts"].reshape(n, len(c.contacts)) > 0.5,
        subject=c.subject, segment_points=c.points, reference_poses=c.reference,
        warnings=warnings)


def _bridge_segments(file: Path, element: str, values: np.ndarray, segments: list[str],
                     rate: float, labels: np.ndarray, warnings: list[str]) -> np.ndarray:
    """Segment orientations (N, S, 4) or positions (N, S, 3) with bad samples bridged.

    Raises:
        InputError: A segment whose bad samples cannot be bridged (file, line, element).
    """
    kind: Kind = "quat_wxyz" if element == "orientation" else "position"
    bad = np.stack([bad_samples(values[:, k], kind) for k in range(len(segments))], axis=1) \
        if segments else np.zeros((len(values), 0), dtype=bool)
    if not bad.any():
        return values
    bad_frames = labels[bad.any(axis=1)]
    lines = _element_lines(file, element, bad_frames)
    frame_lines = np.array([lines.get(int(i), 0) for i in labels]) \
        if len(lines) == len(set(bad_frames.tolist())) else None
    out = values.copy()
    for k in np.flatnonzero(bad.any(axis=0)):
        out[:, k], warning = bridge_channel(
            values[:, k], bad[:, k], rate=rate, path=file,
            channel=f"{element} of {segments[k]}", kind=kind, frame_lines=frame_lines,
            frame_labels=labels)
        if warning is not None:
            warnings.append(warning)
    return out


def _drop_bad_sensor_samples(file: Path, quat_wxyz: np.ndarray, sensors: list[str],
                             labels: np.ndarray, warnings: list[str]) -> np.ndarray:
    """Sensor quaternions (N, K, 4) with infinite or non-unit ones set to NaN (missing)."""
    out = quat_wxyz.copy()
    for k, label in enumerate(sensors):
        q = quat_wxyz[:, k]
        absurd = bad_samples(q, "quat_wxyz") & ~np.isnan(q).all(axis=1)
        if absurd.any():
            out[absurd, k] = np.nan
            frames = labels[absurd]
            warnings.append(f"{file}: sensorOrientation of {label}: {int(absurd.sum())} "
                            f"samples are not rotations (first at frame {frames[0]}); read "
                            "as missing samples")
    return out


def _element_lines(file: Path, element: str, frame_indices: np.ndarray) -> dict[int, int]:
    """1-based line of ``<element>`` inside each normal frame of ``frame_indices``.

    Only called when a bad sample was found, so the common case reads the file once.
    """
    wanted = {int(i) for i in frame_indices}
    found: dict[int, int] = {}
    frame_re = re.compile(r'<(?:\w+:)?frame\b[^>]*\bindex="(\d+)"')
    current: int | None = None
    opening = re.compile(rf"<(?:\w+:)?{element}>")
    with file.open(encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            match = frame_re.search(line)
            if match is not None:
                normal = "type=" not in line or 'type="normal"' in line
                current = int(match.group(1)) if normal else None
            if current in wanted and current not in found and opening.search(line):
                found[current] = number
                if len(found) == len(wanted):
                    break
    return found


def _turn_quat(turn: np.ndarray, quat_wxyz: np.ndarray) -> np.ndarray:
    """Quaternions of ``turn @ R`` (NaN stays NaN)."""
    shape = quat_wxyz.shape
    q = quat_wxyz.reshape(-1, 4)
    out = np.full_like(q, np.nan)
    ok = np.isfinite(q).all(axis=1)
    out[ok] = matrix_to_quat_wxyz(turn @ quat_wxyz_to_matrix(q[ok]))
    return out.reshape(shape)
