"""The human model: a URDF loaded into Pinocchio with a free-flyer at Pelvis and ball joints.

Configuration ``q`` (nq = 7 + 4 * 22 = 95 for the default model): the free-flyer position
``p_world_pelvis`` [m] and quaternion (x, y, z, w, Pinocchio's order), then one quaternion
(x, y, z, w) per ball joint. Tangent space (nv = 6 + 3 * 22 = 72): the free-flyer twist in the
pelvis frame, then one rotation vector per joint in the child frame.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TypeVar

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import ConfigError, NameNotFound
from ..paths import robots_dir
from ..rotations import matrix_to_quat_wxyz, quat_wxyz_to_matrix, wxyz_to_xyzw, xyzw_to_wxyz
from .angle_continuity import continuous_series, nearest_equivalent
from .ball_joints import BallJoint, merge_revolute_triplets
from .body import Body
from .joints import JOINTS, SEGMENTS
from .layout import (
    BODY_CONTACT_SITES,
    CONTACT_SITES,
    SENSOR_SEGMENTS,
    TAG_SITES,
    TRUNK_CONTACT_SITES,
)
from .model_cache import (
    HUMAN_MODEL_FILES,
    TABLE_ATTRIBUTES,
    entry_folder,
    load_entry,
    store_entry,
)
from .motion_kinematics import frame_placements
from .urdf import SITE_SUFFIX, body_to_urdf, write_urdf

#: The shipped default subject (1.75 m).
DEFAULT_URDF = "human.urdf"

V = TypeVar("V")


@dataclass(frozen=True)
class SiteInfo:
    """A site of the model: a fixed frame on a segment.

    Attributes:
        name: SPEC name (``HeadTop``, ``LeftHeel``, or a sensor site named like its segment).
        frame_id: Pinocchio frame index.
        segment: Segment that carries it.
        kind: ``"sensor"``, ``"tag"``, ``"contact"`` or ``"other"``.
    """

    name: str
    frame_id: int
    segment: str
    kind: str


class HumanModel:
    """A Pinocchio model with ball joints, named segments, joints and sites.

    Build it with :meth:`default`, :meth:`from_body` or :meth:`from_urdf`. The convenience queries
    (:meth:`site_position`, ...) run forward kinematics on an internal ``pinocchio.Data`` and are
    not thread-safe; solvers keep their own data.

    Attributes:
        model: The ``pinocchio.Model`` (free-flyer + spherical joints).
        revolute_model: The same URDF loaded with plain revolute joints (for checks and robots).
        ball_joints: Ball joint name -> :class:`BallJoint` (empty for a URDF without triplets).
        body: The body dimensions when the model was built from a :class:`Body`, else None.
        urdf_path: The URDF the model was loaded from (None when generated in memory by
            :meth:`from_body`).
    """

    def __init__(self, urdf_path: str | Path, body: Body | None = None,
                 merge_ball_joints: bool = True) -> None:
        path = Path(urdf_path)
        if not path.is_file():
            raise ConfigError("URDF file not found", path=path)
        try:
            revolute = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
        except (RuntimeError, ValueError) as err:
            raise ConfigError(f"URDF could not be loaded: {err}", path=path) from err
        self.urdf_path: Path | None = path
        self._set_up(revolute, body, merge_ball_joints)

    def _set_up(self, revolute: pin.Model, body: Body | None, merge_ball_joints: bool) -> None:
        """Names, ball joints and the N-pose of a model loaded with revolute joints."""
        self.body = body
        self.revolute_model = revolute
        if merge_ball_joints:
            converted = merge_revolute_triplets(revolute)
            self.model = converted.model
            self.ball_joints = _in_spec_order(converted.ball_joints)
            self.joint_map = converted.joint_map
        else:
            self.model = revolute
            self.ball_joints = {}
            self.joint_map = {j: j for j in range(revolute.njoints)}
        self._data: pin.Data | None = None
        self._frames = {f.name: i for i, f in enumerate(self.model.frames)}
        self._segments = self._find_segments()
        self._sites = self._find_sites()
        self._q_neutral = self._neutral_on_floor()

    @property
    def data(self) -> pin.Data:
        """The internal ``pinocchio.Data`` of the convenience queries (created on first use).

        Also the scratch of :class:`ikfusion.ik.sensed_pose.SensedPose`: whoever uses it runs
        the kinematics it reads first. One Data is enough: Pinocchio sizes its second-order
        tensors by ``nv`` cubed (13 MB for the human model, 8 ms of page faults to build).
        """
        if self._data is None:
            self._data = pin.Data(self.model)
        return self._data

    # ------------------------------------------------------------------ construction
    @classmethod
    def default(cls) -> HumanModel:
        """The shipped 1.75 m subject, ``robots/human.urdf``."""
        return cls(robots_dir() / DEFAULT_URDF, body=Body())

    @classmethod
    def from_body(cls, body: Body, urdf_path: str | Path | None = None) -> HumanModel:
        """The model of ``body``; its URDF written to ``urdf_path`` when given.

        Without ``urdf_path`` the URDF is parsed in memory, once per body dimensions in a
        process (:func:`_model_of_body`): later calls with an equal body get a copy that
        shares the Pinocchio models (never modified) and has its own ``data``.
        """
        if urdf_path is not None:
            write_urdf(body, urdf_path)
            return cls(urdf_path, body=body)
        return _model_of_body(body)._shared_copy()

    @classmethod
    def _from_urdf_text(cls, text: str, body: Body) -> HumanModel:
        """The model of a generated URDF text (no file; ``urdf_path`` is None)."""
        model = cls.__new__(cls)
        model.urdf_path = None
        model._set_up(pin.buildModelFromXML(text, pin.JointModelFreeFlyer()), body, True)
        return model

    @classmethod
    def _from_parts(cls, model: pin.Model, revolute: pin.Model,
                    tables: Mapping[str, object]) -> HumanModel:
        """A generated model (``urdf_path`` None) from its cached parts (:mod:`.model_cache`)."""
        out = cls.__new__(cls)
        out.urdf_path = None
        out.model, out.revolute_model = model, revolute
        for name, value in tables.items():
            setattr(out, name, value)
        out._data = None
        return out

    def _shared_copy(self) -> HumanModel:
        """A copy sharing the Pinocchio models and name tables, with its own ``data``."""
        other = copy.copy(self)
        other._data = None
        return other

    @classmethod
    def from_urdf(cls, path: str | Path, merge_ball_joints: bool = True) -> HumanModel:
        """Load any URDF (free-flyer at its root link); revolute triplets become ball joints."""
        return cls(path, merge_ball_joints=merge_ball_joints)

    # ------------------------------------------------------------------ names
    def _find_segments(self) -> dict[str, int]:
        bodies = {f.name: i for i, f in enumerate(self.model.frames)
                  if f.type == pin.FrameType.BODY and not f.name.endswith(SITE_SUFFIX)}
        if all(s in bodies for s in SEGMENTS):
            return {s: bodies[s] for s in SEGMENTS}
        return bodies

    def _find_sites(self) -> dict[str, SiteInfo]:
        sites = {}
        kinds = {**{s: "sensor" for s in SENSOR_SEGMENTS}, **{s: "tag" for s in TAG_SITES},
                 **{s: "contact" for s in (*CONTACT_SITES, *BODY_CONTACT_SITES,
                                          *TRUNK_CONTACT_SITES)}}
        for i, f in enumerate(self.model.frames):
            if f.type != pin.FrameType.BODY or not f.name.endswith(SITE_SUFFIX):
                continue
            name = f.name[: -len(SITE_SUFFIX)]
            parent = self.model.frames[f.parentFrame]
            segment = self.model.frames[parent.parentFrame].name
            sites[name] = SiteInfo(name, i, segment, kinds.get(name, "other"))
        # the contact points beyond the feet come last, so the feet keep their columns
        last = [n for n in (*BODY_CONTACT_SITES, *TRUNK_CONTACT_SITES) if n in sites]
        return {**{n: s for n, s in sites.items() if n not in last}, **{n: sites[n] for n in last}}

    @property
    def segment_names(self) -> list[str]:
        """Segment (body) names in model order."""
        return list(self._segments)

    @property
    def joint_names(self) -> list[str]:
        """Ball joint names in model order."""
        return list(self.ball_joints)

    @property
    def site_names(self) -> list[str]:
        """Site names (sensor sites are named like their segment)."""
        return list(self._sites)

    @property
    def sites(self) -> dict[str, SiteInfo]:
        """Site name -> :class:`SiteInfo`."""
        return dict(self._sites)

    def sites_of_kind(self, kind: str) -> list[str]:
        """Names of the sites of one kind (``"sensor"``, ``"tag"``, ``"contact"``)."""
        return [s.name for s in self._sites.values() if s.kind == kind]

    def frame_id(self, name: str) -> int:
        """Pinocchio frame index of any frame name (segments, joints, ``<site>_site`` links)."""
        return _look_up(self._frames, "frame", name)

    def segment_frame_id(self, name: str) -> int:
        """Frame index of a segment."""
        return _look_up(self._segments, "segment", name)

    def site_frame_id(self, name: str) -> int:
        """Frame index of a site."""
        return self.site(name).frame_id

    def site(self, name: str) -> SiteInfo:
        """The :class:`SiteInfo` of a site."""
        return _look_up(self._sites, "site", name)

    def ball_joint(self, name: str) -> BallJoint:
        """The :class:`BallJoint` of a joint name."""
        return _look_up(self.ball_joints, "joint", name)

    @property
    def angle_columns(self) -> list[str]:
        """Joint-angle column names, ``<joint>_flex``, ``_abd``, ``_rot`` per joint."""
        return [f"{j}_{a}" for j in self.ball_joints for a in ("flex", "abd", "rot")]

    # ------------------------------------------------------------------ configurations
    def _neutral_on_floor(self) -> np.ndarray:
        q = pin.neutral(self.model)
        contacts = [s.frame_id for s in self._sites.values() if s.kind == "contact"]
        if contacts:  # vectorised kinematics: no pinocchio.Data to allocate (milliseconds)
            p, _ = frame_placements(self.model, q, contacts)
            q[2] = -float(p[0, :, 2].min())
        return q

    def neutral(self) -> np.ndarray:
        """The N-pose: every joint at zero, facing +X, contact points on z = 0."""
        return self._q_neutral.copy()

    def configuration(self, angles_deg: Mapping[str, float] | None = None,
                      p_world_pelvis: npt.ArrayLike | None = None,
                      R_world_pelvis: npt.ArrayLike | None = None) -> np.ndarray:
        """A configuration from anatomical joint angles and the pelvis pose.

        Args:
            angles_deg: ``{"jRightKnee_flex": 30.0, ...}`` [deg]; absent angles are zero.
            p_world_pelvis: Pelvis origin [m]; the N-pose height when omitted.
            R_world_pelvis: Pelvis orientation; identity (facing +X) when omitted.

        Returns:
            ``q`` of size ``model.nq``.
        """
        q = self.neutral()
        if p_world_pelvis is not None:
            q[:3] = np.asarray(p_world_pelvis, dtype=float)
        if R_world_pelvis is not None:
            q[3:7] = wxyz_to_xyzw(matrix_to_quat_wxyz(R_world_pelvis))
        angles = dict(angles_deg or {})
        valid = set(self.angle_columns)
        for key in angles:
            if key not in valid:
                raise NameNotFound("joint angle", key, valid)
        for joint in self.ball_joints.values():
            a = np.radians([angles.get(joint.spec.column(s.name), 0.0) for s in joint.spec.angles])
            R = joint.spec.rotation(a)
            q[joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(matrix_to_quat_wxyz(R))
        return q

    def joint_rotations(self, q: npt.ArrayLike) -> dict[str, np.ndarray]:
        """``R_parent_child`` of every ball joint at ``q``."""
        qq = np.asarray(q, dtype=float)
        return {name: quat_wxyz_to_matrix(xyzw_to_wxyz(qq[j.idx_q:j.idx_q + 4]))
                for name, j in self.ball_joints.items()}

    def joint_angles(self, q: npt.ArrayLike,
                     previous: Mapping[str, float] | None = None) -> dict[str, float]:
        """Anatomical joint angles [deg] at ``q``, keys like ``jRightKnee_flex``.

        Args:
            q: The configuration.
            previous: The previous frame's angles [deg] (live use, causal): each joint then
                takes the Euler triple of its rotation closest to them (no +-360 deg wrap, no
                jump between the two Euler branches near ``|middle| = 90`` deg). Without it,
                the principal triple (middle angle in [-90, 90] deg, the others in
                (-180, 180] deg).
        """
        out: dict[str, float] = {}
        for name, R in self.joint_rotations(q).items():
            spec = self.ball_joints[name].spec
            values = spec.angles_from_rotation(R)
            columns = [spec.column(a.name) for a in spec.angles]
            if previous is not None and all(c in previous for c in columns):
                values, _ = nearest_equivalent(values, np.radians([previous[c] for c in columns]))
            for column, value in zip(columns, np.degrees(values)):
                out[column] = float(value)
        return out

    def joint_angle_matrix(self, qs: npt.ArrayLike, continuous: bool = True,
                           joints: Sequence[str] | None = None,
                           rotations: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """Joint angles [deg] of a series of configurations, shape (N, 3 * joints).

        Columns follow :attr:`angle_columns` (flex, abd, rot per joint), or, with ``joints``,
        those of the joints named (in that order; each joint's values are the same). The series is
        continuous (:func:`~ikfusion.model.angle_continuity.continuous_series`): the first frame
        takes the principal triple, every later one the triple closest to the frame before, so
        spins, arms overhead and high kicks neither wrap by 360 deg nor jump between the Euler
        branches.

        Args:
            qs: (N, nq) configurations in time order.
            continuous: False for each frame's principal triple on its own.
            joints: Names of :attr:`ball_joints` (None: all of them).
            rotations: Joint name -> its ``R_parent_child`` (N, 3, 3) along ``qs`` when already
                computed from them (``quat_wxyz_to_matrix`` of its quaternion, as here); the
                angles are the same.
        """
        Q = np.atleast_2d(np.asarray(qs, dtype=float))
        chosen = list(self.ball_joints.values()) if joints is None else \
            [self.ball_joints[name] for name in joints]
        out = np.empty((Q.shape[0], 3 * len(chosen)))
        for k, joint in enumerate(chosen):
            R = quat_wxyz_to_matrix(xyzw_to_wxyz(Q[:, joint.idx_q:joint.idx_q + 4])) \
                if rotations is None else np.ascontiguousarray(rotations[joint.spec.name])
            angles = joint.spec.angles_from_rotation(R)
            if continuous:
                angles = continuous_series(angles)
            order = [("flex", "abd", "rot").index(a.name) for a in joint.spec.angles]
            out[:, 3 * k + np.array(order)] = np.degrees(angles)
        return out

    def revolute_to_spherical(self, q_revolute: npt.ArrayLike) -> np.ndarray:
        """Map a configuration of :attr:`revolute_model` to the ball-joint model (exact)."""
        qr = np.asarray(q_revolute, dtype=float)
        q = pin.neutral(self.model)
        rev = self.revolute_model
        merged = {j for b in self.ball_joints.values() for j in b.revolute_ids}
        for j in range(1, rev.njoints):
            if j in merged:
                continue
            jn = self.joint_map[j]
            q[self.model.idx_qs[jn]:self.model.idx_qs[jn] + rev.nqs[j]] = \
                qr[rev.idx_qs[j]:rev.idx_qs[j] + rev.nqs[j]]
        for joint in self.ball_joints.values():
            a = np.array([qr[rev.idx_qs[j]] for j in joint.revolute_ids])
            q[joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(matrix_to_quat_wxyz(
                joint.spec.rotation(a)))
        return q

    def random_configuration(self, rng: np.random.Generator, margin_deg: float = 0.0,
                             p_world_pelvis: npt.ArrayLike | None = None) -> np.ndarray:
        """A configuration with every anatomical angle uniform inside its range of motion.

        Args:
            rng: Random generator.
            margin_deg: Stay this far inside each limit [deg] (at most a quarter of the range).
            p_world_pelvis: Pelvis position; the N-pose height when omitted. The pelvis
                orientation is a uniformly random heading.
        """
        angles = {}
        for joint in self.ball_joints.values():
            for a in joint.spec.angles:
                inside = min(margin_deg, 0.25 * (a.upper_deg - a.lower_deg))  # narrow ranges
                angles[joint.spec.column(a.name)] = rng.uniform(a.lower_deg + inside,
                                                                a.upper_deg - inside)
        yaw = rng.uniform(-np.pi, np.pi)
        R = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0],
                      [0.0, 0.0, 1.0]])
        return self.configuration(angles, p_world_pelvis=p_world_pelvis, R_world_pelvis=R)

    # ------------------------------------------------------------------ kinematics
    def forward(self, q: npt.ArrayLike) -> pin.Data:
        """Run forward kinematics of every frame at ``q``; returns the internal data."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return self.data

    def segment_rotation(self, q: npt.ArrayLike, name: str) -> np.ndarray:
        """``R_world_segment`` at ``q``."""
        fid = self.segment_frame_id(name)
        return self.forward(q).oMf[fid].rotation.copy()

    def segment_position(self, q: npt.ArrayLike, name: str) -> np.ndarray:
        """Segment origin ``p_world_segment`` [m] at ``q``."""
        fid = self.segment_frame_id(name)
        return self.forward(q).oMf[fid].translation.copy()

    def site_position(self, q: npt.ArrayLike, name: str) -> np.ndarray:
        """``p_world_site`` [m] at ``q``."""
        fid = self.site_frame_id(name)
        return self.forward(q).oMf[fid].translation.copy()

    def summary(self) -> str:
        """A few lines describing the model (sizes and names)."""
        m = self.model
        height = f"{self.body.height:.2f} m body, " if self.body is not None else ""
        return (
            f"{m.name}: {height}{len(self._segments)} segments, {len(self.ball_joints)} ball "
            f"joints + free-flyer, nq = {m.nq}, nv = {m.nv}, {len(self._sites)} sites\n"
            f"  URDF: {self.urdf_path}\n"
            f"  sites: {', '.join(self._sites)}"
        )


@lru_cache(maxsize=16)
def _model_of_body(body: Body) -> HumanModel:
    """The model of ``body`` from its URDF text, kept for equal bodies.

    A few per process (a batch's clips of one subject share one), and on disk keyed by what
    the URDF text is made of (:mod:`~ikfusion.model.model_cache`): a fresh process loads it
    instead of building it (or writing its URDF text), with the same result to the bit.
    """
    folder = entry_folder(body)
    cached = load_entry(folder)
    tables = None if cached is None else cached[1]
    if cached is not None and tables is not None and tables["body"] == body:
        model, revolute = cached[0]
        return HumanModel._from_parts(model, revolute, tables)
    built = HumanModel._from_urdf_text(body_to_urdf(body), body)
    store_entry(folder, dict(zip(HUMAN_MODEL_FILES, (built.model, built.revolute_model))),
                {name: getattr(built, name) for name in TABLE_ATTRIBUTES})
    return built


def _in_spec_order(ball_joints: dict[str, BallJoint]) -> dict[str, BallJoint]:
    """The human joints in SPEC order (model order for any other URDF)."""
    if not all(j in ball_joints for j in JOINTS):
        return ball_joints
    rest = [j for j in ball_joints if j not in JOINTS]
    return {j: ball_joints[j] for j in (*JOINTS, *rest)}


def _look_up(table: Mapping[str, V], kind: str, name: str) -> V:
    """``table[name]``, or :class:`NameNotFound` listing the ``kind`` names of ``table``."""
    try:
        return table[name]
    except KeyError:
        raise NameNotFound(kind, name, table) from None
