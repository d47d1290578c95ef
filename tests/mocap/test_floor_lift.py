"""Mocap read onto our body never goes deep under the floor (`from_bvh.floor_lift`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.ik import Frame, Solver
from ikfusion.mocap.from_bvh import (
    FLOOR_LIFT_BLEND_S,
    FLOOR_OUTLIER,
    floor_lift,
    motion_from_bvh,
)
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import SENSOR_SEGMENTS
from ikfusion.sim.imu import ImuNoise, simulate_imus

MOTIONS = Path(__file__).resolve().parents[2] / "benchmarks" / "motions"


def test_lift_holds_every_point_near_the_floor_and_rises_smoothly() -> None:
    """A point dipping 8 cm under the floor for half a second: lifted out, nowhere else.

    Depths within the floor fit's scatter (``FLOOR_OUTLIER``) are left alone.
    """
    rate = 60.0
    time = np.arange(240) / rate
    dip = np.where(np.abs(time - 2.0) < 0.25, 0.08 * np.cos(np.pi * (time - 2.0) / 0.5), 0.0)
    points = np.zeros((len(time), 2, 3))
    points[:, 0, 2] = -dip  # a palm through the floor and out again
    points[:, 1, 2] = 0.3 + 0.1 * np.sin(time)  # a point above it all along
    points[:150, 1, 2] = -0.5 * FLOOR_OUTLIER  # ... after standing a little under it
    lift = floor_lift(points, time)
    assert (points[:, 0, 2] + lift).min() >= -FLOOR_OUTLIER - 1e-12  # never deeper
    # tight: at the deepest frame the point is lifted to the tolerance within 5 mm, and far
    # from the dip (more than the blend) nothing is lifted
    assert lift[np.argmax(dip)] - (dip.max() - FLOOR_OUTLIER) < 0.005
    far = np.abs(time - 2.0) > 0.25 + FLOOR_LIFT_BLEND_S
    assert np.abs(lift[far]).max() < 1e-12
    # its velocity has no step: at most a blend's worth of change per frame
    velocity = np.diff(lift) * rate
    assert np.abs(np.diff(velocity)).max() < 0.08 / FLOOR_LIFT_BLEND_S


def test_cartwheel_palms_stay_on_the_floor_and_the_inverted_head_is_where_a_solve_puts_it(
        ) -> None:
    """CMU 49_08's cartwheels on our body: the straight hands went 19 cm under the floor.

    A solver holds a palm on the floor, so against that truth a perfect-sensor IMU-only solve
    stood 15-17 cm too high while upside down (issue #19's head error of every mode). Lifted
    out of the floor (to within its tolerance), the truth and the solve agree on the inverted
    head's height.
    """
    truth = motion_from_bvh(MOTIONS / "cmu_49_08_cartwheels_amp.bvh.gz", direct=True)
    model = truth.model
    P = site_positions(model, truth.q, truth.contact_names)
    assert P[..., 2].min() > -FLOOR_OUTLIER - 0.001
    assert truth.info["floor_lift_max_m"] > 0.1
    imus = simulate_imus(model, truth.time, truth.q, SENSOR_SEGMENTS, np.random.default_rng(1),
                         ImuNoise.none(), random_mounting=False)
    frames = [Frame(float(t), {s: imus.R_world_sensor[i, k]
                               for i, s in enumerate(SENSOR_SEGMENTS)})
              for k, t in enumerate(truth.time)]
    motion = Solver(model).solve(frames)
    pelvis_up = np.array([model.segment_rotation(q, "Pelvis")[2, 2] for q in truth.q])
    inverted = pelvis_up < -0.5
    assert inverted.sum() > 20
    head_true = site_positions(model, truth.q, ["HeadTop"])[inverted, 0, 2]
    head = site_positions(model, motion.q, ["HeadTop"])[inverted, 0, 2]
    assert np.sqrt(np.mean((head - head_true) ** 2)) == pytest.approx(0.0, abs=0.04)
