"""Xsens MVN MVNX (XML) files: segment poses, sensor orientations, joint angles, foot contacts.

MVN users can re-solve a take with ikfusion from its sensor orientations
(:meth:`MvnxRecording.imu_recording`) and compare with MVN's own segment poses. Quaternions in
MVNX are scalar first (w, x, y, z), positions in metres, the world Z up.

MVN's arm segment frames are parallel to the world in a T-pose, not in the N-pose of SPEC
section 1: :meth:`MvnxRecording.R_world_segment` converts them (upper arms, forearms and hands:
``R_ours = R_mvn @ Rx(+90 deg)`` on the left, ``Rx(-90 deg)`` on the right); trunk, legs and
shoulders are the same in both conventions.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..rotations import axis_rotation, quat_wxyz_to_matrix
from .mtmanager import ImuRecording, SensorStream

_ARMS = {"LeftUpperArm": 90.0, "LeftForeArm": 90.0, "LeftHand": 90.0,
         "RightUpperArm": -90.0, "RightForeArm": -90.0, "RightHand": -90.0}


@dataclass
class MvnxRecording:
    """The normal frames of an MVNX take.

    Attributes:
        path: The file.
        frame_rate: [Hz].
        time: (N,) [s] from the first frame.
        segments: Segment labels (MVN names, the same as ours).
        p_world_segment: (N, S, 3) segment origins [m].
        quat_wxyz_world_segment: (N, S, 4) segment orientations in MVN's convention.
        sensors: Labels of the segments that carry a sensor.
        quat_wxyz_world_sensor: (N, K, 4) sensor orientations.
        free_acc_world_sensor: (N, K, 3) sensor accelerations without gravity [m/s^2].
        joints: Joint labels.
        joint_angles_deg: (N, J, 3) MVN joint angles [deg] (ZXY sequence).
        contacts: Contact point labels (``LeftFoot_Heel`` ...).
        foot_contacts: (N, 4) bool.
        subject: Attributes of the ``subject`` element (label, frameRate, configuration, ...).
        segment_points: Segment -> point label -> position in the segment [m].
    """

    path: Path
    frame_rate: float
    time: np.ndarray
    segments: list[str]
    p_world_segment: np.ndarray
    quat_wxyz_world_segment: np.ndarray
    sensors: list[str]
    quat_wxyz_world_sensor: np.ndarray
    free_acc_world_sensor: np.ndarray
    joints: list[str]
    joint_angles_deg: np.ndarray
    contacts: list[str]
    foot_contacts: np.ndarray
    subject: dict[str, str] = field(default_factory=dict)
    segment_points: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    def R_world_segment(self, segment: str) -> np.ndarray:
        """(N, 3, 3) orientation of a segment in OUR convention (N-pose parallel frames)."""
        R = quat_wxyz_to_matrix(self.quat_wxyz_world_segment[:, self.segments.index(segment)])
        if segment in _ARMS:
            R = R @ axis_rotation("x", np.radians(_ARMS[segment]))
        return R

    def imu_recording(self) -> ImuRecording:
        """The sensor orientations as an :class:`ImuRecording` (sensor ids = segment labels)."""
        n = len(self.time)
        sensors = {}
        for k, label in enumerate(self.sensors):
            R = quat_wxyz_to_matrix(self.quat_wxyz_world_sensor[:, k])
            sensors[label] = SensorStream(label, R, np.isfinite(R).all(axis=(1, 2)), None,
                                          self.free_acc_world_sensor[:, k], None, None, n, 0,
                                          ["sensorOrientation", "sensorFreeAcceleration"],
                                          self.path)
        return ImuRecording(self.time.copy(), self.frame_rate, sensors)


def _floats(element: ET.Element | None, path: Path, what: str, index: int) -> np.ndarray:
    if element is None or element.text is None:
        raise InputError(f"frame {index} has no <{what}>", path=path, field=what)
    try:
        return np.array(element.text.split(), dtype=float)
    except ValueError:
        raise InputError(f"frame {index}: <{what}> holds a value that is not a number",
                         path=path, field=what) from None


def read_mvnx(path: str | Path) -> MvnxRecording:
    """Read an MVNX file (version 4 layout; any XML namespace).

    Raises:
        InputError: Not XML, no subject, or frames whose arrays do not match the segment and
            sensor counts (naming the frame and element).
    """
    file = Path(path)
    try:
        root = ET.parse(file).getroot()
    except (OSError, ET.ParseError) as err:
        raise InputError(f"not a readable MVNX (XML) file: {err}", path=file) from err
    ns = root.tag.split("}")[0] + "}" if root.tag.startswith("{") else ""
    subject = root.find(f"{ns}subject")
    if subject is None:
        raise InputError("no <subject> element", path=file, field="subject")
    rate = float(subject.get("frameRate", "nan"))
    segments = [s.get("label", "") for s in subject.iter(f"{ns}segment")]
    points = {}
    for s in subject.iter(f"{ns}segment"):
        points[s.get("label", "")] = {
            p.get("label", ""): np.array((p.findtext(f"{ns}pos_b") or "0 0 0").split(), dtype=float)
            for p in s.iter(f"{ns}point")}
    sensors = [s.get("label", "") for s in subject.iter(f"{ns}sensor")]
    joints = [j.get("label", "") for j in subject.iter(f"{ns}joint")]
    contacts = [c.get("label", "") for c in subject.iter(f"{ns}contactDefinition")]
    frames = [f for f in subject.iter(f"{ns}frame") if f.get("type") == "normal"]
    if not frames:
        raise InputError("no normal frames", path=file, field="frame")
    S, K, J = len(segments), len(sensors), len(joints)
    n = len(frames)
    p = np.empty((n, S, 3))
    q = np.empty((n, S, 4))
    sq = np.full((n, K, 4), np.nan)
    sa = np.full((n, K, 3), np.nan)
    ja = np.full((n, J, 3), np.nan)
    fc = np.zeros((n, len(contacts)), dtype=bool)
    ms = np.empty(n)
    for k, frame in enumerate(frames):
        ms[k] = float(frame.get("time", "nan"))
        q[k] = _floats(frame.find(f"{ns}orientation"), file, "orientation", k).reshape(S, 4)
        p[k] = _floats(frame.find(f"{ns}position"), file, "position", k).reshape(S, 3)
        if K:
            sq[k] = _floats(frame.find(f"{ns}sensorOrientation"), file, "sensorOrientation",
                            k).reshape(K, 4)
            if frame.find(f"{ns}sensorFreeAcceleration") is not None:
                sa[k] = _floats(frame.find(f"{ns}sensorFreeAcceleration"), file,
                                "sensorFreeAcceleration", k).reshape(K, 3)
        if J and frame.find(f"{ns}jointAngle") is not None:
            ja[k] = _floats(frame.find(f"{ns}jointAngle"), file, "jointAngle", k).reshape(J, 3)
        if contacts and frame.find(f"{ns}footContacts") is not None:
            fc[k] = _floats(frame.find(f"{ns}footContacts"), file, "footContacts", k) > 0.5
    if not np.isfinite(rate):
        rate = 1000.0 / float(np.median(np.diff(ms))) if n > 1 else 60.0
    return MvnxRecording(file, rate, (ms - ms[0]) / 1000.0, segments, p, q, sensors, sq, sa,
                         joints, ja, contacts, fc, dict(subject.attrib), points)
