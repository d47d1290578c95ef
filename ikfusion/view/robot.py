"""A ``retarget`` output folder as a viewer actor: the robot (or the resized human) in motion.

``robot_motion.npz`` holds the root pose and joint positions per frame; ``summary.json`` says
which body they belong to (``robot``, ``config``, ``height_m``). The body is rebuilt and its
forward kinematics give what the viewer draws: for a robot, every joint frame as a segment
(bones join each joint to its children) and the sole corners as contact points, lit while the
foot is planted; for the human model, its segments and contact points. A robot also gets the
visual meshes of its URDF with the pose of each link that carries one, so that it is drawn as
built (its joint sticks stay one click away). Joint curves are the robot's joint positions
[deg] (the human's anatomical angles).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InputError
from ..io.npz import read_npz
from ..rotations import matrix_to_quat_wxyz, quat_wxyz_to_matrix
from .robot_meshes import link_poses, visual_meshes
from .scene import Actor, LinkMeshes


def is_retarget_folder(folder: Path) -> bool:
    """Whether ``folder`` holds the ``robot_motion.npz`` of a retarget output."""
    return (folder / "robot_motion.npz").is_file()


def load_retarget_actor(folder: str | Path, name: str = "robot") -> Actor:
    """One actor from a ``retarget`` output folder.

    Raises:
        InputError: The summary does not say which body moved, or the files are malformed.
    """
    root = Path(folder)
    summary_file = root / "summary.json"
    try:
        summary = json.loads(summary_file.read_text())
    except FileNotFoundError:
        raise InputError("missing file", path=summary_file) from None
    except json.JSONDecodeError as err:
        raise InputError(f"invalid JSON: {err.msg}", path=summary_file, line=err.lineno) from None
    data = read_npz(root / "robot_motion.npz", ("fps", "root_pos", "root_quat_wxyz", "dof_pos"),
                    "robot_motion.npz")
    robot = summary.get("robot")
    if robot == "human":
        return _human_actor(data, float(summary["height_m"]), name)
    if not robot:
        raise InputError("summary.json does not name the robot", path=summary_file,
                         field="robot")
    return _robot_actor(data, str(robot), summary.get("config"), name)


def _time(data: dict[str, np.ndarray]) -> np.ndarray:
    return np.arange(len(data["root_pos"])) / float(data["fps"])


def _robot_actor(data: dict[str, np.ndarray], robot: str, config_file: str | None,
                 name: str) -> Actor:
    from ..retarget.robot_config import load_retarget_config
    from ..retarget.robot_model import RobotModel

    model = RobotModel(load_retarget_config(robot, config_file))
    pin_model = model.model
    pin_data = pin_model.createData()
    n = len(data["root_pos"])
    joints = range(1, pin_model.njoints)
    feet = [model.config.feet[side] for side in ("left", "right")]
    P = np.zeros((n, len(joints), 3))
    R = np.zeros((n, len(joints), 3, 3))
    corners = np.zeros((n, 8, 3))
    notes: tuple[str, ...] = ()
    try:
        links, parts, primitives = visual_meshes(pin_model, model.config.urdf)
    except InputError as err:  # the sticks are still worth showing
        links, parts, primitives = [], [], 0
        notes = (f"{robot} drawn without meshes: {err}",)
    if primitives:
        notes += (f"{robot}: {primitives} visual(s) made of primitive shapes are not drawn",)
    p_link = np.zeros((n, len(links), 3))
    R_link = np.zeros((n, len(links), 3, 3))
    for k in range(n):
        q = np.concatenate([data["root_pos"][k], data["root_quat_wxyz"][k, [1, 2, 3, 0]],
                            data["dof_pos"][k]])
        pin.framesForwardKinematics(pin_model, pin_data, q)
        for i, j in enumerate(joints):
            P[k, i] = pin_data.oMi[j].translation
            R[k, i] = pin_data.oMi[j].rotation
        corners[k] = np.concatenate([
            f.corners @ pin_data.oMf[model.frame_ids[f.link]].rotation.T
            + pin_data.oMf[model.frame_ids[f.link]].translation for f in feet])
        p_link[k], R_link[k] = link_poses(pin_data, links)
    meshes = LinkMeshes(tuple(pin_model.frames[f].name for f in links), p_link,
                        matrix_to_quat_wxyz(R_link), tuple(parts)) if parts else None
    sites = tuple(f"{side}_sole_{i}" for side in ("left", "right") for i in range(4))
    return Actor(
        name=name, time=_time(data), segment_names=tuple(pin_model.names[j] for j in joints),
        segment_parents=np.array([pin_model.parents[j] - 1 for j in joints], dtype=int),
        p_world_segment=P, quat_wxyz_world_segment=matrix_to_quat_wxyz(R),
        site_names=sites, p_world_site=corners, contact_names=sites,
        contacts=np.repeat(np.asarray(data["contacts"], dtype=bool), 4, axis=1),
        angle_names=tuple(str(d) for d in data["dof_names"]),
        joint_angles_deg=np.degrees(data["dof_pos"]), meshes=meshes, notes=notes)


def _human_actor(data: dict[str, np.ndarray], height: float, name: str) -> Actor:
    from ..mocap.model_motion import segment_poses, site_positions
    from ..model import Body, HumanModel
    from .load import MODEL_SEGMENT_TIPS, model_parents

    model = HumanModel.from_body(Body.from_height(height))
    names = [str(d) for d in data["dof_names"]]
    angles = np.degrees(data["dof_pos"])
    q = np.array([model.configuration(dict(zip(names, angles[k])), data["root_pos"][k],
                                      quat_wxyz_to_matrix(data["root_quat_wxyz"][k]))
                  for k in range(len(angles))])
    p, R = segment_poses(model, q)
    segments = list(model.segment_names)
    sites = [str(c) for c in data["contact_frames"]] + ["HeadTop"]
    return Actor(
        name=name, time=_time(data), segment_names=tuple(segments),
        segment_parents=model_parents(segments), p_world_segment=p,
        quat_wxyz_world_segment=matrix_to_quat_wxyz(R),
        segment_tips={s: t for s, t in MODEL_SEGMENT_TIPS.items() if t in sites},
        site_names=tuple(sites), p_world_site=site_positions(model, q, sites),
        contact_names=tuple(sites[:-1]), contacts=np.asarray(data["contacts"], dtype=bool),
        angle_names=tuple(names), joint_angles_deg=angles)
