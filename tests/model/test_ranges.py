"""Per-subject ranges of motion from a body file: overrides, the athlete preset, bad entries."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.errors import ConfigError
from ikfusion.ik import Frame, Solver
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import Body, HumanModel
from ikfusion.model.ranges import load_preset


def limits(model: HumanModel, joint: str) -> dict[str, tuple[float, float]]:
    return {a.name: (round(a.lower_deg, 6), round(a.upper_deg, 6))
            for a in model.ball_joint(joint).spec.angles}


def test_a_body_file_widens_one_joint_and_leaves_the_others(tmp_path: Path) -> None:
    path = tmp_path / "body.yaml"
    path.write_text("height: 1.68\nranges:\n  jRightHip: {flex: [-30, 175], abd: [-45, 85]}\n")
    model = HumanModel.from_body(Body.from_yaml(path))
    default = HumanModel.default()
    assert limits(model, "jRightHip") == {"flex": (-30.0, 175.0), "abd": (-45.0, 85.0),
                                          "rot": limits(default, "jRightHip")["rot"]}
    assert limits(model, "jLeftHip") == limits(default, "jLeftHip")


def test_the_athlete_preset_and_an_override_on_top(tmp_path: Path) -> None:
    path = tmp_path / "body.yaml"
    path.write_text("height: 1.68\nranges:\n  preset: athlete\n  jLeftKnee: {flex: [-5, 150]}\n")
    model = HumanModel.from_body(Body.from_yaml(path))
    preset = {(j, a): (lo, hi) for j, a, lo, hi in load_preset("athlete")}
    assert limits(model, "jRightHip")["flex"] == preset[("jRightHip", "flex")]
    assert limits(model, "jRightKnee")["flex"] == preset[("jRightKnee", "flex")]
    assert limits(model, "jLeftKnee")["flex"] == (-5.0, 150.0)  # the file's own line wins
    assert Body.from_dict({"height": 1.7, "ranges": "athlete"}).ranges == load_preset("athlete")


def test_a_shoulders_axial_rotation_may_reach_the_gimbal_lock(tmp_path: Path) -> None:
    """``rot: [-90, 90]`` (a middle angle's range reaching the lock, no cone walled off around
    it: see configs/joints.yaml) is accepted; it was refused as outside (-90, 90)."""
    path = tmp_path / "body.yaml"
    path.write_text("height: 1.68\nranges:\n  jLeftShoulder: {rot: [-90, 90]}\n")
    model = HumanModel.from_body(Body.from_yaml(path))
    assert limits(model, "jLeftShoulder")["rot"] == (-90.0, 90.0)


@pytest.mark.parametrize("entry, field, line", [
    ("ranges:\n  jRightHipp: {flex: [-30, 175]}\n", "ranges.jRightHipp", 3),
    ("ranges:\n  jRightHip:\n    flexion: [-30, 175]\n", "ranges.jRightHip.flexion", 4),
    ("ranges:\n  jRightHip:\n    abd: [-45, 95]\n", "ranges.jRightHip.abd", 4),  # middle angle
    ("ranges:\n  jRightHip:\n    flex: [175, -30]\n", "ranges.jRightHip.flex", 4),
    ("ranges:\n  jRightHip:\n    flex: fast\n", "ranges.jRightHip.flex", 4),
    ("ranges: ballet\n", "ranges", 2),
])
def test_a_bad_range_names_file_line_and_field(tmp_path: Path, capsys, entry: str, field: str,
                                               line: int) -> None:
    path = tmp_path / "body.yaml"
    path.write_text("height: 1.68\n" + entry)
    with pytest.raises(ConfigError) as err:
        Body.from_yaml(path)
    assert (err.value.path, err.value.field, err.value.line) == (path, field, line)
    assert main(["model", "--body", str(path)]) == 2
    assert field in capsys.readouterr().err


def test_a_wider_hip_lets_the_solve_follow_a_high_kick(human_athlete: HumanModel) -> None:
    """Hip flexed to 160 deg: the default model stops at its 130 deg limit, the athlete's
    follows the truth. Reached at 1.5 deg a frame with the target pulling on, the default's
    hip sinks into its soft range wall (``joint_range_overshoot_deg``) and is pushed back."""
    flex = np.linspace(100.0, 160.0, 40)
    solved = {}
    for name, model in (("default", HumanModel.default()), ("athlete", human_athlete)):
        qs = [model.configuration({"jRightHip_flex": f}) for f in flex]
        frames = [Frame(k / 60.0, {s: model.segment_rotation(q, s)
                                   for s in ("Pelvis", "RightUpperLeg", "RightLowerLeg")})
                  for k, q in enumerate(qs)]
        motion = Solver(model, contacts=False).solve(frames)
        column = model.angle_columns.index("jRightHip_flex")
        solved[name] = motion.joint_angles()[:, column]
    overshoot = SolverSettings.load().joint_range_overshoot_deg
    assert 129.0 < np.max(solved["default"]) <= 130.0 + overshoot + 1e-6
    assert solved["default"][-1] < np.max(solved["default"]) - 1.0  # on its way back
    np.testing.assert_allclose(solved["athlete"][-1], 160.0, atol=1.0)


@pytest.fixture(scope="module")
def human_athlete() -> HumanModel:
    return HumanModel.from_body(Body.from_dict({"height": 1.75, "ranges": "athlete"}))


def test_a_joints_file_is_read_again_once_edited(tmp_path: Path) -> None:
    """The specs of a joints file are kept between reads only while the file is unchanged."""
    from ikfusion.model.joints import load_joint_specs
    from ikfusion.paths import shipped_config

    file = tmp_path / "joints.yaml"
    text = shipped_config("joints.yaml").read_text()
    file.write_text(text)
    first = load_joint_specs(file)
    again = load_joint_specs(file)
    assert again == first and again is not first  # the caller's own dict
    again.clear()
    assert load_joint_specs(file) == first
    knee = first["jRightKnee"].angles[0]
    at = text.index("jRightKnee:")
    edited = text[:at] + text[at:].replace(f"[{knee.lower_deg:g}, {knee.upper_deg:g}]",
                                           "[-1, 100]", 1)
    assert edited != text
    file.write_text(edited + "\n# edited\n")
    assert load_joint_specs(file)["jRightKnee"] != first["jRightKnee"]
