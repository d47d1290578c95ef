"""Motion sources for retargeting: segment world poses and contact phases over time.

A ``solve`` result folder (``segments.csv``, ``contacts.csv``), a BVH clip (mapped onto the
human model, contacts from its kinematics) or an MVNX file of Xsens MVN (segment poses and the
foot contacts MVN detected, lifted so that the soles stand on z = 0) becomes a
:class:`HumanMotion`: per segment its world rotation ``R_world_segment`` (MVN segment
convention, SPEC section 1) and origin [m], world frame Z up.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.bad_samples import FAR_BEYOND_ANY_HALL_M
from ..model.layout import CONTACT_SITES
from ..rotations import quat_wxyz_to_matrix


@dataclass
class HumanMotion:
    """Segment poses and contact phases of a human over time.

    Attributes:
        time: (N,) [s].
        segments: Segment names (columns of the pose arrays).
        p_world_segment: (N, S, 3) segment origins [m].
        R_world_segment: (N, S, 3, 3) segment rotations.
        contact_names: Contact points (columns of ``contacts``).
        contacts: (N, k) planted or not.
        hip_height: Standing height of the hip joints above the floor [m] (for scaling).
        source: Where it came from.
        warnings: What reading it repaired (bad samples bridged), for the summary.
    """

    time: np.ndarray
    segments: list[str]
    p_world_segment: np.ndarray
    R_world_segment: np.ndarray
    contact_names: list[str]
    contacts: np.ndarray
    hip_height: float
    source: str
    warnings: list[str] = field(default_factory=list)

    @property
    def rate(self) -> float:
        """Frame rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.time))) if len(self.time) > 1 else 0.0

    def __len__(self) -> int:
        return len(self.time)

    def check(self) -> None:
        """Refuse poses that no solver can track: not finite, or far beyond any hall.

        Raises:
            InputError: Naming the source, the first bad frame and its segment.
        """
        with np.errstate(invalid="ignore", over="ignore"):
            bad_p = ~np.isfinite(self.p_world_segment).all(axis=2) | (
                np.abs(self.p_world_segment) > FAR_BEYOND_ANY_HALL_M).any(axis=2)
            bad_R = ~np.isfinite(self.R_world_segment).all(axis=(2, 3))
        for what, bad in (("position", bad_p), ("orientation", bad_R)):
            if bad.any():
                k, s = (int(i) for i in np.argwhere(bad)[0])
                raise InputError(
                    f"frame {k} (t = {self.time[k]:.3f} s): the {what} of {self.segments[s]} "
                    f"is not finite or farther than {FAR_BEYOND_ANY_HALL_M:g} m; "
                    f"{int(bad.any(axis=1).sum())} frames are affected", path=self.source,
                    field=f"{what} of {self.segments[s]}")


def load_source(path: str | Path) -> HumanMotion:
    """A ``solve`` result folder, a BVH file or an MVNX file as a :class:`HumanMotion`.

    Raises:
        InputError: Not a result folder, BVH or MVNX, or a malformed file (file, line and
            field).
    """
    p = Path(path)
    if p.is_dir() and (p / "segments.csv").is_file():
        return _from_result_folder(p)
    if p.is_file() and p.suffix.lower() == ".bvh":
        return _from_bvh(p)
    if p.is_file() and p.suffix.lower() == ".mvnx":
        return _from_mvnx(p)
    raise InputError("expected a solve result folder (with segments.csv), a .bvh or an .mvnx "
                     "file", path=p)


def _read_rows(path: Path, columns: tuple[str, ...]) -> list[list[str]]:
    """Rows of a CSV whose header must start with ``columns``."""
    if not path.is_file():
        raise InputError("missing file", path=path)
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows or tuple(rows[0][:len(columns)]) != columns:
        raise InputError(f"expected the header {','.join(columns)}", path=path, line=1)
    return rows


def _number(path: Path, line: int, field: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"not a number: {text!r}", path=path, line=line, field=field) from None
    if not np.isfinite(value):
        raise InputError("not a finite number", path=path, line=line, field=field)
    return value


def _from_result_folder(folder: Path) -> HumanMotion:
    path = folder / "segments.csv"
    header = ("time", "segment", "px", "py", "pz", "qw", "qx", "qy", "qz")
    rows = _read_rows(path, header)
    times: dict[float, int] = {}
    segments: list[str] = []
    values: dict[tuple[int, str], list[float]] = {}
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputError(f"expected {len(header)} fields, found {len(row)}", path=path,
                             line=n)
        t = _number(path, n, "time", row[0])
        k = times.setdefault(t, len(times))
        if row[1] not in segments:
            segments.append(row[1])
        values[(k, row[1])] = [_number(path, n, name, v) for name, v in zip(header[2:], row[2:])]
    N, S = len(times), len(segments)
    data = np.full((N, S, 7), np.nan)
    for (k, seg), v in values.items():
        data[k, segments.index(seg)] = v
    if np.isnan(data).any():
        raise InputError("some frames lack some segments", path=path)
    crows = _read_rows(folder / "contacts.csv", ("time",))
    names = crows[0][1:]
    contacts = np.array([[_number(folder / "contacts.csv", n, c, v) > 0.5
                          for c, v in zip(names, row[1:])]
                         for n, row in enumerate(crows[1:], start=2)], dtype=bool)
    if len(contacts) != N:
        raise InputError(f"{len(contacts)} rows, but segments.csv has {N} frames",
                         path=folder / "contacts.csv")
    time = np.array(sorted(times, key=times.__getitem__))
    R = quat_wxyz_to_matrix(data[..., 3:])
    p = data[..., :3]
    return HumanMotion(time, segments, p, R, list(names), contacts,
                       _standing_hip_height(segments, p), str(folder))


def _standing_hip_height(segments: list[str], p_world_segment: np.ndarray) -> float:
    """Height of the hip joints above the floor (z = 0) in the first frame [m]."""
    hips = [segments.index(s) for s in ("RightUpperLeg", "LeftUpperLeg") if s in segments]
    if not hips:
        raise InputError("the source has no thighs (RightUpperLeg, LeftUpperLeg) to scale from")
    return float(np.mean(p_world_segment[0, hips, 2]))


def _from_bvh(path: Path) -> HumanMotion:
    from ..mocap.from_bvh import segment_motion_from_bvh

    # no per-frame solve (see mocap.direct_pose); segment poses from the contacts' pass
    truth, p, R = segment_motion_from_bvh(path)
    segments = list(truth.model.segment_names)
    names = list(truth.contact_names) or list(CONTACT_SITES)
    return HumanMotion(truth.time, segments, p, R, names, truth.contacts.astype(bool),
                       _standing_hip_height(segments, p), str(path),
                       list(truth.info.get("warnings", [])))


#: MVN's foot contact labels -> our contact points.
_MVN_CONTACTS = {"LeftFoot_Heel": "LeftHeel", "LeftFoot_Toe": "LeftToe",
                 "RightFoot_Heel": "RightHeel", "RightFoot_Toe": "RightToe"}


def _from_mvnx(path: Path) -> HumanMotion:
    from ..io.mvnx import read_mvnx
    from ..mocap.model_motion import contact_phases_from_points

    rec = read_mvnx(path)
    segments = list(rec.segments)
    R = np.stack([rec.R_world_segment(s) for s in segments], axis=1)
    p = rec.p_world_segment.copy()
    soles = _mvn_sole_points(rec.segment_points, segments, R, p)
    p[..., 2] -= float(np.percentile(soles[..., 2].min(axis=1), 2))  # soles on z = 0
    soles[..., 2] -= float(np.percentile(soles[..., 2].min(axis=1), 2))
    names = list(CONTACT_SITES)
    if rec.contacts and all(c in _MVN_CONTACTS for c in rec.contacts) and len(rec.foot_contacts):
        by_name = {_MVN_CONTACTS[c]: rec.foot_contacts[:, k] for k, c in enumerate(rec.contacts)}
        contacts = np.column_stack([by_name[n] for n in names]).astype(bool)
    else:  # no contacts exported: from the kinematics of the sole points
        contacts = contact_phases_from_points(soles, rec.time)
    return HumanMotion(rec.time, segments, p, R, names, contacts,
                       _standing_hip_height(segments, p), str(path), list(rec.warnings))


def _mvn_sole_points(points: dict[str, dict[str, np.ndarray]], segments: list[str],
                     R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """World positions (N, 4, 3) [m] of heels and toe tips, in ``CONTACT_SITES`` order.

    From MVN's segment points ``p<Side>HeelFoot`` and ``p<Side>Toe`` when the file has them,
    else the foot and toe segment origins.
    """
    out = []
    for name in CONTACT_SITES:
        side = "Left" if name.startswith("Left") else "Right"
        segment, point = ((f"{side}Foot", f"p{side}HeelFoot") if name.endswith("Heel")
                          else (f"{side}Toe", f"p{side}Toe"))
        if segment not in segments:
            raise InputError(f"the MVNX has no {segment} segment to stand on")
        k = segments.index(segment)
        local = points.get(segment, {}).get(point, np.zeros(3))
        out.append(p[:, k] + R[:, k] @ local)
    return np.stack(out, axis=1)
