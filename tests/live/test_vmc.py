"""VMC over OSC out: decoded with python-osc's dispatcher, the bones rebuild the poses."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pythonosc", reason="the live extra (python-osc) is not installed")
from pythonosc.dispatcher import Dispatcher  # noqa: E402
from pythonosc.osc_server import BlockingOSCUDPServer  # noqa: E402

from ikfusion.live.vmc import VmcSink  # noqa: E402

#: Unity's humanoid hierarchy (HumanBodyBones), child -> parent, for the bones VMC sends.
UNITY_PARENT = {
    "Spine": "Hips", "Chest": "Spine", "UpperChest": "Chest", "Neck": "UpperChest",
    "Head": "Neck",
    **{f"{s}{b}": f"{s}{p}" for s in ("Left", "Right") for b, p in (
        ("UpperArm", "Shoulder"), ("LowerArm", "UpperArm"), ("Hand", "LowerArm"),
        ("LowerLeg", "UpperLeg"), ("Foot", "LowerLeg"), ("Toes", "Foot"))},
    "LeftShoulder": "UpperChest", "RightShoulder": "UpperChest",
    "LeftUpperLeg": "Hips", "RightUpperLeg": "Hips",
}
OURS = {"Hips": "Pelvis", "Spine": "L5", "Chest": "T12", "UpperChest": "T8", "Neck": "Neck",
        "Head": "Head", **{f"{s}{u}": f"{s}{o}" for s in ("Left", "Right") for u, o in (
            ("Shoulder", "Shoulder"), ("UpperArm", "UpperArm"), ("LowerArm", "ForeArm"),
            ("Hand", "Hand"), ("UpperLeg", "UpperLeg"), ("LowerLeg", "LowerLeg"),
            ("Foot", "Foot"), ("Toes", "Toe"))}}
# Unity (x right, y up, z forward) from ours (x forward, y left, z up)
M = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def quat_xyzw_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def world_bones(local: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict:
    """Unity world (position, rotation) of every bone from the local transforms."""
    world: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def resolve(bone: str) -> tuple[np.ndarray, np.ndarray]:
        if bone not in world:
            p, R = local[bone]
            if bone in UNITY_PARENT:
                pp, Rp = resolve(UNITY_PARENT[bone])
                p, R = pp + Rp @ p, Rp @ R
            world[bone] = (p, R)
        return world[bone]

    for bone in local:
        resolve(bone)
    return world


@pytest.fixture
def vmc_server():
    frames: list[dict] = []

    def on_bone(address, name, *values):
        frames[-1]["bones"][name] = (np.array(values[:3]), quat_xyzw_matrix(values[3:]))

    def on_time(address, t):
        frames.append({"t": t, "bones": {}})

    dispatcher = Dispatcher()
    dispatcher.map("/VMC/Ext/T", on_time)
    dispatcher.map("/VMC/Ext/Bone/Pos", on_bone)
    dispatcher.map("/VMC/Ext/Root/Pos", lambda a, *v: frames[-1].update(root=v))
    dispatcher.map("/VMC/Ext/OK", lambda a, *v: frames[-1].update(ok=v) if frames else None)
    server = BlockingOSCUDPServer(("127.0.0.1", 0), dispatcher)
    server.timeout = 2.0
    yield server, frames
    server.server_close()


def test_vmc_bones_rebuild_the_result_folder_poses(result_poses, vmc_server) -> None:
    server, frames = vmc_server
    sink = VmcSink("127.0.0.1", server.server_address[1])
    for pose in result_poses:
        sink.send([pose])
        server.handle_request()
    sink.close()
    assert len(frames) == len(result_poses)
    for pose, frame in zip(result_poses, frames):
        assert abs(frame["t"] - pose.time_s) < 1e-4
        assert frame["root"] == ("root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
        assert set(frame["bones"]) == set(OURS)
        world = world_bones(frame["bones"])
        for bone, (p_u, R_u) in world.items():
            i = pose.segments.index(OURS[bone])
            np.testing.assert_allclose(M.T @ p_u, pose.p_world_segment[i], atol=1e-4)
            # the bone's rest is the T-pose: its rotation times the T-pose-to-segment turn
            R_ours = M.T @ R_u @ M
            arm = OURS[bone][4 if bone.startswith("Left") else 5:]
            if arm in ("UpperArm", "ForeArm", "Hand"):
                sign = 1.0 if bone.startswith("Left") else -1.0
                c, s = 0.0, sign
                R_ours = R_ours @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
            np.testing.assert_allclose(R_ours, pose.R_world_segment[i], atol=1e-4)


def test_vmc_frame_is_unity_y_up_and_arms_hang_from_a_t_pose(result_poses, vmc_server) -> None:
    server, frames = vmc_server
    sink = VmcSink("127.0.0.1", server.server_address[1])
    sink.send([result_poses[0]])  # standing still at the start of the walk
    server.handle_request()
    world = world_bones(frames[0]["bones"])
    assert world["Head"][0][1] > world["Hips"][0][1] + 0.4  # y is up
    assert world["LeftToes"][0][2] > world["LeftFoot"][0][2]  # toes point +z
    assert world["LeftUpperArm"][0][0] < world["RightUpperArm"][0][0]  # x is right
    # a T-pose arm points sideways (left: -x, right: +x); standing, the bones turn it down
    for bone, along in (("LeftUpperArm", [-1.0, 0, 0]), ("RightUpperArm", [1.0, 0, 0])):
        assert (world[bone][1] @ along)[1] < -0.9


def test_vmc_sends_only_the_chosen_actor(result_poses, vmc_server) -> None:
    import dataclasses

    server, frames = vmc_server
    other = dataclasses.replace(result_poses[0], actor="B", character_id=1,
                                p_world_segment=result_poses[0].p_world_segment + 5.0)
    sink = VmcSink("127.0.0.1", server.server_address[1], actor="B")
    sink.send([result_poses[0], other])
    server.handle_request()
    assert sink.sent == 1
    hips = world_bones(frames[0]["bones"])["Hips"][0]
    np.testing.assert_allclose(M.T @ hips, other.p_world_segment[0], atol=1e-4)


def test_missing_python_osc_is_a_clear_error(monkeypatch) -> None:
    import sys

    from ikfusion.errors import InputError

    monkeypatch.setitem(sys.modules, "pythonosc", None)
    with pytest.raises(InputError, match="python-osc"):
        VmcSink("127.0.0.1", 9)
