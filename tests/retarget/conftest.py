"""Fixtures of the retargeting tests."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml


@pytest.fixture
def human_as_robot(tmp_path: Path) -> Path:
    """A retarget config that treats our own human URDF as a robot (no extra package)."""
    corners = [[-0.05, 0.04, -0.08], [-0.05, -0.04, -0.08], [0.14, -0.04, -0.08],
               [0.14, 0.04, -0.08]]
    segments = ["Pelvis", "T8", "Head", "RightUpperArm", "RightForeArm", "RightHand",
                "LeftUpperArm", "LeftForeArm", "LeftHand", "RightUpperLeg", "RightLowerLeg",
                "RightFoot", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot"]
    config = {
        "links": {s: s for s in segments},
        "position_weights": {"Pelvis": 10.0, "LeftFoot": 5.0, "RightFoot": 5.0},
        "feet": {"left": {"link": "LeftFoot", "corners": corners},
                 "right": {"link": "RightFoot", "corners": corners}},
        "capsules": {
            "trunk": {"link": "T8", "a": [0, 0, -0.25], "b": [0, 0, 0.15], "radius": 0.1},
            "left_forearm": {"link": "LeftForeArm", "a": [0, 0, 0], "b": [0, 0, -0.25],
                             "radius": 0.035},
            "right_forearm": {"link": "RightForeArm", "a": [0, 0, 0], "b": [0, 0, -0.25],
                              "radius": 0.035},
            "left_shin": {"link": "LeftLowerLeg", "a": [0, 0, 0], "b": [0, 0, -0.4],
                          "radius": 0.05},
            "right_shin": {"link": "RightLowerLeg", "a": [0, 0, 0], "b": [0, 0, -0.4],
                           "radius": 0.05},
        },
        "collision_pairs": [["left_forearm", "trunk"], ["right_forearm", "trunk"],
                            ["left_shin", "right_shin"]],
    }
    file = tmp_path / "human_as_robot.yaml"
    file.write_text(yaml.safe_dump(config))
    return file
