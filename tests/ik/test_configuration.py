"""Configuration: the frame positions it caches are those of Pinocchio's forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ikfusion.ik.configuration import Configuration
from ikfusion.model import CONTACT_SITES, HumanModel


def test_positions_are_the_frame_placements_of_the_configuration(human: HumanModel) -> None:
    model = human.model
    frames = [human.site_frame_id(s) for s in CONTACT_SITES]
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    conf = Configuration(model, q)
    truth = pin.Data(model)
    pin.framesForwardKinematics(model, truth, q)
    expected = np.array([truth.oMf[f].translation for f in frames])
    P = conf.positions(frames)
    np.testing.assert_allclose(P, expected, atol=1e-12)
    assert not P.flags.writeable
    assert conf.positions(frames) is P  # kept until the next update
    np.testing.assert_array_equal(conf.placement(frames[0]).translation, P[0])
    q2 = q.copy()
    q2[2] += 0.25  # the root 0.25 m higher: every point follows after update()
    conf.update(q2)
    np.testing.assert_allclose(conf.positions(frames), expected + [0.0, 0.0, 0.25], atol=1e-12)


def test_step_by_is_update_of_integrate_bit_for_bit(human: HumanModel) -> None:
    model, frames = human.model, [human.site_frame_id(s) for s in CONTACT_SITES]
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        dq = rng.normal(scale=0.3, size=model.nv)
        by_update, stepped = Configuration(model, q), Configuration(model, q)
        by_update.positions(frames)  # a cached point must not survive the step
        stepped.positions(frames)
        by_update.update(by_update.integrate(dq))
        stepped.step_by(dq)
        assert stepped.q.tobytes() == by_update.q.tobytes()
        assert not stepped.q.flags.writeable
        assert stepped.positions(frames).tobytes() == by_update.positions(frames).tobytes()
