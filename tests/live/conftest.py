"""Fixtures of the live wire-format tests: a small solved result folder and its poses."""

from __future__ import annotations

import csv
import socket
from pathlib import Path

import numpy as np
import pytest

from ikfusion.ik import Motion
from ikfusion.live.actor_pose import ActorPose
from ikfusion.model import HumanModel
from ikfusion.results import write_result_folder
from ikfusion.rotations import quat_wxyz_to_matrix
from ikfusion.sim.gait import GaitParameters, generate_gait


def segment_parents(model: HumanModel) -> tuple[int, ...]:
    """Index of each segment's parent segment in the model's joint tree (-1 for the root)."""
    pm = model.model
    joint_of = {name: pm.frames[model.segment_frame_id(name)].parentJoint
                for name in model.segment_names}
    segment_of_joint = {j: i for i, j in enumerate(joint_of.values())}
    return tuple(segment_of_joint.get(pm.parents[joint_of[name]], -1)
                 for name in model.segment_names)


def read_result_folder(folder: Path, parents: tuple[int, ...], actor: str = "A",
                       character_id: int = 0) -> list[ActorPose]:
    """The ActorPose of every frame of a result folder (segments.csv, joint_angles.csv)."""
    with (folder / "segments.csv").open() as f:
        rows = list(csv.DictReader(f))
    with (folder / "joint_angles.csv").open() as f:
        reader = csv.reader(f)
        header = next(reader)
        angles = np.array([[float(v) for v in row] for row in reader])
    segments = tuple(dict.fromkeys(r["segment"] for r in rows))
    n_seg = len(segments)
    poses = []
    for k in range(len(rows) // n_seg):
        block = rows[k * n_seg:(k + 1) * n_seg]
        p = np.array([[float(r["px"]), float(r["py"]), float(r["pz"])] for r in block])
        q = np.array([[float(r[c]) for c in ("qw", "qx", "qy", "qz")] for r in block])
        poses.append(ActorPose(actor=actor, character_id=character_id,
                               time_s=float(block[0]["time"]), frame=k, segments=segments,
                               parents=parents, p_world_segment=p,
                               R_world_segment=quat_wxyz_to_matrix(q),
                               joint_names=tuple(header[1:]), joint_angles_deg=angles[k, 1:]))
    return poses


@pytest.fixture(scope="session")
def result_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A result folder of a 1.2 s simulated walk at 30 Hz (written by write_result_folder)."""
    model = HumanModel.default()
    walk = generate_gait(model, GaitParameters(duration=1.2, stand=0.2), rate=30.0)
    n = len(walk.time)
    motion = Motion(walk.model, walk.time, walk.q, walk.contact_names, walk.contacts,
                    np.zeros(n), np.ones(n, dtype=int), np.zeros(n, dtype=bool))
    return write_result_folder(motion, tmp_path_factory.mktemp("live") / "result")


@pytest.fixture(scope="session")
def result_poses(result_folder: Path) -> list[ActorPose]:
    """The result folder's frames as ActorPose values (actor "A", character 0)."""
    return read_result_folder(result_folder, segment_parents(HumanModel.default()))


@pytest.fixture
def udp_receiver():
    """A UDP socket bound to a free localhost port, with a receive timeout of 2 s."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    yield sock
    sock.close()
