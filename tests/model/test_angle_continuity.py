"""Continuous joint angles: closed-form spins and passes through the Euler singularity."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear, minimize

from ikfusion.model import HumanModel
from ikfusion.model.angle_continuity import (
    continuous_columns_deg,
    continuous_series,
    equivalent_triple,
    nearest_equivalent,
    nearest_to_ranges,
    turn_into_range,
    wrap_near,
)
from ikfusion.rotations import angle_between


@pytest.fixture(scope="module")
def human() -> HumanModel:
    return HumanModel.default()


def principal(human: HumanModel, joint: str, angles_deg: np.ndarray) -> np.ndarray:
    """The per-frame principal decomposition [rad] of a joint's rotations given as angles."""
    spec = human.ball_joints[joint].spec
    return spec.angles_from_rotation(spec.rotation(np.radians(angles_deg)))


def test_a_spin_through_180_deg_is_one_ramp(human: HumanModel) -> None:
    """The trunk twists 0 -> 400 deg: principal angles wrap at 180, the series does not."""
    twist = np.linspace(0.0, 400.0, 201)
    truth = np.stack([np.full_like(twist, 10.0), np.full_like(twist, -5.0), twist], axis=1)
    raw = principal(human, "jT9T8", truth)  # sequence flex, abd, rot
    assert np.max(np.abs(np.diff(np.degrees(raw[:, 2])))) > 300.0  # the wrap is there
    np.testing.assert_allclose(np.degrees(continuous_series(raw)), truth, atol=1e-9)


def test_a_pass_through_the_singularity_keeps_the_branch(human: HumanModel) -> None:
    """The shoulder's middle angle (axial rotation) sweeps 60 -> 120 -> 60 deg: the principal
    triple jumps to (flex + 180, 180 - rot, abd + 180) beyond 90 deg, the series stays on the
    truth's branch."""
    rot = 90.0 - 30.0 * np.cos(np.linspace(0.0, 2.0 * np.pi, 121))
    truth = np.stack([np.full_like(rot, 40.0), rot, np.full_like(rot, 25.0)], axis=1)
    raw = np.degrees(principal(human, "jRightShoulder", truth))
    assert np.max(np.abs(raw[:, 1])) <= 90.0 + 1e-9
    assert np.max(np.abs(np.diff(raw[:, 0]))) > 170.0  # the branch jump
    np.testing.assert_allclose(np.degrees(continuous_series(np.radians(raw))), truth, atol=1e-6)


def test_the_chosen_triple_is_the_same_rotation(human: HumanModel, rng) -> None:
    spec = human.ball_joints["jLeftHip"].spec
    for _ in range(200):
        a = rng.uniform(-np.pi, np.pi, 3) * np.array([1.0, 0.5, 1.0])
        a[1] += rng.choice([0.0, 0.49 * np.pi])  # near the singularity too
        reference = rng.uniform(-2 * np.pi, 2 * np.pi, 3)
        chosen, flipped = nearest_equivalent(a, reference)
        np.testing.assert_allclose(spec.rotation(chosen), spec.rotation(a), atol=1e-12)
        other = equivalent_triple(a)
        np.testing.assert_allclose(spec.rotation(other), spec.rotation(a), atol=1e-12)
        # no candidate triple is closer to the reference
        for candidate in (a, other):
            shifted = candidate + 2 * np.pi * np.round((reference - candidate) / (2 * np.pi))
            assert np.sum((chosen - reference) ** 2) <= np.sum((shifted - reference) ** 2) + 1e-12
        assert bool(flipped) == (not np.allclose(chosen, wrap_near(a, reference)))


def test_the_causal_per_frame_angles_equal_the_series(human: HumanModel) -> None:
    rot = 90.0 - 30.0 * np.cos(np.linspace(0.0, 2.0 * np.pi, 61))
    qs = np.array([human.configuration({"jRightShoulder_flex": 40.0, "jRightShoulder_rot": r,
                                        "jRightShoulder_abd": 25.0}) for r in rot])
    series = human.joint_angle_matrix(qs)
    previous = None
    for k, q in enumerate(qs):
        previous = human.joint_angles(q, previous)
        np.testing.assert_allclose([previous[c] for c in human.angle_columns], series[k],
                                   atol=1e-9)
    k = human.angle_columns.index("jRightShoulder_rot")
    np.testing.assert_allclose(series[:, k], rot, atol=1e-6)


def test_a_joint_with_nan_keeps_its_last_good_reference(human: HumanModel) -> None:
    twist = np.linspace(150.0, 210.0, 7)
    columns = ["jT9T8_flex", "jT9T8_abd", "jT9T8_rot"]
    wrapped = (twist + 180.0) % 360.0 - 180.0
    table = np.stack([np.zeros(7), np.zeros(7), wrapped], axis=1)
    table[3] = np.nan
    out = continuous_columns_deg(table, columns,
                                 {n: j.spec for n, j in human.ball_joints.items()})
    assert np.all(np.isnan(out[3]))
    keep = np.arange(7) != 3
    np.testing.assert_allclose(out[keep, 2], twist[keep], atol=1e-9)


def test_a_pose_beyond_a_limit_is_measured_from_that_limit(human: HumanModel) -> None:
    """A hip flexed to 185 deg is 55 deg beyond the 130 deg limit, not 140 deg below -35."""
    joint = human.ball_joints["jRightHip"].spec
    lower = np.radians([a.lower_deg for a in joint.angles])
    upper = np.radians([a.upper_deg for a in joint.angles])
    raw = principal(human, "jRightHip", np.array([185.0, 10.0, 5.0]))
    assert np.degrees(raw[0]) < 0.0  # the principal triple reads -175 deg
    chosen, flipped = nearest_to_ranges(raw, lower, upper, joint.axis_coupling)
    assert not flipped
    np.testing.assert_allclose(np.degrees(chosen), [185.0, 10.0, 5.0], atol=1e-9)


def nearest_in_range_deg(spec, R: np.ndarray) -> float:
    """Brute force: the least turn [deg] from ``R`` to a rotation whose angles are in range."""
    bounds = [(np.radians(a.lower_deg), np.radians(a.upper_deg)) for a in spec.angles]
    starts = [np.clip(x, *np.array(bounds).T) for x in (
        spec.angles_from_rotation(R), equivalent_triple(spec.angles_from_rotation(R)))]
    best = np.inf
    for x0 in starts:
        fit = minimize(lambda x: float(angle_between(spec.rotation(x), R)), x0,
                       method="Powell", bounds=bounds, options={"xtol": 1e-6, "ftol": 1e-10})
        best = min(best, float(fit.fun))
    return float(np.degrees(best))


def test_a_pose_near_gimbal_lock_is_measured_on_the_branch_a_small_turn_brings_in(
        human: HumanModel) -> None:
    """Issue #19 (cmu-02-10-wash, a 20 deg pop): a right shoulder at 74 deg axial rotation,
    sensed 21 deg past its -65 deg extension limit with its abduction 21 deg up (5.8 deg of
    sensor error near gimbal lock). It is 6 deg of turn from its range on its own branch; the
    other branch (rotation 106 deg, 21 deg past 85) looked nearer angle by angle, and the solve
    was thrown through the lock."""
    spec = human.ball_joints["jRightShoulder"].spec
    lower = np.radians([a.lower_deg for a in spec.angles])
    upper = np.radians([a.upper_deg for a in spec.angles])
    sensed = np.radians([-86.45, 74.13, 129.92])  # flex, rot, abd
    chosen, flipped = nearest_to_ranges(sensed, lower, upper, spec.axis_coupling)
    assert not flipped
    np.testing.assert_allclose(chosen, sensed, atol=1e-12)
    turn = np.degrees(np.sqrt(turn_into_range(lower - chosen, upper - chosen,
                                              spec.axis_coupling * np.sin(chosen[1]))))
    truth = nearest_in_range_deg(spec, spec.rotation(sensed))  # 5.7 deg
    assert truth < 7.0
    assert abs(turn - truth) < 1.0  # first order, 21 deg of angles from the range


def test_the_turn_into_range_is_the_least_of_its_form_over_the_box(rng) -> None:
    """The closed form (interior or one of four clamped edges) against bounded least squares:
    the form is ``|A d|^2`` with ``A^T A = [[1, 0, k], [0, 1, 0], [k, 0, 1]]``."""
    for _ in range(300):
        low = rng.uniform(-1.0, 0.6, 3)
        high = low + rng.uniform(0.0, 1.5, 3)
        kappa = rng.uniform(-0.999, 0.999)
        A = np.linalg.cholesky(np.array([[1.0, 0.0, kappa], [0.0, 1.0, 0.0],
                                         [kappa, 0.0, 1.0]])).T
        fit = lsq_linear(A, np.zeros(3), bounds=(low, high), method="bvls", tol=1e-14)
        least = float(np.sum((A @ fit.x) ** 2))
        assert turn_into_range(low, high, np.array(kappa)) == pytest.approx(least, abs=1e-10)


def frame_by_frame(angles: np.ndarray) -> np.ndarray:
    """The documented rule one frame after the other (reference for the vectorised series)."""
    out = np.array(angles, dtype=float)
    flat = out.reshape(len(out), -1, 3)
    for j in range(flat.shape[1]):
        previous = None
        for k in range(len(flat)):
            if not np.isfinite(flat[k, j]).all():
                continue
            if previous is not None:
                flat[k, j] = nearest_equivalent(flat[k, j], previous)[0]
            previous = flat[k, j].copy()
    return out


@pytest.mark.parametrize("step_rad", [0.05, 0.8, 2.5, np.pi])
def test_the_series_equals_the_rule_applied_frame_by_frame(step_rad: float, rng) -> None:
    # Wrapped principal-like angles with gaps of NaN; large steps make near-ties between
    # the branches and between whole turns (where the vectorised path must fall back).
    for _ in range(20):
        n, joints = int(rng.integers(2, 300)), int(rng.integers(1, 4))
        raw = np.cumsum(rng.normal(0.0, step_rad, (n, joints, 3)), axis=0)
        raw = (raw + np.pi) % (2 * np.pi) - np.pi
        raw[..., 1] = np.clip(raw[..., 1], -np.pi / 2, np.pi / 2)
        raw[rng.random((n, joints)) < 0.1, int(rng.integers(0, 3))] = np.nan
        raw[: int(rng.integers(0, 3))] = np.nan
        got = continuous_series(raw)
        assert np.array_equal(np.isnan(got), np.isnan(raw))
        np.testing.assert_allclose(got, frame_by_frame(raw), rtol=0, atol=1e-12)


def test_a_long_series_needs_no_python_loop_per_frame(monkeypatch, rng) -> None:
    # 2505 frames of 23 joints took ~0.1 s each through a Python loop over frames (about a
    # second of every solve's result writing); all frames are now taken at once.
    import ikfusion.model.angle_continuity as module

    def per_frame_loop(rows: list[list[float]]) -> list[list[float]]:
        raise AssertionError("the per-frame Python loop ran on a smooth series")

    monkeypatch.setattr(module, "_continuous_triples", per_frame_loop)
    raw = np.cumsum(rng.normal(0.0, 0.05, (2505, 23, 3)), axis=0)
    raw = (raw + np.pi) % (2 * np.pi) - np.pi
    got = continuous_series(raw)
    assert np.abs(np.diff(got, axis=0)).max() < 0.5  # continuous: no wraps left


@pytest.mark.parametrize("step_rad", [0.05, 2.5, np.pi])
def test_joints_made_continuous_together_as_one_by_one_to_the_bit(step_rad: float, rng) -> None:
    """The joints finite in every frame go through at once; each must come out as alone."""
    raw = np.cumsum(rng.normal(0.0, step_rad, (400, 6, 3)), axis=0)
    raw = (raw + np.pi) % (2 * np.pi) - np.pi
    raw[..., 1] = np.clip(raw[..., 1], -np.pi / 2, np.pi / 2)
    raw[rng.random(400) < 0.1, 4, 0] = np.nan  # one joint with gaps
    together = continuous_series(raw)
    alone = np.stack([continuous_series(raw[:, j]) for j in range(6)], axis=1)
    assert np.array_equal(together.view(np.uint64), alone.view(np.uint64))


@pytest.mark.parametrize("step_rad", [0.05, 0.8, 2.5, np.pi])
def test_the_c_kernel_gives_the_numpy_paths_numbers_to_the_bit(step_rad: float, rng,
                                                               monkeypatch) -> None:
    # Random walks with NaN gaps, near-ties of branches and turns, and exact halves of a turn.
    import ikfusion.model.angle_continuity as module
    from ikfusion.model.continuity_kernel import continuous_in_place

    if not continuous_in_place(np.zeros((2, 1, 3))):
        pytest.skip("no C kernel (no compiler or IKFUSION_NO_COMPILE): NumPy runs")
    series = []
    for _ in range(20):
        n, joints = int(rng.integers(2, 300)), int(rng.integers(1, 5))
        raw = np.cumsum(rng.normal(0.0, step_rad, (n, joints, 3)), axis=0)
        raw = (raw + np.pi) % (2 * np.pi) - np.pi
        raw[..., 1] = np.clip(raw[..., 1], -np.pi / 2, np.pi / 2)
        raw[rng.random((n, joints)) < 0.1, int(rng.integers(0, 3))] = np.nan
        raw[: int(rng.integers(0, 3))] = np.nan
        series.append(raw)
    halves = np.array([[0.0, 0.0, 0.0], [np.pi, 0.0, -np.pi], [0.0, np.pi / 2, np.pi],
                       [-np.pi, -np.pi / 2, 0.0], [np.pi / 2, 0.0, -np.pi / 2]])
    series.append(np.resize(halves, (40, 3))[:, None])
    with_kernel = [continuous_series(raw) for raw in series]
    monkeypatch.setattr(module, "continuous_in_place", lambda flat: False)
    for raw, got in zip(series, with_kernel):
        assert np.array_equal(got.view(np.uint64), continuous_series(raw).view(np.uint64))
