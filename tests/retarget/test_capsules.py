"""Capsule distances against brute force, and their Jacobians against finite differences."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from ikfusion.ik.configuration import Configuration
from ikfusion.paths import robots_dir
from ikfusion.retarget.capsules import CapsulePairs, closest_points
from ikfusion.retarget.robot_config import load_retarget_config
from ikfusion.retarget.robot_model import RobotModel


def test_closest_points_match_a_dense_search() -> None:
    rng = np.random.default_rng(4)
    a1, b1, a2, b2 = (rng.normal(size=(200, 3)) for _ in range(4))
    b2[:20] = a2[:20] + 1e-3 * (b1[:20] - a1[:20])  # nearly parallel and short
    b1[20:30] = a1[20:30]                           # a point against a segment
    p, q = closest_points(a1, b1, a2, b2)
    s = np.linspace(0.0, 1.0, 401)
    P = a1[:, None] + s[None, :, None] * (b1 - a1)[:, None]
    Q = a2[:, None] + s[None, :, None] * (b2 - a2)[:, None]
    brute = np.linalg.norm(P[:, :, None] - Q[:, None, :], axis=3).min(axis=(1, 2))
    found = np.linalg.norm(p - q, axis=1)
    assert np.all(found <= brute + 1e-12)
    np.testing.assert_allclose(found, brute, atol=5e-3 * np.linalg.norm(b1 - a1, axis=1).max())


def test_capsule_rows_are_the_distance_jacobian(human_as_robot: Path) -> None:
    config = load_retarget_config(robots_dir() / "human.urdf", human_as_robot)
    robot = RobotModel(config)
    pairs = CapsulePairs(config.capsules, config.collision_pairs, robot.frame_ids,
                         margin=0.0, activation=10.0)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q = robot.rest.copy()
        q[7:] = rng.uniform(np.maximum(robot.lower, -1.0), np.minimum(robot.upper, 1.0))
        conf = Configuration(robot.model, q)
        rows = pairs.inequality(conf)
        d0 = pairs._witnesses(conf)[2]
        numeric = np.zeros_like(rows.G)
        for i in range(robot.model.nv):
            step = np.zeros(robot.model.nv)
            step[i] = 1e-7
            moved = Configuration(robot.model, pin.integrate(robot.model, q, step))
            numeric[:, i] = (pairs._witnesses(moved)[2] - d0) / 1e-7
        np.testing.assert_allclose(-rows.G, numeric, atol=2e-5)
        np.testing.assert_allclose(rows.h, d0, atol=1e-12)
        assert pairs.distances(conf).shape == (3,)


@pytest.mark.parametrize("bad", ["frame", "pair"])
def test_config_mistakes_are_named(human_as_robot: Path, bad: str) -> None:
    from ikfusion.errors import ConfigError

    file = human_as_robot
    data = yaml.safe_load(file.read_text())
    if bad == "frame":
        data["links"]["LeftHand"] = "left_palm"
    else:
        data["collision_pairs"].append(["left_forearm", "nose"])
    file.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        RobotModel(load_retarget_config(robots_dir() / "human.urdf", file))
    text = str(err.value)
    assert str(file) in text
    if bad == "frame":
        assert "left_palm" in text and "LeftForeArm" in text  # what was asked, what exists
    else:
        assert "collision_pairs[3]" in text and "nose" in text


def test_distances_along_a_motion_match_a_dense_search(human_as_robot: Path) -> None:
    """All frames at once (the metrics' path) give each pair's exact capsule distance."""
    from ikfusion.mocap.model_motion import frame_poses

    config = load_retarget_config(robots_dir() / "human.urdf", human_as_robot)
    robot = RobotModel(config)
    pairs = CapsulePairs(config.capsules, config.collision_pairs, robot.frame_ids,
                         activation=np.inf)
    rng = np.random.default_rng(7)
    q = np.tile(robot.rest, (6, 1))
    q[:, 7:] = rng.uniform(np.maximum(robot.lower, -1.5), np.minimum(robot.upper, 1.5),
                           size=(6, len(robot.lower)))
    p_links, R_links = frame_poses(robot.model, q, pairs.links)
    found = pairs.along(R_links, p_links)
    s = np.linspace(0.0, 1.0, 801)
    for k, qk in enumerate(q):
        conf = Configuration(robot.model, qk)
        for i, (first, second) in enumerate(pairs.pairs):
            ends = []
            for capsule in (config.capsules[first], config.capsules[second]):
                T = conf.placement(robot.frame_ids[capsule.link])
                a, b = (T.rotation @ np.asarray(x) + T.translation for x in (capsule.a, capsule.b))
                ends.append(a + s[:, None] * (b - a))
            brute = np.linalg.norm(ends[0][:, None] - ends[1][None], axis=2).min() \
                - config.capsules[first].radius - config.capsules[second].radius
            assert brute - 2e-3 <= found[k, i] <= brute + 1e-12
        np.testing.assert_allclose(found[k], pairs.distances(conf), atol=1e-12)


def test_min_distance_is_the_smallest_of_all_pairs_and_frames() -> None:
    """The metrics' pruned minimum equals the minimum over every pair of every frame."""
    from ikfusion.mocap.model_motion import frame_poses

    robot = RobotModel(load_retarget_config("g1"))
    config = robot.config
    pairs = CapsulePairs(config.capsules, config.collision_pairs, robot.frame_ids,
                         activation=np.inf)
    rng = np.random.default_rng(3)
    q = np.tile(robot.rest, (300, 1))
    q[:, 7:] = rng.uniform(robot.lower, robot.upper, size=(300, len(robot.lower)))
    p_links, R_links = frame_poses(robot.model, q, pairs.links)
    every = pairs.along(R_links, p_links)
    for frames in (slice(None), slice(0, 1), slice(17, 60)):
        assert pairs.min_distance(R_links[frames], p_links[frames]) == every[frames].min()
    assert pairs.min_distance(R_links[:0], p_links[:0]) is None
