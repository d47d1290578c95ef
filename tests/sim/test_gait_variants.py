"""The generator's walks beyond forward walking: backwards, side steps, on the spot, pauses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.mocap.model_motion import TruthMotion, site_positions
from ikfusion.model import HumanModel
from ikfusion.sim.gait import GAIT_PRESETS, gait_preset, generate_gait

RATE = 30.0  # [Hz] enough to see the motion, quick to generate


def _walk(name: str, seconds: float) -> TruthMotion:
    return generate_gait(HumanModel.default(), gait_preset(name, seconds, stand=1.0), rate=RATE)


def _pelvis_forward_and_velocity(truth: TruthMotion) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal pelvis forward axis (N, 2) and pelvis velocity (N, 2) [m/s]."""
    R = np.array([truth.model.segment_rotation(q, "Pelvis") for q in truth.q])
    forward = R[:, :2, 0] / np.linalg.norm(R[:, :2, 0], axis=1, keepdims=True)
    velocity = np.gradient(truth.q[:, :2], 1.0 / RATE, axis=0)
    return forward, velocity


def _moving(velocity: np.ndarray) -> np.ndarray:
    return np.linalg.norm(velocity, axis=1) > 0.2


def test_backwards_walk_moves_against_the_facing_direction() -> None:
    truth = _walk("backwards", 7.0)
    forward, velocity = _pelvis_forward_and_velocity(truth)
    moving = _moving(velocity)
    assert moving.mean() > 0.5
    direction = velocity[moving] / np.linalg.norm(velocity[moving], axis=1, keepdims=True)
    assert np.mean(np.sum(forward[moving] * direction, axis=1)) < -0.9


def test_side_steps_move_across_the_facing_direction() -> None:
    truth = _walk("sidestep", 7.0)
    forward, velocity = _pelvis_forward_and_velocity(truth)
    moving = np.linalg.norm(velocity, axis=1) > 0.15
    assert moving.mean() > 0.4
    direction = velocity[moving] / np.linalg.norm(velocity[moving], axis=1, keepdims=True)
    along = np.sum(forward[moving] * direction, axis=1)
    assert np.mean(np.abs(along)) < 0.3
    # towards the body's right (its -Y): forward x velocity points down
    cross = forward[moving, 0] * direction[:, 1] - forward[moving, 1] * direction[:, 0]
    assert np.mean(cross) < -0.9


def test_turn_on_the_spot_turns_without_travelling() -> None:
    truth = _walk("turn-on-spot", 7.0)
    forward, _ = _pelvis_forward_and_velocity(truth)
    yaw = np.unwrap(np.arctan2(forward[:, 1], forward[:, 0]))
    assert np.degrees(yaw[-1] - yaw[0]) > 180.0
    centre = truth.q[:, :2].mean(axis=0)
    assert np.linalg.norm(truth.q[:, :2] - centre, axis=1).max() < 0.25
    feet = site_positions(truth.model, truth.q, ["LeftHeel", "RightHeel"])
    assert (feet[:, :, 2].max(axis=0) > 0.03).all()  # it steps round, both feet leave the floor


def test_start_stop_halts_with_both_feet_planted_and_walks_on() -> None:
    truth = _walk("start-stop", 12.0)
    names = list(truth.contact_names)
    speed = np.linalg.norm(np.gradient(truth.q[:, :2], 1.0 / RATE, axis=0), axis=1)
    still = speed < 0.01
    walking_start = int(1.5 * RATE)
    runs = np.flatnonzero(np.diff(still[walking_start:].astype(int)) != 0) + walking_start
    # a halt of at least 1.5 s after walking, and walking again after it
    edges = np.concatenate([[walking_start], runs + 1, [len(still)]])
    halts = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if still[a] and b - a >= 1.5 * RATE]
    assert halts, "no halt of 1.5 s"
    a, b = halts[0]
    assert speed[b:].max() > 0.8  # it walks on at speed
    points = site_positions(truth.model, truth.q[a:b], names)
    planted = truth.contacts[a:b]
    for side in ("Left", "Right"):
        foot = [i for i, n in enumerate(names) if n.startswith(side)]
        assert planted[:, foot].any(axis=1).all(), f"{side} foot off the floor in the halt"
    for i in range(len(names)):  # planted points do not move
        if planted[:, i].all():
            assert np.ptp(points[:, i], axis=0).max() < 1e-3


def test_presets_keep_the_forward_walks_as_they_were() -> None:
    # the walks simulate used before the presets existed
    for name in ("circle", "straight"):
        p = gait_preset(name, 10.0)
        assert (p.radius, p.speed, p.step_length, p.stand, p.duration) == (1.5, 1.1, 0.6, 2.0,
                                                                           10.0)
        assert p.facing_deg == 0.0 and p.pauses == ()
    assert set(GAIT_PRESETS) >= {"backwards", "sidestep", "turn-on-spot", "start-stop", "slow",
                                 "fast"}


def test_simulate_names_the_walks_and_refuses_an_unknown_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["simulate", "--motion", "gait:moonwalk", "--seconds", "4",
                 "--out", str(tmp_path / "cap"), "--quiet"])
    assert code == 2
    err = capsys.readouterr().err
    assert "moonwalk" in err and "sidestep" in err and "motion" in err
    assert not (tmp_path / "cap").exists()
