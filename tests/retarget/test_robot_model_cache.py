"""A retarget robot's reduced model is cached on disk, keyed by its URDF's bytes and options."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ikfusion.paths import robots_dir
from ikfusion.retarget import robot_model
from ikfusion.retarget.robot_config import load_retarget_config
from ikfusion.retarget.robot_model import RobotModel


def _no_build(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*_: object) -> None:
        raise AssertionError("the robot model was built from its URDF although it is cached")

    monkeypatch.setattr(robot_model, "_build_reduced_model", refuse)


def _assert_same_robot(a: RobotModel, b: RobotModel) -> None:
    assert a.model == b.model and a.dof_names == b.dof_names
    for name in ("lower", "upper", "max_velocity", "rest"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_a_cached_robot_model_equals_a_fresh_one(tmp_path: Path, human_as_robot: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    config = load_retarget_config(robots_dir() / "human.urdf", human_as_robot)
    blocker = tmp_path / "a_file"
    blocker.write_text("where no cache folder can be\n")
    monkeypatch.setenv("IKFUSION_CACHE", str(blocker))
    fresh = RobotModel(config)  # built, and not stored: an unwritable cache only costs time
    monkeypatch.setenv("IKFUSION_CACHE", str(tmp_path / "cache"))
    built = RobotModel(config)
    assert list((tmp_path / "cache" / "robot_models").glob("*/model.bin"))
    _no_build(monkeypatch)
    loaded = RobotModel(config)
    _assert_same_robot(loaded, fresh)
    _assert_same_robot(loaded, built)


def test_another_urdf_or_other_locked_joints_get_their_own_model(
        tmp_path: Path, human_as_robot: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IKFUSION_CACHE", str(tmp_path / "cache"))
    config = load_retarget_config(robots_dir() / "human.urdf", human_as_robot)
    RobotModel(config)
    text = (robots_dir() / "human.urdf").read_text()
    knee = 'name="jRightKnee_flex"'
    assert knee in text
    start = text.index(knee)
    limit = text.index('upper="', start)
    end = text.index('"', limit + len('upper="'))
    edited = tmp_path / "human_stiff_knee.urdf"
    edited.write_text(text[:limit] + 'upper="0.5' + text[end:])  # the right knee flexes less
    stiff = RobotModel(replace(config, urdf=edited))
    locked = RobotModel(replace(config, locked_joints={"jLeftElbow_rot": 0.25}))
    assert len(list((tmp_path / "cache" / "robot_models").glob("*/model.bin"))) == 3
    plain = RobotModel(config)
    i = plain.dof_names.index("jRightKnee_flex")
    assert stiff.model.upperPositionLimit[7 + i] == 0.5 != plain.model.upperPositionLimit[7 + i]
    assert "jLeftElbow_rot" in plain.dof_names and "jLeftElbow_rot" not in locked.dof_names
    assert locked.model.nq == plain.model.nq - 1
