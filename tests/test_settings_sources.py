"""Every setting has one source: its shipped YAML file, never a Python default beside it.

The solver's dataclass defaults once disagreed with ``configs/solver.yaml`` (``lag_speed`` 0.2
vs 0.3, ``tilt_deg`` 5 vs 2, ...): code that built ``SolverSettings()`` ran other values than
the command line. Now the settings classes have no defaults, the shipped files set every field
and nothing else, and a user file overrides some keys or is refused with its line.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest
import yaml

from ikfusion.app.correction import CorrectionSettings
from ikfusion.errors import ConfigError
from ikfusion.ik.qp import QpSettings
from ikfusion.ik.settings import SolverSettings
from ikfusion.imu.bridging import BridgingSettings
from ikfusion.live.settings import LiveSettings
from ikfusion.paths import shipped_config
from ikfusion.retarget.settings import RetargetSettings
from ikfusion.settings_files import ShippedSettings, load_settings

#: Settings class -> its shipped file.
SOURCES: dict[type, Path] = {
    SolverSettings: shipped_config("solver.yaml"),
    CorrectionSettings: shipped_config("correction.yaml"),
    RetargetSettings: shipped_config("retarget", "defaults.yaml"),
    BridgingSettings: shipped_config("bridging.yaml"),
    LiveSettings: shipped_config("live.yaml"),
}


def _flat(file: Path) -> dict[str, Any]:
    """The file's settings, read with plain PyYAML (sections flattened)."""
    doc = yaml.safe_load(file.read_text())
    return {key: value for section in doc.values() for key, value in section.items()}


@pytest.mark.parametrize("cls", [*SOURCES, QpSettings])
def test_settings_classes_have_no_defaults_of_their_own(cls: type) -> None:
    with_default = [f.name for f in dataclasses.fields(cls)
                    if f.default is not dataclasses.MISSING
                    or f.default_factory is not dataclasses.MISSING]
    assert with_default == []
    with pytest.raises(TypeError):
        cls()


@pytest.mark.parametrize("cls", list(SOURCES))
def test_the_shipped_file_sets_every_field_and_nothing_else(cls: type) -> None:
    values = _flat(SOURCES[cls])
    names = [f.name for f in dataclasses.fields(cls)]
    assert sorted(values) == sorted(names)
    loaded = cls.load()  # type: ignore[attr-defined]
    for name in names:
        assert getattr(loaded, name) == values[name], name


def test_every_class_loaded_from_a_shipped_file_is_checked_here() -> None:
    assert set(ShippedSettings.__subclasses__()) <= set(SOURCES)


@pytest.mark.parametrize("cls", ShippedSettings.__subclasses__())
def test_each_shipped_settings_class_takes_a_user_file(tmp_path: Path, cls: Any) -> None:
    doc = yaml.safe_load(SOURCES[cls].read_text())
    section = next(iter(doc))
    key, value = next((k, v) for k, v in doc[section].items() if isinstance(v, float))
    user = tmp_path / "mine.yaml"
    user.write_text(f"{section}:\n  {key}: {2.0 * value + 1.0!r}\n")
    shipped, mine = cls.load(), cls.load(user)
    assert getattr(mine, key) == 2.0 * value + 1.0
    assert dataclasses.replace(mine, **{key: getattr(shipped, key)}) == shipped
    user.write_text(f"{section}:\n  {key}_typo: 1.0\n")
    with pytest.raises(ConfigError, match="unknown setting") as err:
        cls.load(user)
    assert (err.value.path, err.value.line, err.value.field) == (user, 2, f"{section}.{key}_typo")


def test_the_solver_runs_the_shipped_values() -> None:
    from ikfusion.ik.solver import Solver
    from ikfusion.model import HumanModel

    shipped = _flat(SOURCES[SolverSettings])
    settings = Solver(HumanModel.default(), compiled=False).settings
    for key in ("lag_speed", "swing_speed", "reenter_delay", "tilt_deg",
                "joint_range_margin_deg", "touchdown_confirm", "qp_max_iterations"):
        assert getattr(settings, key) == shipped[key], key


def test_a_user_file_overrides_some_keys(tmp_path: Path) -> None:
    user = tmp_path / "mine.yaml"
    user.write_text("limits:\n  lag_speed: 0.25\nqp:\n  qp_max_iterations: 500\n")
    shipped = SolverSettings.load()
    mine = SolverSettings.load(user)
    assert mine.lag_speed == 0.25 and mine.qp.max_iterations == 500
    assert dataclasses.replace(mine, lag_speed=shipped.lag_speed,
                               qp_max_iterations=shipped.qp_max_iterations) == shipped
    assert SolverSettings.load(user, lag_speed=0.5).lag_speed == 0.5  # keywords win


@pytest.mark.parametrize(("text", "line", "field", "reason"), [
    ("contacts:\n  floor_z: 0.0\nlimits:\n  lag_sped: 0.25\n", 4, "limits.lag_sped",
     "unknown setting"),
    ("contacts:\n  lag_speed: 0.25\n", 2, "contacts.lag_speed", "belongs in section 'limits'"),
    ("limits:\n  lag_speed: fast\n", 2, "limits.lag_speed", "expected a number"),
    ("solver:\n  max_iterations: 2.5\n", 2, "solver.max_iterations", "whole number"),
    ("limits:\n  lag_speed: 1e-3\n", 2, "limits.lag_speed", "1.0e-9"),
])
def test_a_mistake_in_a_user_file_names_file_line_and_key(tmp_path: Path, text: str, line: int,
                                                          field: str, reason: str) -> None:
    user = tmp_path / "mine.yaml"
    user.write_text(text)
    with pytest.raises(ConfigError, match=reason) as err:
        SolverSettings.load(user)
    assert (err.value.path, err.value.line, err.value.field) == (user, line, field)


def test_a_shipped_file_without_a_setting_is_refused(tmp_path: Path) -> None:
    text = SOURCES[CorrectionSettings].read_text().replace("  max_step:", "  # max_step:")
    shipped = tmp_path / "correction.yaml"
    shipped.write_text(text)
    with pytest.raises(ConfigError, match="missing max_step"):
        load_settings(CorrectionSettings, shipped, "correction settings")


def test_correction_settings_take_a_user_file(tmp_path: Path) -> None:
    user = tmp_path / "correction.yaml"
    user.write_text("heading:\n  heading_rate_deg: 5.0\n")
    assert CorrectionSettings.load(user).heading_rate_deg == 5.0
    user.write_text("heading:\n  heading_rate: 5.0\n")
    with pytest.raises(ConfigError) as err:
        CorrectionSettings.load(user)
    assert (err.value.line, err.value.field) == (2, "heading.heading_rate")
