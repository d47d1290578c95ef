"""A pull on the flying path never presses the body through the floor (issue #19).

The drift correction moves the solver's ballistic path toward the tags in flight
(:meth:`ikfusion.ik.ballistic.BallisticRoot.shift`, in height too when the head's tag has a
fix). In a false flight of a body on the floor (the head's tag ran away and every point was let
go: dm-getup-facedown, causal) the path still rose slowly with the body's last velocity while
the head's tag pulled it down at about 1 m/s: the pelvis sank 16 cm under the height at which the
sensed pose reaches the floor, the floor held the palm up and bent the elbow 12 deg from its
sensors, and the landing straightened it in one frame (6.7 deg against the truth's change).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from motions import frames_from

from ikfusion.ik import Solver
from ikfusion.ik.ballistic import BallisticRoot
from ikfusion.model import HumanModel

RATE = 60.0
FLIGHT = range(60, 72)  # frames whose points are all hinted off: a false flight
PULL = 1.0 / RATE  # the tags pull the path down by this much per frame [m] (1 m/s)


def _rising_squat(model: HumanModel, frames: int = 150) -> np.ndarray:
    """Configurations (frames, nq) of a body rising from a squat, feet flat on the floor."""
    qs = []
    for k in range(frames):
        s = min(max((k - 30) / 90.0, 0.0), 1.0)
        bend = 1.0 - 0.9 * s * s * (3.0 - 2.0 * s)
        angles = {}
        for side in ("Right", "Left"):
            angles.update({f"j{side}Hip_flex": 60.0 * bend, f"j{side}Knee_flex": 90.0 * bend,
                           f"j{side}Ankle_flex": 30.0 * bend})
        qs.append(model.configuration(angles))
    return np.array(qs)


def test_a_shift_lowers_the_path_onto_the_landing_height_never_under_it() -> None:
    dt = 1.0 / RATE
    root = BallisticRoot(tau=0.2)
    root.velocity = np.array([0.0, 0.0, 0.2])  # still rising with the body's last velocity
    p = root.target(np.array([0.0, 0.0, 0.5]), dt, np.zeros(3), lowest_z=0.49)
    root.update(np.zeros(3), dt, np.zeros(3), supported=False)
    root.shift(np.array([0.01, 0.0, -0.03]))
    lowered = root.target(p, dt, np.zeros(3), lowest_z=0.5)
    assert lowered[0] == pytest.approx(p[0] + 0.01)  # horizontally the shift is kept
    assert lowered[2] == pytest.approx(0.5)  # down onto the landing height, not under it
    root.update(np.zeros(3), dt, np.zeros(3), supported=False)
    root.shift(np.array([0.0, 0.0, -0.03]))
    free = lowered[2] + root.velocity[2] * dt
    # already under the landing height (a take-off's level toes): the shift lowers it no more
    assert root.target(lowered, dt, np.zeros(3), lowest_z=0.6)[2] == pytest.approx(free)


def test_a_false_flight_pulled_down_keeps_the_legs_on_their_sensors(human: HumanModel) -> None:
    truth = _rising_squat(human)
    frames = frames_from(human, truth)
    solver = Solver(human)
    off = dict.fromkeys(solver.contact_names, False)
    # the body rests on the floor: its accelerometer measures no free fall
    frames = [replace(f, contacts=off, root_acceleration=np.zeros(3)) if k in FLIGHT else f
              for k, f in enumerate(frames)]

    def pull(solver: Solver, _pose: object, k: int, _dt: float) -> None:
        if k + 1 in FLIGHT:  # as the correction's flight pull does between two frames
            solver.ballistic.shift(np.array([0.0, 0.0, -PULL]))

    q = np.asarray(solver.solve(frames, after_step=pull).q)
    columns = human.angle_columns
    knees = [columns.index(f"j{side}Knee_flex") for side in ("Right", "Left")]
    error = human.joint_angle_matrix(q)[:, knees] - human.joint_angle_matrix(truth)[:, knees]
    # the floor does not fold the knees away from their sensors ...
    assert np.abs(error).max() < 2.0  # [deg]
    # ... and the landing does not straighten them in one frame
    assert np.abs(np.diff(error, axis=0)).max() < 1.0  # [deg]
