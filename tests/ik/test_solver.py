"""The frame-by-frame solver against ground truth: exact targets, elevations, noise, relaxation."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from motions import frames_from, observable_columns, smooth_motion, wrap_deg

from ikfusion.ik import Frame, Solver
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.model import Body, HumanModel
from ikfusion.model.layout import CONTACT_SITES
from ikfusion.rotations import angle_between, exp_so3


def solve_exact(human: HumanModel, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    frames = frames_from(human, qs)
    motion = Solver(human, contacts=False).solve(frames)
    errors = []
    for frame, q in zip(frames, motion.q):
        for segment, R in frame.orientations.items():
            errors.append(angle_between(R, human.segment_rotation(q, segment)))
    return np.degrees(np.array(errors)), motion.q


def test_exact_targets_smooth_random_motion(human: HumanModel, rng) -> None:
    qs = smooth_motion(human, rng, frames=240)
    errors, q_est = solve_exact(human, qs)
    assert np.sqrt(np.mean(errors**2)) <= 0.2
    cols = observable_columns(human)
    truth = human.joint_angle_matrix(qs)[:, cols]
    diff = wrap_deg(truth - human.joint_angle_matrix(q_est)[:, cols])
    assert np.sqrt(np.mean(diff**2)) <= 0.5


@pytest.mark.parametrize(
    "fixed",
    [
        {"jRightShoulder_abd": 90.0},
        {"jLeftShoulder_flex": 90.0},
        {"jRightHip_flex": 90.0, "jRightKnee_flex": 90.0},
    ],
)
def test_no_gimbal_lock_at_elevations(human: HumanModel, rng, fixed: dict[str, float]) -> None:
    """Shoulder at 90 deg elevation with axial twist, hip at 90 deg flexion."""
    qs = smooth_motion(human, rng, frames=120, keys=4)
    twist = np.linspace(-60.0, 60.0, len(qs))
    data = []
    for q, t in zip(qs, twist):
        angles = human.joint_angles(q)
        angles.update(fixed)
        if "jRightShoulder_abd" in fixed:
            angles["jRightShoulder_rot"] = t
        if "jLeftShoulder_flex" in fixed:
            angles["jLeftShoulder_rot"] = t
        data.append(human.configuration(angles, q[:3], human.segment_rotation(q, "Pelvis")))
    qs = np.array(data)
    errors, q_est = solve_exact(human, qs)
    assert np.sqrt(np.mean(errors**2)) <= 0.2
    cols = observable_columns(human)
    truth = human.joint_angle_matrix(qs)[:, cols]
    diff = wrap_deg(truth - human.joint_angle_matrix(q_est)[:, cols])
    assert np.sqrt(np.mean(diff**2)) <= 0.5


def test_noise_never_pushes_joints_past_their_limits(human: HumanModel, rng) -> None:
    qs = smooth_motion(human, rng, frames=200, margin_deg=0.5)
    frames = frames_from(human, qs)
    noisy = [Frame(f.time, {s: exp_so3(np.radians(1.0) * rng.normal(size=3) / np.sqrt(3)) @ R
                            for s, R in f.orientations.items()}) for f in frames]
    motion = Solver(human, contacts=False).solve(noisy)
    limits = JointRangeLimit(human.ball_joints, margin_deg=25.0)
    worst = max(limits.violation_deg(q).max() for q in motion.q)
    assert worst <= 0.5


def test_missing_and_invalid_targets_are_simply_not_tracked(human: HumanModel, rng) -> None:
    qs = smooth_motion(human, rng, frames=30)
    frames = frames_from(human, qs)
    for k, f in enumerate(frames):
        orientations = dict(f.orientations)
        if k % 3 == 0:
            orientations["RightHand"] = np.full((3, 3), np.nan)
        if k % 4 == 0:
            orientations.pop("LeftForeArm")
        frames[k] = Frame(f.time, orientations, orientation_weights={"Head": 0.0})
    motion = Solver(human, contacts=False).solve(frames)
    assert np.all(np.isfinite(motion.q))
    R = human.segment_rotation(motion.q[-1], "RightUpperArm")
    assert np.degrees(angle_between(R, frames[-1].orientations["RightUpperArm"])) < 0.2


def test_unreachable_contacts_relax_instead_of_failing(human: HumanModel) -> None:
    """Both feet planted, then the legs are told to fold: constraints cannot all hold."""
    solver = Solver(human)
    q0 = human.neutral()
    pose = solver.step(Frame(0.0, {"Pelvis": np.eye(3)}))
    assert all(pose.contacts[n] for n in CONTACT_SITES)  # knees and palms stay up
    bent = human.configuration({"jRightHip_flex": 100.0, "jRightKnee_flex": 120.0,
                                "jLeftHip_flex": 100.0, "jLeftKnee_flex": 120.0}, q0[:3])
    targets = {s: human.segment_rotation(bent, s) for s in ("Pelvis", "RightUpperLeg",
                                                            "RightLowerLeg", "LeftUpperLeg",
                                                            "LeftLowerLeg", "RightFoot",
                                                            "LeftFoot")}
    pose = solver.step(Frame(1 / 60, targets))
    assert np.all(np.isfinite(pose.q))


def test_a_failing_qp_never_crashes_the_solve(human: HumanModel, rng, monkeypatch) -> None:
    import ikfusion.ik.active_set as solver_module
    from ikfusion.errors import SolverError

    qs = smooth_motion(human, rng, frames=12)
    frames = frames_from(human, qs)
    real = solver_module.solve_qp
    calls = {"n": 0}

    def flaky(problem, backend, settings, *hint):
        calls["n"] += 1
        if calls["n"] == 20:
            raise SolverError("no backend could solve it")
        return real(problem, backend, settings, *hint)

    monkeypatch.setattr(solver_module, "solve_qp", flaky)
    motion = Solver(human, contacts=False).solve(frames)
    assert len(motion) == len(frames) and np.all(np.isfinite(motion.q))
    assert motion.relaxed.sum() == 1
    assert any("no QP backend" in w for w in motion.warnings)


def test_a_still_foot_keeps_its_contacts(human: HumanModel) -> None:
    """The sensed pose says the left foot lifted, its IMU says it stands still (and the right
    foot moves): the left foot keeps its contacts and the right one lets go."""
    solver = Solver(human)
    q0 = human.neutral()
    segments = ("Pelvis", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "RightUpperLeg",
                "RightLowerLeg", "RightFoot")
    still = {s: human.segment_rotation(q0, s) for s in segments}
    assert all(solver.step(Frame(0.0, still)).contacts[n] for n in CONTACT_SITES)
    lifted_q = human.configuration({"jLeftHip_flex": 40.0, "jLeftKnee_flex": 60.0})
    lifted = {s: human.segment_rotation(lifted_q, s) for s in segments}
    held = solver.step(Frame(1 / 60, lifted, feet_still={"LeftFoot": True, "RightFoot": False}))
    assert held.contacts["LeftHeel"] and held.contacts["LeftToe"]
    assert not held.contacts["RightHeel"] and not held.contacts["RightToe"]
    fresh = Solver(human)
    fresh.step(Frame(0.0, still))
    released = fresh.step(Frame(1 / 60, lifted))
    assert not released.contacts["LeftHeel"]


def test_a_pose_beyond_a_limit_is_held_at_that_limit_not_thrown_to_the_other(
        human: HumanModel) -> None:
    """Swordplay's symptom: an arm raised forward past its 175 deg flexion limit, through the
    +-180 deg wrap of the Euler angle, and back. The solve must stay at the upper limit and follow
    the arm down, not jump to the -65 deg extension limit while the truth is beyond 180 deg."""
    flex = 140.0 + 80.0 * np.sin(np.linspace(0.0, np.pi, 90))  # 140 -> 220 -> 140 deg
    qs = np.array([human.configuration({"jLeftShoulder_flex": f, "jLeftShoulder_abd": 20.0,
                                        "jLeftShoulder_rot": 10.0}) for f in flex])
    _, q_est = solve_exact(human, qs)
    columns = ["jLeftShoulder_flex", "jLeftShoulder_abd", "jLeftShoulder_rot"]
    index = [human.angle_columns.index(c) for c in columns]
    solved = human.joint_angle_matrix(q_est)[:, index]
    assert np.max(np.abs(np.diff(solved, axis=0))) < 10.0  # no pop between frames
    beyond = flex > 175.0
    assert np.all(solved[beyond, 0] > 165.0)  # held near the limit it crossed
    inside = flex < 160.0  # well inside: the solve follows the truth again
    np.testing.assert_allclose(solved[inside, 0], flex[inside], atol=1.0)


def shoulder_rotations(human: HumanModel, qs: np.ndarray, side: str) -> np.ndarray:
    """(N, 3, 3) ``R_shoulder_upperarm`` of the ``side`` ("Left"/"Right") arm per configuration."""
    return np.array([human.segment_rotation(q, f"{side}Shoulder").T
                     @ human.segment_rotation(q, f"{side}UpperArm") for q in qs])


def test_a_shoulder_near_gimbal_lock_past_its_limit_is_held_there_not_thrown_through_it(
        human: HumanModel) -> None:
    """Issue #19 (cmu-02-10-wash: a 20 deg pop of the right shoulder, every mode): the upper arm
    sensed at 74 deg axial rotation moves past the -65 deg extension limit by up to 25 deg with
    the abduction rising as much (a few degrees of turn near gimbal lock). The solve must stay
    on the in-range pose nearest the arm (brute force), without a pop between frames; it was
    thrown through the lock to a pose 21 deg off the arm."""
    from scipy.optimize import minimize

    spec = human.ball_joint("jRightShoulder").spec
    flex = -55.0 - 35.0 * np.sin(np.linspace(0.0, np.pi, 90))  # -55 -> -90 -> -55 deg
    qs = np.array([human.configuration({"jRightShoulder_flex": f, "jRightShoulder_rot": 74.0,
                                        "jRightShoulder_abd": 108.0 - (f + 65.0)})
                   for f in flex])
    _, q_est = solve_exact(human, qs)
    target = shoulder_rotations(human, qs, "Right")
    solved = shoulder_rotations(human, q_est, "Right")
    error = np.degrees(angle_between(target, solved))
    bounds = [(np.radians(a.lower_deg), np.radians(a.upper_deg)) for a in spec.angles]
    for k in np.flatnonzero(flex < -80.0)[::6]:  # the farthest past the limit
        fit = minimize(lambda x, R=target[k]: float(angle_between(spec.rotation(x), R)),
                       np.clip(spec.angles_from_rotation(target[k]), *np.array(bounds).T),
                       method="Powell", bounds=bounds)
        assert error[k] <= np.degrees(fit.fun) + 1.5
    assert np.max(np.degrees(angle_between(solved[:-1], solved[1:]))) < 2.0


def test_an_arm_turning_through_the_shoulders_gimbal_lock_passes_without_a_pop(
        human: HumanModel) -> None:
    """Issue #19 (amp-cartwheels: a 7 deg pop of the left shoulder from perfect sensors, 10 deg
    with the default errors): the arm overhead turns about its long axis through the Euler
    lock of the shoulder (axial rotation 90 deg, where flexion and abduction only count by their
    sum, every other triple of the turn in range). The solve must follow it frame by frame; a
    limit of the axial rotation 5 deg short of the lock walled off a cone around it, the solve
    slid along the wall and crossed the cone in one frame. At 89 deg (the default) the cone is
    1 deg wide: 0.8 deg off the arm and a 1.3 deg pop; a range reaching the lock
    (``rot: [-90, 90]``, a limit at the lock is no limit) has no cone."""
    turn = arm_overhead_turning(human, 60.0, 100.0)
    for model, off_deg, pop_deg in ((human, 1.5, 2.0), (lock_free(), 0.01, 0.01)):
        error = shoulder_error(model, turn, noise_deg=0.0)
        assert np.max(np.degrees(angle_between(error, np.eye(3)))) < off_deg  # was 4.8 at 85
        # a pop across the walled-off cone changed the error by 9 deg in one frame at 85
        assert np.max(np.degrees(angle_between(error[:-1], error[1:]))) < pop_deg


@functools.cache
def lock_free() -> HumanModel:
    """The default model with both shoulders' axial rotation reaching the lock (+-90 deg)."""
    return HumanModel.from_body(Body(ranges=(("jLeftShoulder", "rot", -90.0, 90.0),
                                              ("jRightShoulder", "rot", -90.0, 90.0))))


def arm_overhead_turning(human: HumanModel, start_deg: float, end_deg: float) -> np.ndarray:
    """(60, nq) the left arm overhead (flexion 170, abduction -23 deg) turning about its long
    axis from ``start_deg`` to ``end_deg`` of axial rotation (through the lock at 90 deg)."""
    rot = np.linspace(start_deg, end_deg, 60)
    return np.array([human.configuration({"jLeftShoulder_flex": 170.0, "jLeftShoulder_rot": r,
                                          "jLeftShoulder_abd": -23.0}) for r in rot])


def shoulder_error(human: HumanModel, qs: np.ndarray, noise_deg: float,
                   seed: int = 0) -> np.ndarray:
    """(N, 3, 3) the left shoulder's error rotation ``R_true^T R_solved``, solved with the upper
    arm's sensor off by a slowly varying rotation of ``noise_deg`` RMS (random axes, averaged
    over 6 frames: 0.1 s at 60 Hz, like a real sensor's drifting error)."""
    frames = frames_from(human, qs)
    rng = np.random.default_rng(seed)
    white = rng.normal(size=(len(qs) + 5, 3))
    drift = np.stack([np.convolve(white[:, i], np.ones(6) / 6.0, mode="valid")
                      for i in range(3)], axis=1)
    drift *= np.radians(noise_deg) / np.sqrt(np.mean(np.sum(drift**2, axis=1)))
    for frame, turn in zip(frames, exp_so3(drift)):
        frame.orientations["LeftUpperArm"] = turn @ frame.orientations["LeftUpperArm"]
    solved = Solver(human, contacts=False).solve(frames).q
    return np.swapaxes(shoulder_rotations(human, qs, "Left"), -1, -2) \
        @ shoulder_rotations(human, solved, "Left")


@pytest.mark.parametrize("seed", range(8))
def test_a_noisy_arm_through_the_gimbal_lock_pops_no_more_than_away_from_it(
        human: HumanModel, seed: int) -> None:
    """Issue #19 (cmu-02-10-wash: the right shoulder crossing the lock, pops of 2 deg): the arm
    overhead turning through the shoulder's lock with a drifting 1 deg sensor error must be
    solved as smoothly as the same turn 40 deg short of the lock with the same error: the
    largest one-frame change of the error rotation (``evaluate``'s joint-angle jump) no larger,
    with the shoulders' axial rotation reaching the lock (:func:`lock_free`). The default limit
    at 89 deg walls off a cone around the lock that the solve has to get round: 0.2-0.9 deg
    more on six of these eight seeds."""
    errors = [shoulder_error(lock_free(), arm_overhead_turning(human, start, start + 40.0), 1.0,
                             seed) for start in (60.0, 20.0)]  # through the lock, away from it
    through, away = (np.max(np.degrees(angle_between(e[:-1], e[1:]))) for e in errors)
    assert through <= away + 0.05
