"""MVN network streaming out: an independent receiver rebuilds the result folder's poses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from mvn_receiver import MvnReceiver

from ikfusion.live.mvn_stream import MvnStreamSink
from ikfusion.model import load_joint_specs
from ikfusion.rotations import axis_rotation


def send_and_receive(sink: MvnStreamSink, frames, sock) -> MvnReceiver:
    receiver = MvnReceiver()
    for poses in frames:
        before = sink.sent
        sink.send(poses)
        receiver.receive(sock, sink.sent - before)
    sink.close()
    return receiver


def assert_pose_matches(decoded, pose) -> None:
    assert set(decoded) == set(pose.segments)
    for i, name in enumerate(pose.segments):
        p, q = decoded[name]
        np.testing.assert_allclose(p, pose.p_world_segment[i], atol=1e-4)
        w, x, y, z = q
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(R, pose.R_world_segment[i], atol=1e-4)


def test_every_message_type_decodes_and_poses_match_the_result_folder(result_poses,
                                                                       udp_receiver) -> None:
    port = udp_receiver.getsockname()[1]
    sink = MvnStreamSink("127.0.0.1", port, meta_period_s=0.5)
    receiver = send_and_receive(sink, [[p] for p in result_poses], udp_receiver)

    by_type: dict[str, list] = {}
    for m in receiver.messages:
        by_type.setdefault(m.message_type, []).append(m)
    assert set(by_type) == {"02", "12", "13", "20", "25"}
    assert len(by_type["02"]) == len(result_poses)
    # meta data and scale at the start and again every 0.5 s of capture time
    duration = result_poses[-1].time_s - result_poses[0].time_s
    assert len(by_type["12"]) == len(by_type["13"]) >= 1 + int(duration / 0.5)
    assert by_type["12"][0].content["name"] == "A"
    assert by_type["13"][0].sample_counter == result_poses[0].frame

    for pose, msg in zip(result_poses, by_type["02"]):
        assert msg.sample_counter == pose.frame and msg.character_id == 0
        assert msg.time_code_ms == round(pose.time_s * 1000)
        assert_pose_matches(msg.content, pose)

    # joint angles: the scale message's points name each joint; the rotations about the
    # segment axes, composed in the joint's Euler order (configs/joints.yaml), rebuild
    # R_parent_child of the result folder's segment orientations
    specs = load_joint_specs()
    point_names = {(p["segment"], p["point_id"]): p["name"]
                   for p in by_type["13"][0].content["points"]}
    for pose, msg in zip(result_poses, by_type["20"]):
        assert len(msg.content) == 22
        for joint in msg.content:
            spec = specs[point_names[joint["parent"]]]
            assert (joint["parent"][0], joint["child"]) == (spec.parent, (spec.child, 0))
            about = dict(zip("xyz", np.deg2rad(joint["rotation_deg"])))
            R = np.eye(3)
            for angle in spec.angles:
                R = R @ axis_rotation(angle.axis, about[angle.axis])
            i, j = pose.segments.index(spec.parent), pose.segments.index(spec.child)
            R_parent_child = pose.R_world_segment[i].T @ pose.R_world_segment[j]
            np.testing.assert_allclose(R, R_parent_child, atol=1e-4)

    for pose, msg in zip(result_poses, by_type["25"]):
        h, m, s = msg.content.split(":")
        assert abs(3600 * int(h) + 60 * int(m) + float(s) - pose.time_s) < 1e-3

    # the scale message's null pose keeps every bone's length and its points sit at the joints
    scale = by_type["13"][0].content
    pose = result_poses[0]
    for i, parent in enumerate(pose.parents):
        if parent < 0:
            continue
        bone = np.linalg.norm(pose.p_world_segment[i] - pose.p_world_segment[parent])
        null = np.subtract(scale["null_pose"][pose.segments[i]],
                           scale["null_pose"][pose.segments[parent]])
        assert abs(np.linalg.norm(null) - bone) < 1e-4
    assert len(scale["points"]) == 22
    for point in scale["points"]:  # each joint point sits at its child's origin
        spec = specs[point["name"]]
        np.testing.assert_allclose(
            point["position"], np.subtract(scale["null_pose"][spec.child],
                                           scale["null_pose"][spec.parent]), atol=1e-6)


def test_large_messages_are_split_and_joined(result_poses, udp_receiver) -> None:
    port = udp_receiver.getsockname()[1]
    sink = MvnStreamSink("127.0.0.1", port, max_payload=200)
    frames = [[p] for p in result_poses[:4]]
    receiver = send_and_receive(sink, frames, udp_receiver)
    poses = [m for m in receiver.messages if m.message_type == "02"]
    assert len(poses) == 4
    assert all(m.datagrams == 4 and m.items == 23 for m in poses)  # 23 x 32 bytes over 200
    for pose, msg in zip(result_poses, poses):
        assert_pose_matches(msg.content, pose)
    scale = next(m for m in receiver.messages if m.message_type == "13")
    assert scale.datagrams > 2 and len(scale.content["null_pose"]) == 23
    assert len(scale.content["points"]) == 22


def test_one_character_id_per_actor(result_poses, udp_receiver) -> None:
    port = udp_receiver.getsockname()[1]
    sink = MvnStreamSink("127.0.0.1", port)
    frames = []
    for pose in result_poses[:3]:
        other = dataclasses.replace(pose, actor="B", character_id=1,
                                    p_world_segment=pose.p_world_segment + [2.0, 0.0, 0.0])
        frames.append([pose, other])
    receiver = send_and_receive(sink, frames, udp_receiver)
    names = {m.character_id: m.content["name"] for m in receiver.messages
             if m.message_type == "12"}
    assert names == {0: "A", 1: "B"}
    for m in receiver.messages:
        if m.message_type == "02":
            pose = frames[m.sample_counter][m.character_id]
            assert_pose_matches(m.content, pose)


def test_max_payload_must_hold_one_item() -> None:
    with pytest.raises(ValueError, match="max_payload"):
        MvnStreamSink("127.0.0.1", 9, max_payload=10)
