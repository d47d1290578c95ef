"""A humanoid robot for retargeting: the URDF on a free-flyer, its limits and its rest pose.

Frames: world Z up, floor at z = 0; the free-flyer is the URDF's root link. Configuration
``q`` = (root position [m], root quaternion x, y, z, w, joint positions [rad]); tangent ``dq``
= (root linear, root angular, joint velocities) as in Pinocchio.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import ConfigError
from ..model.model_cache import cached_model
from .robot_config import RetargetConfig


class RobotModel:
    """The robot of a :class:`RetargetConfig`, locked joints removed.

    Attributes:
        model: Pinocchio model (free-flyer root).
        dof_names: The actuated joints, in ``q[7:]`` order.
        rest: The rest configuration: the rest pose standing with its soles on the floor,
            facing +x (some URDFs face -x, e.g. iCub).
        lower, upper: Joint position limits (n,) [rad]: the URDF's, narrowed by the config.
        max_velocity: Joint velocity limits (n,) [rad/s] (inf where the URDF gives none).
    """

    def __init__(self, config: RetargetConfig) -> None:
        self.config = config
        self.model = _reduced_model(config)
        self._data: pin.Data | None = None
        self.frame_ids = {}
        names = [f.name for f in self.model.frames]
        wanted = (list(config.links.values()) + [f.link for f in config.feet.values()]
                  + [c.link for c in config.capsules.values()])
        missing = sorted({w for w in wanted if not self.model.existFrame(w)})
        if missing:
            raise ConfigError(f"the URDF {config.urdf.name} has no frame(s) {', '.join(missing)}; "
                              f"frames found: {', '.join(n for n in names if n != 'universe')}",
                              path=config.source, field="links")
        self.frame_ids = {w: self.model.getFrameId(w) for w in wanted}
        joints = [self.model.joints[j] for j in range(2, self.model.njoints)]
        if any(j.nq != 1 or j.nv != 1 for j in joints):
            raise ConfigError("only revolute and prismatic joints are supported beside the root",
                              path=config.urdf)
        self.dof_names = list(self.model.names[2:])
        self.lower = self.model.lowerPositionLimit[7:].copy()
        self.upper = self.model.upperPositionLimit[7:].copy()
        self._narrow_ranges()
        v = self.model.velocityLimit[6:].copy()
        self.max_velocity = np.where(v > 0, v, np.inf)
        self.rest = self._rest_configuration()

    def _narrow_ranges(self) -> None:
        """Apply the config's ``joint_ranges`` (only ever narrower than the URDF's)."""
        for joint, (lower, upper) in self.config.joint_ranges.items():
            key = f"joint_ranges.{joint}"
            if joint not in self.dof_names:
                raise ConfigError(f"no joint {joint!r} in the URDF", path=self.config.source,
                                  field=key)
            i = self.dof_names.index(joint)
            if lower < self.lower[i] - 1e-9 or upper > self.upper[i] + 1e-9:
                raise ConfigError(f"[{lower}, {upper}] is wider than the URDF's "
                                  f"[{self.lower[i]:.4f}, {self.upper[i]:.4f}]",
                                  path=self.config.source, field=key)
            self.lower[i], self.upper[i] = lower, upper

    @property
    def name(self) -> str:
        """The URDF's file name without suffix."""
        return self.config.urdf.stem

    def _rest_configuration(self) -> np.ndarray:
        q = pin.neutral(self.model)
        for joint, value in self.config.rest_pose.items():
            if not self.model.existJointName(joint):
                raise ConfigError(f"no joint {joint!r} in the URDF", path=self.config.source,
                                  field=f"rest_pose.{joint}")
            q[self.model.joints[self.model.getJointId(joint)].idx_q] = value
        q[7:] = np.clip(q[7:], self.lower, self.upper)
        corners = self.sole_corners(q)
        left_of = corners[0].mean(axis=0) - corners[1].mean(axis=0)
        facing = np.arctan2(-left_of[0], left_of[1])  # heading of forward = left x up
        turn = pin.Quaternion(pin.utils.rpyToMatrix(0.0, 0.0, -facing))
        q[3:7] = (turn * pin.Quaternion(q[3:7])).coeffs()  # facing +x, as the human's N-pose
        q[2] -= self.sole_corners(q)[..., 2].min()  # soles on the floor
        return q

    def _kinematics(self) -> pin.Data:
        """The ``pinocchio.Data`` of this model's own queries (created once, ~0.1 ms each).

        Every query recomputes the kinematics it reads, so reusing it changes no result; not
        thread-safe, as Pinocchio's data are not.
        """
        if self._data is None:
            self._data = self.model.createData()
        return self._data

    def placement(self, q: np.ndarray, link: str) -> pin.SE3:
        """``T_world_link`` at ``q``."""
        data = self._kinematics()
        pin.framesForwardKinematics(self.model, data, q)
        return data.oMf[self.frame_ids[link]].copy()

    def sole_corners(self, q: np.ndarray) -> np.ndarray:
        """World positions of both soles' corners (2, 4, 3) [m], left first."""
        data = self._kinematics()
        pin.framesForwardKinematics(self.model, data, q)
        out = []
        for side in ("left", "right"):
            foot = self.config.feet[side]
            T = data.oMf[self.frame_ids[foot.link]]
            out.append(foot.corners @ T.rotation.T + T.translation)
        return np.array(out)

    def hip_height(self) -> float:
        """Height of the hip joints above the floor in the rest pose [m].

        The hips are the parents of the first joints of the two legs' chains: taken as the
        mean height of the joints that carry the foot links, highest ones.
        """
        data = self._kinematics()
        pin.forwardKinematics(self.model, data, self.rest)
        heights = []
        for side in ("left", "right"):
            joint = self.model.frames[self.frame_ids[self.config.feet[side].link]].parentJoint
            chain = []
            while joint > 1:
                chain.append(joint)
                joint = self.model.parents[joint]
            heights.append(data.oMi[chain[-1]].translation[2])
        return float(np.mean(heights))


def _reduced_model(config: RetargetConfig) -> pin.Model:
    """The URDF on a free-flyer with the locked joints removed, built once per content.

    Kept in the user cache (:func:`~ikfusion.model.model_cache.cached_model`) keyed by the
    URDF's bytes and the locked joints' values: a fresh process loads it instead of parsing.
    """
    path = Path(config.urdf)
    try:
        urdf = path.read_bytes()
    except OSError as err:
        raise ConfigError(f"cannot read the URDF: {err}", path=path) from err
    locked = sorted((joint, float(value)) for joint, value in config.locked_joints.items())
    key = f"{hashlib.sha256(urdf).hexdigest()} free-flyer, locked {locked!r}"
    return cached_model("robot_models", key, lambda: _build_reduced_model(config))


def _build_reduced_model(config: RetargetConfig) -> pin.Model:
    path = Path(config.urdf)
    try:
        full = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    except (RuntimeError, ValueError) as err:
        raise ConfigError(f"cannot read the URDF: {err}", path=path) from err
    if not config.locked_joints:
        return full
    q = pin.neutral(full)
    ids = []
    for joint, value in config.locked_joints.items():
        if not full.existJointName(joint):
            raise ConfigError(f"no joint {joint!r} in the URDF", path=config.source,
                              field=f"locked_joints.{joint}")
        jid = full.getJointId(joint)
        q[full.joints[jid].idx_q] = value
        ids.append(jid)
    return pin.buildReducedModel(full, ids, q)
