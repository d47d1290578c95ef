"""Bridging of missing samples against closed-form motions with known truth."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.imu.bridging import BridgingSettings, bridge_segments
from ikfusion.rotations import angle_between, axis_rotation

RATE = 60.0
PARENTS = {"Pelvis": None, "UpperLeg": "Pelvis", "LowerLeg": "UpperLeg"}


def turning_leg(seconds: float = 6.0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A pelvis turning at 90 deg/s about z and a thigh swinging +-30 deg at 1 Hz below it."""
    time = np.arange(int(seconds * RATE)) / RATE
    pelvis = axis_rotation("z", np.radians(90.0) * time)
    thigh = pelvis @ axis_rotation("y", np.radians(30.0) * np.sin(2 * np.pi * time))
    shank = thigh @ axis_rotation("y", np.radians(-20.0) * (1 - np.cos(2 * np.pi * time)))
    return time, {"Pelvis": pelvis, "UpperLeg": thigh, "LowerLeg": shank}


def steps_deg(R: np.ndarray) -> np.ndarray:
    """Angle between successive orientations [deg]."""
    return np.degrees(angle_between(R[:-1], R[1:]))


def test_a_long_gap_keeps_the_global_motion_and_meets_the_sensor_exactly() -> None:
    time, R = turning_leg()
    valid = {s: np.ones(len(time), dtype=bool) for s in R}
    valid["UpperLeg"][120:180] = False  # 1 s: the pelvis turns 90 deg meanwhile
    out = bridge_segments(R, valid, time, PARENTS)
    err = np.degrees(angle_between(out.R_world_segment["UpperLeg"], R["UpperLeg"]))
    # the hip swings +-30 deg; interpolated relative to the pelvis the error stays below that,
    # while a world slerp across the gap would miss the pelvis' 90 deg turn
    assert err[120:180].max() < 35.0
    world = np.degrees(angle_between(R["UpperLeg"][119], R["UpperLeg"][180]))
    assert world > 60.0
    assert err[valid["UpperLeg"]].max() < 1e-9
    assert steps_deg(out.R_world_segment["UpperLeg"]).max() < 1.2 * steps_deg(
        R["UpperLeg"]).max()
    # the shank below follows its thigh: bridged relative to the bridged thigh, never jumps
    assert steps_deg(out.R_world_segment["LowerLeg"]).max() < 1.2 * steps_deg(
        R["LowerLeg"]).max() + 1.0
    assert out.bridged["UpperLeg"].sum() == 60 and not out.bridged["LowerLeg"].any()


def test_a_sensor_gone_at_the_end_holds_its_relative_orientation() -> None:
    time, R = turning_leg()
    valid = {s: np.ones(len(time), dtype=bool) for s in R}
    valid["LowerLeg"][300:] = False
    out = bridge_segments(R, valid, time, PARENTS)
    rel = np.swapaxes(out.R_world_segment["UpperLeg"], -1, -2) @ out.R_world_segment["LowerLeg"]
    np.testing.assert_allclose(rel[300:], np.broadcast_to(rel[299], rel[300:].shape), atol=1e-9)
    report = out.summary()["LowerLeg"]
    assert report["gaps"] == [[pytest.approx(5.0), pytest.approx(6.0)]]
    assert any("LowerLeg" in w and "to the end" in w for w in out.warnings)


@pytest.mark.parametrize("seconds_away", [0.05, 2.0])
def test_causal_return_is_blended_at_a_bounded_rate(seconds_away: float) -> None:
    time, R = turning_leg()
    valid = {s: np.ones(len(time), dtype=bool) for s in R}
    gap = slice(120, 120 + int(round(seconds_away * RATE)))
    valid["UpperLeg"][gap] = False
    settings = BridgingSettings.load()
    out = bridge_segments(R, valid, time, PARENTS, causal=True, settings=settings)
    hip = np.swapaxes(R["Pelvis"], -1, -2) @ out.R_world_segment["UpperLeg"]
    true_hip = np.swapaxes(R["Pelvis"], -1, -2) @ R["UpperLeg"]
    extra = steps_deg(hip) - steps_deg(true_hip)
    assert extra.max() < np.degrees(settings.blend_rate) / RATE + 1.5
    err = np.degrees(angle_between(hip, true_hip))
    assert err[gap.stop + int(RATE):].max() < 1e-6  # back on its sensor within 1 s
    assert err[: gap.start].max() < 1e-9  # the past is untouched


def test_the_summary_merges_and_limits_the_listed_gaps() -> None:
    time, R = turning_leg(30.0)
    valid = {s: np.ones(len(time), dtype=bool) for s in R}
    valid["Pelvis"][::10] = False  # a lost packet every 1/6 s: 180 gaps
    out = bridge_segments(R, valid, time, PARENTS)
    report = out.summary()["Pelvis"]
    assert report["samples"] == 180 and report["gap_count"] == 180
    assert report["gaps"] == [[pytest.approx(0.0), pytest.approx(29.85)]]
    assert report["share"] == pytest.approx(0.1)
    assert any(w.startswith("samples bridged") and "Pelvis 10.0 %" in w for w in out.warnings)
    valid["Pelvis"][:] = True
    valid["Pelvis"][::30] = False  # every 0.5 s: 60 gaps, apart by more than merge_s
    assert len(bridge_segments(R, valid, time, PARENTS).summary()["Pelvis"]["gaps"]) == 20
