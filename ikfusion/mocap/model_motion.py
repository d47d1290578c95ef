"""A motion of the human model and its kinematics: segment poses, site positions, contacts.

Simulation builds its ground truth on it (:mod:`ikfusion.sim`), and real-data code reads motion
capture onto it (:mod:`ikfusion.mocap.from_bvh`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from ..model.human_model import HumanModel
from ..model.layout import TRUNK_CONTACT_SITES
from ..model.motion_kinematics import JointRotations, frame_placements


@dataclass
class TruthMotion:
    """A motion of the model that simulated sensors are computed from.

    Attributes:
        model: The human model it moves.
        time: (N,) [s].
        q: (N, nq) configurations.
        contact_names: Contact points (columns of ``contacts``).
        contacts: (N, k) true contact phases.
        source: Where it came from (``gait:circle``, a BVH path, ...).
        info: Anything else worth keeping (gait parameters, BVH mapping notes).
    """

    model: HumanModel
    time: np.ndarray
    q: np.ndarray
    contact_names: list[str]
    contacts: np.ndarray
    source: str = ""
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def rate(self) -> float:
        """Sample rate [Hz]."""
        return float(1.0 / np.mean(np.diff(self.time))) if len(self.time) > 1 else 0.0


def moved_configurations(q: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Configurations (N, nq) of a free-flyer model moved rigidly: ``p -> R p + t``.

    The root position and orientation turn by ``R`` (3, 3) and shift by ``t`` (3,) [m];
    joint coordinates are unchanged.
    """
    out = q.copy()
    out[:, :3] = q[:, :3] @ np.asarray(R).T + np.asarray(t)
    for k in range(len(q)):
        out[k, 3:7] = pin.Quaternion(R @ pin.Quaternion(q[k, 3:7]).matrix()).coeffs()
    return out


def limb_contact_sites(model: HumanModel) -> list[str]:
    """The contact sites at the ends of the limbs: heels, toes, knees, palms.

    A truth's floor is fitted to these and its planted points locked with these, never with
    the points where a lying body rests (:data:`~ikfusion.model.TRUNK_CONTACT_SITES`): those
    are the model's guess of the trunk's surface (how deep the back lies behind the joints),
    the very guess the solver makes, so a truth shaped by them would agree with the solver by
    construction; a mocap clip's body ends where its bones do, at its feet and hands.
    """
    return [n for n in model.sites_of_kind("contact") if n not in TRUNK_CONTACT_SITES]


def contact_phases(model: HumanModel, q: np.ndarray, time: np.ndarray,
                   names: list[str], height: float = 0.03, speed: float = 0.3) -> np.ndarray:
    """Contact phases from kinematics: a point near the floor (z = 0) that is nearly still."""
    return contact_phases_from_points(site_positions(model, q, names), time, height, speed)


def contact_phases_from_points(P: np.ndarray, time: np.ndarray, height: float = 0.03,
                               speed: float = 0.3) -> np.ndarray:
    """(N, k) contact phases of points (N, k, 3) [m].

    A point is in contact below ``height`` [m] and slower than ``speed`` [m/s].
    """
    if len(time) < 2:
        return P[..., 2] < height
    v = np.linalg.norm(np.gradient(P, float(np.mean(np.diff(time))), axis=0), axis=2)
    return (P[..., 2] < height) & (v < speed)


def frame_poses(model: pin.Model, q: np.ndarray, frame_ids: list[int],
                rotations: JointRotations | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World origins (N, F, 3) [m] and rotations (N, F, 3, 3) of frames along ``q`` (N, nq).

    ``R_world_frame`` and ``p_world_frame`` of the Pinocchio frames ``frame_ids``, in that
    order; each joint is composed for all configurations at once
    (:func:`~ikfusion.model.motion_kinematics.frame_placements`, Pinocchio's results to rounding;
    ``rotations`` keeps the joints' rotations between queries of one motion moved by its root's
    translation only).
    """
    return frame_placements(model, q, frame_ids, rotations)


def segment_poses(model: HumanModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every segment's world origin (N, S, 3) [m] and rotation (N, S, 3, 3) along ``q``.

    Segments in ``model.segment_names`` order; ``q`` is (N, nq).
    """
    return frame_poses(model.model, q, [model.segment_frame_id(s) for s in model.segment_names])


def site_positions(model: HumanModel, q: np.ndarray, names: list[str],
                   rotations: JointRotations | None = None) -> np.ndarray:
    """World positions (N, k, 3) [m] of sites along configurations (N, nq) (:func:`frame_poses`)."""
    return frame_poses(model.model, q, [model.site_frame_id(n) for n in names], rotations)[0]
