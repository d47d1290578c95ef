"""What a retarget writes (SPEC section 5) and the metrics it reports.

``robot_motion.npz``: ``fps``, ``root_pos`` (N, 3) [m], ``root_quat_wxyz`` (N, 4), ``dof_pos``
(N, n) [rad] (metres for a prismatic joint), ``dof_names``, ``contacts`` (N, k) bool,
``contact_frames``; ``robot_motion.csv`` (one row a frame; every column name that carries a
unit says it: ``frame,time_s,root_x_m,root_y_m,root_z_m,root_qw,root_qx,root_qy,root_qz``, then
``<dof>_rad`` (``_m`` for a prismatic joint), e.g. ``jRightKnee_flex_rad`` for the human model,
then ``<contact frame>_planted`` as 0/1); ``summary.json`` (the metrics); for the human model
also ``motion.bvh`` (the retargeted body for animation tools, as ``solve`` writes it); with
``gmr`` also ``robot_motion.pkl``, the layout RL tracking pipelines read (``fps``,
``root_pos``, ``root_rot`` as x, y, z, w, ``dof_pos``). The folder appears whole or not at all.
"""

from __future__ import annotations

import json
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..app.evaluate import phase_slides
from ..atomic import atomic_folder
from ..ik.limits import JointRangeLimit
from ..ik.pose import Motion
from ..mocap.model_motion import frame_poses, site_positions
from ..results.bvh_export import write_motion_bvh
from ..rotations import angle_between, wxyz_to_xyzw, xyzw_to_wxyz
from .capsules import CapsulePairs
from .robot import RobotTrajectory
from .source import HumanMotion


@dataclass
class RobotMotion:
    """A retargeted motion in the robot-motion layout (see the module docstring).

    ``dof_units`` gives each dof's unit (``rad``, or ``m`` for a prismatic joint); empty means
    ``rad`` for all. ``human`` is the motion of the human model when that is the target (then
    ``motion.bvh`` is written too).
    """

    fps: float
    root_pos: np.ndarray
    root_quat_wxyz: np.ndarray
    dof_pos: np.ndarray
    dof_names: list[str]
    contacts: np.ndarray
    contact_frames: list[str]
    dof_units: list[str] = field(default_factory=list)
    human: Motion | None = None

    def csv_header(self) -> list[str]:
        """Column names of ``robot_motion.csv``, each with its unit where one applies."""
        units = self.dof_units or ["rad"] * len(self.dof_names)
        return (["frame", "time_s", "root_x_m", "root_y_m", "root_z_m", "root_qw", "root_qx",
                 "root_qy", "root_qz"] + [f"{n}_{u}" for n, u in zip(self.dof_names, units)]
                + [f"{c}_planted" for c in self.contact_frames])


def human_robot_motion(motion: Motion) -> RobotMotion:
    """A motion of the human model in the robot layout.

    Its dofs are the URDF's revolute joints, whose positions are the anatomical angles
    (``<joint>_flex/_abd/_rot``) [rad].
    """
    return RobotMotion(motion.rate, motion.q[:, :3].copy(), xyzw_to_wxyz(motion.q[:, 3:7]),
                       np.radians(motion.joint_angles()), list(motion.model.angle_columns),
                       motion.contacts.astype(bool), list(motion.contact_names),
                       human=motion)


def human_metrics(motion: Motion, source: HumanMotion, seconds: float,
                  max_joint_velocity: float) -> dict[str, Any]:
    """Limits, velocities, foot slide, floor penetration and tracking of a human target."""
    model = motion.model
    limits = JointRangeLimit(model.ball_joints, margin_deg=0.0)  # only violations are read
    over = np.array([limits.violation_deg(q).max() for q in motion.q])
    rates = np.abs(np.diff(np.radians(motion.joint_angles()), axis=0)) * motion.rate
    points = site_positions(model, motion.q, list(source.contact_names))
    slides = 1e3 * np.array(phase_slides(points, source.contacts)) if source.contacts.any() \
        else np.zeros(1)
    index = {s: i for i, s in enumerate(source.segments)}
    tracking = {}
    for s in model.segment_names:
        if s in index:
            R = np.array([model.segment_rotation(q, s) for q in motion.q])
            err = np.degrees(angle_between(R, source.R_world_segment[:, index[s]]))
            tracking[s] = float(np.sqrt(np.mean(err ** 2)))
    return {
        "frames": len(motion), "fps": motion.rate,
        "frames_per_second": len(motion) / seconds if seconds > 0 else None,
        "joint_limit_violations": int((over > 1e-3).sum()),  # beyond QP round-off [deg]
        "joint_limit_worst_deg": float(over.max()),
        "velocity_limit_violations": int((rates > max_joint_velocity).sum()),
        "velocity_worst_rad_s": float(rates.max()) if rates.size else 0.0,
        "foot_slide_mm_mean": float(slides.mean()), "foot_slide_mm_max": float(slides.max()),
        "floor_penetration_mm_max": float(max(0.0, -1e3 * points[..., 2].min())),
        "self_collision_min_distance_m": None,
        "tracking_orientation_rms_deg": tracking,
        "relaxed_frames": int(motion.relaxed.sum()), "warnings": list(motion.warnings),
    }


def robot_robot_motion(trajectory: RobotTrajectory) -> RobotMotion:
    """A robot trajectory in the robot layout (contacts: the two feet's links, planted)."""
    q = trajectory.q
    model = trajectory.robot.model
    units = ["m" if "Prismatic" in model.joints[model.getJointId(n)].shortname() else "rad"
             for n in trajectory.robot.dof_names]
    return RobotMotion(trajectory.rate, q[:, :3].copy(), xyzw_to_wxyz(q[:, 3:7]),
                       q[:, 7:].copy(), list(trajectory.robot.dof_names),
                       trajectory.planted.copy(),
                       [trajectory.robot.config.feet[s].link for s in ("left", "right")],
                       dof_units=units)


def robot_metrics(trajectory: RobotTrajectory, seconds: float) -> dict[str, Any]:
    """Limits, velocities, foot slide, floor penetration, self-collision and tracking.

    Foot slide is measured on the sole corners over the robot's planted phases; velocities
    are frame-to-frame joint differences times the frame rate [rad/s].
    """
    robot = trajectory.robot
    model = robot.model
    dofs = trajectory.q[:, 7:]
    over = np.maximum(robot.lower - dofs, dofs - robot.upper)
    rates = np.abs(np.diff(dofs, axis=0)) * trajectory.rate
    too_fast = rates - robot.max_velocity
    pairs = CapsulePairs(robot.config.capsules, robot.config.collision_pairs, robot.frame_ids,
                         activation=np.inf)
    feet = [robot.config.feet["left"], robot.config.feet["right"]]
    links = {n: robot.frame_ids[n.split("->")[1]]
             for n in (*trajectory.link_targets, *trajectory.position_targets)}
    ids = sorted({*pairs.links, *links.values(), *(robot.frame_ids[f.link] for f in feet)})
    column = {f: i for i, f in enumerate(ids)}
    p_world, R_world = frame_poses(model, trajectory.q, ids)
    points = np.concatenate([
        np.einsum("nij,cj->nci", R_world[:, column[robot.frame_ids[foot.link]]], foot.corners)
        + p_world[:, column[robot.frame_ids[foot.link]], None] for foot in feet], axis=1)
    capsule_links = [column[f] for f in pairs.links]
    closest = pairs.min_distance(R_world[:, capsule_links], p_world[:, capsule_links])
    orientation_err = {n: angle_between(R_world[:, column[links[n]]], R)
                       for n, R in trajectory.link_targets.items()}
    position_err = {n: np.linalg.norm(p_world[:, column[links[n]]] - p, axis=1)
                    for n, p in trajectory.position_targets.items()}
    planted = np.repeat(trajectory.planted, 4, axis=1)
    slides = 1e3 * np.array(phase_slides(points, planted) or [0.0])
    return {
        "robot": robot.name, "dofs": len(robot.dof_names), "scale": trajectory.scale,
        "frames": len(trajectory.q), "fps": trajectory.rate,
        "frames_per_second": len(trajectory.q) / seconds if seconds > 0 else None,
        "joint_limit_violations": int((over > 1e-6).sum()),  # beyond QP round-off [rad]
        "joint_limit_worst_rad": float(max(0.0, over.max())),
        "velocity_limit_violations": int((too_fast > 1e-6).sum()),
        "velocity_worst_rad_s": float(rates.max()) if rates.size else 0.0,
        "foot_slide_mm_mean": float(slides.mean()), "foot_slide_mm_max": float(slides.max()),
        "floor_penetration_mm_max": float(max(0.0, -1e3 * points[..., 2].min())),
        "self_collision_min_distance_m": closest,
        "tracking_orientation_rms_deg": {n: float(np.degrees(np.sqrt(np.mean(np.square(e)))))
                                         for n, e in orientation_err.items()},
        "tracking_position_rms_cm": {n: float(100 * np.sqrt(np.mean(np.square(e))))
                                     for n, e in position_err.items()},
        "relaxed_frames": int(trajectory.relaxed.sum()),
        "warnings": list(trajectory.warnings),
    }


def write_robot_motion(out_dir: str | Path, robot: RobotMotion, summary: dict[str, Any],
                       gmr: bool = False, force: bool = False, bvh_up: str = "z") -> Path:
    """Write the output folder (replacing one ikfusion wrote, or any with ``force``).

    Args:
        out_dir: The folder.
        robot: The motion; with :attr:`RobotMotion.human` also ``motion.bvh``.
        summary: The metrics (``summary.json``).
        gmr: Also write ``robot_motion.pkl``.
        force: Replace ``out_dir`` even when ikfusion did not write it.
        bvh_up: Up axis of ``motion.bvh`` (``"z"`` or ``"y"`` for Y-up tools).
    """
    with atomic_folder(out_dir, "retarget", force) as tmp:
        np.savez(tmp / "robot_motion.npz", fps=robot.fps, root_pos=robot.root_pos,
                 root_quat_wxyz=robot.root_quat_wxyz, dof_pos=robot.dof_pos,
                 dof_names=np.array(robot.dof_names), contacts=robot.contacts,
                 contact_frames=np.array(robot.contact_frames))
        n = len(robot.root_pos)
        header = robot.csv_header()
        table = np.column_stack([np.arange(n), np.arange(n) / robot.fps, robot.root_pos,
                                 robot.root_quat_wxyz, robot.dof_pos, robot.contacts])
        (tmp / "robot_motion.csv").write_text(_csv_text(header, table))
        if robot.human is not None:
            write_motion_bvh(tmp / "motion.bvh", robot.human.model, robot.human.q,
                             1.0 / robot.fps, up=bvh_up)
        if gmr:
            with (tmp / "robot_motion.pkl").open("wb") as f:
                pickle.dump({"fps": robot.fps, "root_pos": robot.root_pos,
                             "root_rot": wxyz_to_xyzw(robot.root_quat_wxyz),
                             "dof_pos": robot.dof_pos}, f)
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2))
    return Path(out_dir)


def _csv_text(header: list[str], table: np.ndarray) -> str:
    """``header`` and ``table`` (N, len(header)) as CSV, six decimals, in one formatting pass.

    The same text as ``np.savetxt(..., delimiter=",", fmt="%.6f", comments="")``, which
    formats and writes row by row.
    """
    row = ",".join(["%.6f"] * table.shape[1]) + "\n"
    return ",".join(header) + "\n" + (row * len(table)) % tuple(table.ravel().tolist())
