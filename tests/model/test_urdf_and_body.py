"""URDF generation, the shipped default file, an independent parser, and body validation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from ikfusion.errors import ConfigError
from ikfusion.model import Body, HumanModel, body_to_urdf, build_layout
from ikfusion.model.layout import _MASS_TABLE
from ikfusion.paths import robots_dir


def test_shipped_urdf_is_not_stale() -> None:
    shipped = (robots_dir() / "human.urdf").read_text()
    assert shipped == body_to_urdf(Body()), (
        "robots/human.urdf is stale: regenerate it with `ikfusion model --urdf robots/human.urdf`"
    )


def test_independent_parser_sees_the_same_link_tree(tmp_path: Path) -> None:
    path = robots_dir() / "human.urdf"
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False)
    ours = pin.buildModelFromUrdf(str(path))
    parents = {}
    for joint in urdf.robot.joints:
        parents[joint.child] = joint.parent
    pin_parents = {}
    for f in ours.frames:
        if f.type == pin.FrameType.BODY and f.name != "universe":
            parent_joint_frame = ours.frames[f.parentFrame]
            pin_parents[f.name] = ours.frames[parent_joint_frame.parentFrame].name
    pin_parents.pop("Pelvis", None)
    assert parents == pin_parents
    # sites: 24, the knees and palms, and the 6 where a lying or sitting body rests
    assert len(urdf.robot.links) == 23 + 2 * 22 + 28 + 6
    revolute = [j for j in urdf.robot.joints if j.type == "revolute"]
    assert len(revolute) == 66
    assert all(j.limit is not None and j.limit.lower < j.limit.upper for j in revolute)


def test_any_other_urdf_loads_as_it_is(tmp_path: Path) -> None:
    """Revolute joints with offsets (a robot's hip) stay revolute."""
    urdf = tmp_path / "arm.urdf"
    inertial = ('<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" '
                'izz="1"/></inertial>')
    links = "".join(f'<link name="{n}">{inertial}</link>' for n in ("base", "l1", "l2", "l3"))
    joints = "".join(
        f'<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
        f'<origin xyz="{o}"/><axis xyz="{a}"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        for n, p, c, o, a in (("a", "base", "l1", "0 0 0.1", "0 1 0"),
                              ("b", "l1", "l2", "0 0 0.2", "1 0 0"),
                              ("c", "l2", "l3", "0 0 0", "0 0 1")))
    urdf.write_text(f'<?xml version="1.0"?><robot name="arm">{links}{joints}</robot>')
    model = HumanModel.from_urdf(urdf)
    assert model.ball_joints == {}
    assert model.model.nv == 6 + 3
    assert [model.model.joints[j].shortname() for j in range(2, 5)] == [
        "JointModelRY", "JointModelRX", "JointModelRZ"]


def test_mass_fractions_sum_to_one() -> None:
    from ikfusion.model import SEGMENTS

    total = sum(_MASS_TABLE[s.replace("Left", "Right")][0] for s in SEGMENTS)
    assert total == pytest.approx(1.0, abs=1e-9)
    layout = build_layout(Body(height=1.8, mass=80.0))
    assert sum(m.mass for m in layout.masses.values()) == pytest.approx(80.0)


def test_model_mass_matches_body() -> None:
    model = HumanModel.from_body(Body(height=1.6, mass=55.0))
    assert sum(i.mass for i in model.model.inertias) == pytest.approx(55.0)


def test_measured_dimensions_are_used() -> None:
    body = Body(height=1.80, upper_leg=0.47, lower_leg=0.43, ankle_height=0.07)
    model = HumanModel.from_body(body)
    q = model.neutral()
    hip = model.segment_position(q, "RightUpperLeg")
    knee = model.segment_position(q, "RightLowerLeg")
    ankle = model.segment_position(q, "RightFoot")
    assert np.linalg.norm(hip - knee) == pytest.approx(0.47)
    assert np.linalg.norm(knee - ankle) == pytest.approx(0.43)
    assert ankle[2] == pytest.approx(0.07)
    assert model.site_position(q, "HeadTop")[2] == pytest.approx(1.80, abs=0.01)


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"height": 1.75, "upper_leg": -0.4}, "upper_leg"),
        ({"height": 1.75, "forearm": 2.6}, "forearm"),
        ({"height": 175}, "height"),
        ({"height": 1.75, "hip_height": 0.9, "upper_leg": 0.3, "lower_leg": 0.4,
          "ankle_height": 0.07}, "hip_height"),
        ({"height": 1.75, "sholder_width": 0.4}, "sholder_width"),
        ({"height": 1.75, "hand": "long"}, "hand"),
        ({"upper_arm": 0.3}, "height"),
    ],
)
def test_bad_body_names_the_field(tmp_path: Path, values: dict, field: str) -> None:
    import yaml

    path = tmp_path / "body.yaml"
    path.write_text(yaml.safe_dump(values))
    with pytest.raises(ConfigError) as err:
        Body.from_yaml(path)
    assert err.value.field == field
    assert str(path) in str(err.value)


def test_body_yaml_round_trip(tmp_path: Path) -> None:
    import yaml

    path = tmp_path / "body.yaml"
    path.write_text(yaml.safe_dump({"height": 1.62, "shoulder_width": 0.36}))
    body = Body.from_yaml(path)
    assert body.dimension("shoulder_width") == 0.36
    assert body.dimension("upper_arm") == pytest.approx(0.186 * 1.62)


@pytest.mark.parametrize(
    ("value", "field"),
    [
        (".nan", "height"), (".inf", "height"), ("-.inf", "height"), ("0", "height"),
        ("1" + "0" * 400, "height"),  # an integer too large for a float
        (".nan", "upper_leg"), (".inf", "upper_leg"), ("-0.43", "upper_leg"), ("43", "upper_leg"),
        (".nan", "mass"), ("1.0e+400", "mass"), ("7000", "mass"),
    ],
)
def test_non_finite_or_absurd_body_value_names_file_line_field(tmp_path: Path, value: str,
                                                               field: str) -> None:
    values = {"height": "1.75", "mass": "70", "upper_leg": "0.43"} | {field: value}
    lines = ["# subject 7, measured 2026-03-02"] + [f"{k}: {v}" for k, v in values.items()]
    path = tmp_path / "body.yaml"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as err:
        Body.from_yaml(path)
    assert (err.value.path, err.value.field) == (path, field)
    assert err.value.line == 1 + list(values).index(field) + 1
