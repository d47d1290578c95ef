"""PointsConfiguration: the contact points from one compiled call equal Pinocchio's kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.ik import Configuration, Solver
from ikfusion.ik.compiled import CompiledKinematics
from ikfusion.ik.points_configuration import PointsConfiguration
from ikfusion.model import SENSOR_SEGMENTS, Body, HumanModel
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames


def _random_configuration(model: HumanModel, rng: np.random.Generator) -> np.ndarray:
    """Every joint inside its range, the pelvis anywhere and turned any way (x, y, z, w)."""
    q = model.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
    quaternion = rng.normal(size=4)
    q[3:7] = quaternion / np.linalg.norm(quaternion)
    return q


@pytest.mark.parametrize("height", [1.55, 1.95])
def test_points_are_pinocchios_frame_positions_and_jacobians(rng, height: float) -> None:
    """Positions and world linear Jacobians of every contact point, of subsets in any order,
    asked for in any order between updates: Pinocchio's ``oMf`` translations and
    ``LOCAL_WORLD_ALIGNED`` frame Jacobians (to rounding), for two body sizes; a frame that is
    not a point is answered by Pinocchio."""
    model = HumanModel.from_body(Body.from_height(height))
    points = [model.site_frame_id(n) for n in model.sites_of_kind("contact")]
    kinematics = CompiledKinematics(model.model, [], [], [], points=points)
    assert kinematics.points_function is not None
    conf = PointsConfiguration(model.model, model.neutral(), points,
                               kinematics.points_function, kinematics.geometry(model.model))
    other = model.segment_frame_id("Head")  # not a point
    data = model.model.createData()
    for n in range(8):
        q = _random_configuration(model, rng)
        conf.update(q)
        pin.computeJointJacobians(model.model, data, q)
        pin.updateFramePlacements(model.model, data)
        P = np.array([data.oMf[f].translation for f in points])
        J = np.array([pin.getFrameJacobian(model.model, data, f, pin.LOCAL_WORLD_ALIGNED)[:3]
                      for f in points])
        subset = rng.permutation(len(points))[:5]
        ids = [points[i] for i in subset]
        if n % 2:  # the Jacobians asked for before the positions
            np.testing.assert_allclose(conf.linear_jacobians(ids), J[subset], atol=1e-12)
        got = conf.positions(points)
        assert not got.flags.writeable
        np.testing.assert_allclose(got, P, atol=1e-12)
        np.testing.assert_allclose(conf.positions(ids), P[subset], atol=1e-12)
        every = conf.linear_jacobians(points)  # a view of the output buffer: read-only
        assert not every.flags.writeable
        np.testing.assert_allclose(every, J, atol=1e-12)
        np.testing.assert_allclose(conf.linear_jacobians(ids), J[subset], atol=1e-12)
        np.testing.assert_allclose(conf.positions([other, points[0]]),
                                   [data.oMf[other].translation, P[0]], atol=1e-12)
        np.testing.assert_allclose(conf.linear_jacobians([other])[0], pin.getFrameJacobian(
            model.model, data, other, pin.LOCAL_WORLD_ALIGNED)[:3], atol=1e-12)


def test_the_solver_takes_its_contact_points_from_the_compiled_function(
        human: HumanModel, monkeypatch: pytest.MonkeyPatch) -> None:
    """A walk with contacts solved without a single Pinocchio kinematics pass of the solver's
    configuration (the contact points came from 14 Pinocchio calls per query), to the same
    configurations (1e-9) and contact states as with Pinocchio's points."""
    truth = generate_gait(human, GaitParameters(duration=3.0, stand=1.0), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    reference_solver = Solver(human)
    reference_solver._configuration = Configuration(human.model, human.neutral())
    reference = reference_solver.solve(frames)

    def no_pinocchio(self: Configuration) -> None:
        raise AssertionError("the contact points were asked of Pinocchio")

    solver = Solver(human)
    assert isinstance(solver._configuration, PointsConfiguration)
    monkeypatch.setattr(Configuration, "_kinematics", no_pinocchio)
    motion = solver.solve(frames)
    np.testing.assert_allclose(motion.q, reference.q, rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(motion.contacts, reference.contacts)
    assert motion.contacts.any()


def test_a_step_by_forgets_the_points_of_the_last_configuration(rng) -> None:
    """``step_by`` (the solver's Gauss-Newton step) is ``update(integrate(dq))`` for the compiled
    points too: the points and Jacobians read after it are those of the new ``q``, bit for bit."""
    model = HumanModel.default()
    points = [model.site_frame_id(n) for n in model.sites_of_kind("contact")]
    kinematics = CompiledKinematics(model.model, [], [], [], points=points)
    assert kinematics.points_function is not None
    geometry = kinematics.geometry(model.model)
    q = _random_configuration(model, rng)
    stepped, updated = (PointsConfiguration(model.model, q, points, kinematics.points_function,
                                            geometry) for _ in range(2))
    for _ in range(5):
        dq = rng.normal(scale=0.3, size=model.model.nv)
        stepped.positions(points)  # kept points and Jacobians must not survive the step
        stepped.linear_jacobians(points)
        stepped.step_by(dq)
        updated.update(updated.integrate(dq))
        assert stepped.q.tobytes() == updated.q.tobytes()
        assert stepped.positions(points).tobytes() == updated.positions(points).tobytes()
        assert stepped.linear_jacobians(points).tobytes() == \
            updated.linear_jacobians(points).tobytes()
