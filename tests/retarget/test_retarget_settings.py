"""Retargeting settings: ``configs/retarget/defaults.yaml``, overridden by a robot config."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

import ikfusion.retarget.robot as robot_module
from ikfusion.errors import ConfigError
from ikfusion.ik.settings import SolverSettings
from ikfusion.paths import robots_dir
from ikfusion.retarget.robot import RobotRetargeter
from ikfusion.retarget.robot_config import SHIPPED_ROBOTS, load_retarget_config, robots_installed
from ikfusion.retarget.robot_model import RobotModel
from ikfusion.retarget.settings import RetargetSettings


def test_the_retargeter_has_no_numeric_constants_of_its_own() -> None:
    constants = [name for name, value in vars(robot_module).items()
                 if name.isupper() and isinstance(value, int | float | tuple)]
    assert constants == []


def _with_solver(config: Path, solver: dict) -> Path:  # type: ignore[type-arg]
    data = yaml.safe_load(config.read_text()) | {"solver": solver}
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    return config


def test_a_robot_config_overrides_some_defaults(human_as_robot: Path) -> None:
    _with_solver(human_as_robot, {"steps": {"max_steps": 3, "backend": "proxqp"}})
    config = load_retarget_config(robots_dir() / "human.urdf", human_as_robot)
    defaults = RetargetSettings.load()
    assert (config.solver.max_steps, config.solver.backend) == (3, "proxqp")
    assert dataclasses.replace(config.solver, max_steps=defaults.max_steps,
                               backend=defaults.backend) == defaults
    retargeter = RobotRetargeter(RobotModel(config), SolverSettings.load().qp)
    assert retargeter.settings is config.solver and retargeter.backend == "proxqp"


def test_a_typo_in_a_robot_configs_solver_key_names_its_line(human_as_robot: Path) -> None:
    _with_solver(human_as_robot, {"steps": {"max_step": 3}})
    line = next(n for n, text in enumerate(human_as_robot.read_text().splitlines(), 1)
                if "max_step:" in text)
    with pytest.raises(ConfigError, match="unknown setting") as err:
        load_retarget_config(robots_dir() / "human.urdf", human_as_robot)
    assert (err.value.path, err.value.line, err.value.field) == (
        human_as_robot, line, "solver.steps.max_step")


@pytest.mark.skipif(not robots_installed(), reason="needs example-robot-data")
@pytest.mark.parametrize("robot", SHIPPED_ROBOTS)
def test_shipped_robots_run_the_defaults(robot: str) -> None:
    assert load_retarget_config(robot).solver == RetargetSettings.load()
