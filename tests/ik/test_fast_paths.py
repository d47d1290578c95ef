"""The solver's fast paths compute the very numbers of the plain NumPy formulas they replace.

Speed work must not change a solve (issue #20): each shortcut is checked against the
straightforward formula, on the model's own Jacobians and on random arrays (bit for bit where it
keeps the order of the operations, to rounding where a matrix product sums in another order).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.ik import Configuration, SolverSettings
from ikfusion.ik.fast_math import (
    any_true,
    count_true,
    mean_rows,
    min_of,
    row_norms,
    true_indices,
)
from ikfusion.ik.limits import ContactConstraint, FloorLimit
from ikfusion.ik.tasks import PositionTask
from ikfusion.ik.tasks.position import add_products
from ikfusion.model import HumanModel
from ikfusion.rotations import random_rotations


def random_configuration(human: HumanModel, rng: np.random.Generator) -> np.ndarray:
    q = human.neutral()
    q[:3] = rng.normal(size=3)
    for joint in human.ball_joints.values():  # every ball joint turned at random
        R = random_rotations(1, rng)[0]
        q[joint.idx_q:joint.idx_q + 4] = pin.Quaternion(R).coeffs()
    return q


def test_any_true_and_true_indices_are_numpys_answers() -> None:
    """Masks and numbers of every kind the solver asks about: empty, all False, one True,
    NaN (non-zero), -0.0 (zero), 2-D offsets, strided views."""
    rng = np.random.default_rng(5)
    cases = [np.zeros(0, dtype=bool), np.zeros(4, dtype=bool), np.eye(4, dtype=bool)[2],
             np.array([0.0, -0.0]), np.array([0.0, np.nan]), np.zeros((4, 3)),
             np.eye(3)[1:], rng.normal(size=(5, 3)) * (rng.random((5, 3)) < 0.3)]
    cases += [rng.random(n) < p for n in (1, 4, 9) for p in (0.0, 0.2, 1.0)]
    cases += [c[::2] for c in list(cases)]
    for values in cases:
        assert any_true(values) is bool(np.any(values))
        assert count_true(values) == np.count_nonzero(values)
        if values.size:
            assert np.array_equal(min_of(values), values.min(), equal_nan=True)
        if values.ndim == 1:
            assert np.array_equal(true_indices(values), np.flatnonzero(values))


def test_clipping_a_short_vector_is_the_plain_formula() -> None:
    """The support's clip of a vector already within its limit returns the bits of
    ``v - shrink(v, limit)`` (zeros of either sign as +0.0), and the same numbers when longer."""
    from ikfusion.ik.fast_math import clip_norm, shrink

    rng = np.random.default_rng(11)
    vectors = [np.zeros(3), np.array([-0.0, 0.0, -0.0]), np.array([0.03, -0.0, 0.0]),
               *rng.normal(size=(40, 3)) * 10.0 ** rng.integers(-6, 1, size=(40, 1))]
    for v in vectors:
        n = float(np.linalg.norm(v))
        for limit in (0.0, 0.5 * n, n, 2.0 * n + 1e-9, 0.04, np.inf):
            assert clip_norm(v, limit).tobytes() == (v - shrink(v, limit)).tobytes()


@pytest.mark.parametrize("shape", [(1, 3), (4, 3), (4, 2), (7, 5)])
def test_row_norms_and_mean_rows_are_numpys_numbers(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(3)
    v = rng.normal(size=shape) * 10.0 ** rng.integers(-8, 8, size=shape)
    for x in (v, np.hstack([v, v])[:, ::2]):  # contiguous and strided rows
        assert np.array_equal(row_norms(x), np.linalg.norm(x, axis=1))
        assert np.array_equal(mean_rows(x), np.mean(x, axis=0))


def test_other_foot_is_the_masked_any_of_the_layout(human: HumanModel) -> None:
    """The boolean product over the points of the other foot answers what the plain mask
    formula answers, for every mask of the feet's points."""
    from ikfusion.ik.foot_pairs import other_foot
    from ikfusion.model.topology import BodyTopology

    layout = BodyTopology.of(human).foot_layout(human.sites_of_kind("contact"))
    k = len(layout.same_foot)
    rng = np.random.default_rng(11)
    masks = [np.zeros(k, dtype=bool), np.ones(k, dtype=bool), *np.eye(k, dtype=bool)]
    for mask in masks + [rng.random(k) < 0.4 for _ in range(50)]:
        expected = (~layout.same_foot & mask[None, :]).any(axis=1)
        got = other_foot(layout, mask)
        assert got.dtype == bool
        assert np.array_equal(got, expected)


def test_position_rows_are_the_dense_sums(human: HumanModel) -> None:
    """Only the moving columns are summed, yet H and c equal the dense ``J^T W J`` sums."""
    rng = np.random.default_rng(5)
    sites = ["LeftHeel", "RightToe", "HeadTop", "RightHand"]
    task = PositionTask([human.site_frame_id(s) for s in sites], sites, weight=3.0)
    information = np.array([m @ m.T for m in rng.normal(size=(4, 3, 3))])
    information[2] = 0.0  # a site without a target this frame
    task.set_targets(rng.normal(size=(4, 3)), information)
    conf = Configuration(human.model, random_configuration(human, rng))
    P, J = conf.positions(task.frame_ids), conf.linear_jacobians(task.frame_ids)
    assert not J.reshape(-1, human.model.nv).any(axis=0).all()  # some columns do not move
    H0 = rng.normal(size=(human.model.nv, human.model.nv))
    c0 = rng.normal(size=human.model.nv)
    H, c = H0.copy(), c0.copy()
    task.add_rows(P, J, H, c)
    on = information.any(axis=(1, 2))
    WJ = task.weight * information[on] @ J[on]
    np.testing.assert_allclose(H, H0 + np.einsum("kin,kim->nm", J[on], WJ), rtol=1e-13,
                               atol=1e-12)
    np.testing.assert_allclose(c, c0 + np.einsum("kin,ki->n", WJ, P[on] - task.targets[on]),
                               rtol=1e-13, atol=1e-12)


def test_add_products_leaves_the_still_columns_alone() -> None:
    rng = np.random.default_rng(8)
    J = np.zeros((3, 10))
    J[:, [0, 4, 7]] = rng.normal(size=(3, 3))
    H, c = np.full((10, 10), 2.0), np.full(10, -1.0)
    add_products(J, 2.0 * J, rng.normal(size=3), H, c)
    still = [1, 2, 3, 5, 6, 8, 9]
    assert (H[still] == 2.0).all() and (H[:, still] == 2.0).all() and (c[still] == -1.0).all()
    assert (H[np.ix_([0, 4, 7], [0, 4, 7])] != 2.0).all()


def test_planted_slide_is_slide_m_without_the_free_points(human: HumanModel) -> None:
    rng = np.random.default_rng(2)
    names = human.sites_of_kind("contact")[:4]  # the feet's heel and toe points
    contact = ContactConstraint([human.site_frame_id(n) for n in names], names)
    conf = Configuration(human.model, random_configuration(human, rng))
    P = conf.positions(contact.frame_ids)
    contact.set_anchors([True, False, True, True], P + rng.normal(size=P.shape),
                        [False, False, True, False])
    slide = contact.slide_m(conf)
    assert np.array_equal(contact.planted_slide_m(P), slide[np.isfinite(slide)])
    rows = contact.rows(P, conf.linear_jacobians(contact.frame_ids))
    assert rows.A.shape[0] == 3 + 2 + 3  # the rising point (free_z) is held horizontally only
    # the projection hands its positions to the rows: the same rows as from the kinematics
    for given, fresh in zip(contact.equality(conf, P),
                            contact.equality(Configuration(human.model, conf.q))):
        assert np.array_equal(given, fresh)


def test_the_projection_qp_rows_are_the_kinematics_rows(human: HumanModel) -> None:
    """The projection's QP takes the contact and floor rows from every point's positions and
    Jacobians (a view of the points function's output): the very rows of
    :meth:`ContactConstraint.equality` and :meth:`FloorLimit.inequality`."""
    rng = np.random.default_rng(5)
    names = human.sites_of_kind("contact")
    frames = [human.site_frame_id(n) for n in names]
    contact, floor = ContactConstraint(frames, names), FloorLimit(frames, -0.1)
    conf = Configuration(human.model, random_configuration(human, rng))
    P = conf.positions(frames)
    planted = rng.random(len(frames)) < 0.5
    contact.set_anchors(planted, P + rng.normal(scale=0.01, size=P.shape), planted & (rng.random(
        len(frames)) < 0.5))
    floor.enabled = ~planted | contact.free_z
    J = conf.linear_jacobians(frames)
    for given, fresh in [*zip(contact.rows(P, J), contact.equality(conf)),
                         *zip(floor.rows(P, J), floor.inequality(conf))]:
        assert np.array_equal(given, fresh)


@pytest.mark.parametrize("seed", range(4))
def test_slides_is_any_planted_slide_beyond_the_tolerance(human: HumanModel, seed: int) -> None:
    """The projection's Python-float test against ``planted_slide_m`` in NumPy, at tolerances
    just below, at and just above each planted point's own slide (and with a NaN position)."""
    rng = np.random.default_rng(seed)
    names = human.sites_of_kind("contact")[:4]
    contact = ContactConstraint([human.site_frame_id(n) for n in names], names)
    P = Configuration(human.model, random_configuration(human, rng)).positions(contact.frame_ids)
    contact.set_anchors(rng.random(4) < 0.7, P + rng.normal(scale=1e-4, size=P.shape),
                        rng.random(4) < 0.5)
    for positions in (P, np.where(rng.random(P.shape) < 0.2, np.nan, P)):
        slide = contact.planted_slide_m(positions)
        for tolerance in [*slide, *np.nextafter(slide, 0.0), *np.nextafter(slide, 1.0), 0.0]:
            assert contact.slides(positions, tolerance) == any_true(slide > tolerance)


def test_qp_settings_are_made_once() -> None:
    settings = SolverSettings.load()
    assert settings.qp is settings.qp
    assert settings.qp.max_iterations == settings.qp_max_iterations


@pytest.mark.parametrize("reach", [None, 0.05])
def test_scalar_position_weights_are_their_information_matrices(human: HumanModel,
                                                                 reach: float | None) -> None:
    """Scalar weights (the root, swing feet) take a row-by-row shortcut; a NaN target, a zero
    weight and information matrices ``w I`` give the very numbers of the 3x3 products."""
    rng = np.random.default_rng(11)
    sites = ["LeftHeel", "RightToe", "HeadTop", "RightHand"]
    targets = rng.normal(size=(4, 3))
    targets[1] = np.nan  # a site whose target is lost this frame
    w = np.array([2.0, 1.0, 0.0, 0.5])  # HeadTop: no target
    conf = Configuration(human.model, random_configuration(human, rng))
    results = []
    for weights in (w, w[:, None, None] * np.eye(3)):
        task = PositionTask([human.site_frame_id(s) for s in sites], sites, weight=3.0)
        task.reach = reach
        task.set_targets(targets, weights)
        H, c = np.zeros((human.model.nv,) * 2), np.zeros(human.model.nv)
        task.add_rows(conf.positions(task.frame_ids), conf.linear_jacobians(task.frame_ids),
                      H, c)
        results.append((task.targets, task.information, H, c))
    for scalar, matrix in zip(*results):
        assert np.array_equal(scalar, matrix)
    # ... and those of the plain formula, with the lost and the zero-weight rows left out
    on = np.array([True, False, False, True])
    J = conf.linear_jacobians(task.frame_ids)[on]
    e = conf.positions(task.frame_ids)[on] - targets[on]
    if reach is not None:
        e *= np.minimum(1.0, reach / np.linalg.norm(e, axis=1))[:, None]
    WJ = 3.0 * w[on][:, None, None] * J
    np.testing.assert_allclose(results[0][2], np.einsum("kin,kim->nm", J, WJ), rtol=1e-13,
                               atol=1e-12)
    np.testing.assert_allclose(results[0][3], np.einsum("kin,ki->n", WJ, e), rtol=1e-13,
                               atol=1e-12)


def test_information_assigned_directly_weighs_the_rows(human: HumanModel) -> None:
    """The residual report assigns ``information`` itself: the rows follow what it holds."""
    rng = np.random.default_rng(12)
    sites = ["LeftHeel", "HeadTop"]
    task = PositionTask([human.site_frame_id(s) for s in sites], sites)
    task.set_targets(rng.normal(size=(2, 3)), np.zeros(2))  # no target: no rows
    conf = Configuration(human.model, random_configuration(human, rng))
    P, J = conf.positions(task.frame_ids), conf.linear_jacobians(task.frame_ids)
    nv = human.model.nv
    H, c = np.zeros((nv, nv)), np.zeros(nv)
    task.add_rows(P, J, H, c)
    assert not H.any() and not c.any()
    W = np.array([[[4.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 1.0]], np.zeros((3, 3))])
    task.information = W  # an anisotropic matrix on the heel only
    task.add_rows(P, J, H, c)
    np.testing.assert_allclose(H, J[0].T @ W[0] @ J[0], rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(c, J[0].T @ W[0] @ (P[0] - task.targets[0]), rtol=1e-13,
                               atol=1e-12)


def test_compiled_and_numpy_steps_agree_with_contacts_and_limits(human: HumanModel) -> None:
    """A walk with planted feet, the floor and the ranges of motion: the compiled step (its QP
    stacked at once) and the NumPy tasks' step give the same motion and the same contacts."""
    from ikfusion.ik import Solver
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=2.5, stand=0.5), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    fast = Solver(human, contacts=True)
    assert fast.compiled is not None
    fast_motion = fast.solve(frames)
    plain = Solver(human, contacts=True, compiled=False).solve(frames)
    assert (fast_motion.contacts != fast_motion.contacts[0]).any()  # feet lift and plant
    assert np.array_equal(fast_motion.contacts, plain.contacts)
    np.testing.assert_allclose(fast_motion.q, plain.q, atol=1e-6)


def test_the_compiled_step_sums_the_chain_share_and_the_persistence_itself(
        human: HumanModel, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue #20: the chain-share and persistence tasks cost a compiled step no NumPy work
    (their objectives are in the step function), and the walk is solved as with the NumPy
    tasks. Before, each step summed them in NumPy (the chain share took a quarter of the QP
    build)."""
    from ikfusion.ik import Solver
    from ikfusion.ik.tasks import ChainShareTask
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=1.5, stand=0.3), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    plain = Solver(human, contacts=True, compiled=False).solve(frames)
    fast = Solver(human, contacts=True)
    assert fast.compiled is not None
    held: list[float] = []
    original = ChainShareTask.set_previous

    def set_previous(task: ChainShareTask, q_previous: np.ndarray | None) -> None:
        original(task, q_previous)
        held.append(float(task.row_weights().max()))

    def numpy_objective(*_: object, **__: object) -> None:
        raise AssertionError("a task summed in NumPy on the compiled path")

    monkeypatch.setattr(ChainShareTask, "set_previous", set_previous)
    monkeypatch.setattr(ChainShareTask, "add_objective", numpy_objective)
    monkeypatch.setattr(ChainShareTask, "_logs", numpy_objective)
    monkeypatch.setattr(fast.persistence.task, "add_objective", numpy_objective)
    monkeypatch.setattr(fast.persistence.task, "compute_error", numpy_objective)
    motion = fast.solve(frames)
    assert max(held) == fast.settings.chain_share > 0.0  # the share was on
    assert fast.persistence.weight > 0.0
    np.testing.assert_allclose(motion.q, plain.q, atol=1e-6)


def test_a_persistence_weighing_the_root_is_summed_in_numpy(human: HumanModel,
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    """The compiled persistence covers the joints only: weights on the root's columns send the
    task to NumPy, and the compiled solve still equals the NumPy one."""
    from ikfusion.ik import Solver
    from ikfusion.ik.sensed_pose import Persistence
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    hold = Persistence.hold

    def hold_the_root_too(self: Persistence, q_warm: np.ndarray, sensed_joints: np.ndarray,
                          bent: np.ndarray | None) -> None:
        hold(self, q_warm, sensed_joints, None if bent is None else bent + 0.01)
        weights = self.task.weights.copy()  # (hold's weights are shared from frame to frame)
        weights[:6] = 5.0
        self.task.weights = weights

    monkeypatch.setattr(Persistence, "hold", hold_the_root_too)
    truth = generate_gait(human, GaitParameters(duration=0.5, stand=0.2), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    fast = Solver(human, contacts=False)
    calls: list[int] = []
    numpy_objective = fast.persistence.task.add_objective

    def counted(*args: object) -> None:
        calls.append(1)
        numpy_objective(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(fast.persistence.task, "add_objective", counted)
    motion = fast.solve(frames)
    assert calls  # summed in NumPy
    plain = Solver(human, contacts=False, compiled=False).solve(frames)
    np.testing.assert_allclose(motion.q, plain.q, atol=1e-7)


def test_frame_targets_follow_the_segments_each_frame_holds(human: HumanModel) -> None:
    """The rows of a set of segments are kept from frame to frame: a sensor that drops out or
    comes back, a heading turn and an unknown segment name are still read right."""
    from ikfusion.errors import NameNotFound
    from ikfusion.ik import Frame, Solver

    rng = np.random.default_rng(13)
    solver = Solver(human, contacts=False)
    names = ["Pelvis", "LeftFoot", "Head"]
    R = dict(zip(names, random_rotations(3, rng)))
    heading = random_rotations(1, rng)[0]
    index = {n: i for i, n in enumerate(human.segment_names)}
    for held in (names, names[::2], names[::-1]):
        targets = solver.targets.load(Frame(0.0, {n: R[n] for n in held}), heading)
        assert set(np.flatnonzero(targets.tracked)) >= {index[n] for n in held}
        for n in held:
            np.testing.assert_allclose(targets.R_sensed[index[n]], heading @ R[n], atol=1e-15)
        assert solver.tasks.orientation.weights[index[names[1]]] == (names[1] in held)
    with pytest.raises(NameNotFound, match="Pelvis"):  # the message lists the valid names
        solver.targets.load(Frame(0.0, {"Pelvis": R["Pelvis"], "Tail": R["Head"]}), None)


def test_stacked_orientations_load_the_targets_of_the_dict(human: HumanModel) -> None:
    """A frame that carries its orientations stacked (``Frame.orientations_stacked``) loads
    the very targets of one that does not, heading turned or not."""
    from ikfusion.ik import Frame, Solver

    rng = np.random.default_rng(19)
    names = ["Pelvis", "LeftFoot", "Head", "RightLowerLeg"]
    R = random_rotations(len(names), rng)
    plain, stacked = Solver(human, contacts=False), Solver(human, contacts=False)
    for heading in (None, random_rotations(1, rng)[0]):
        got = stacked.targets.load(Frame(0.0, dict(zip(names, R)), orientations_stacked=R),
                                   heading)
        want = plain.targets.load(Frame(0.0, dict(zip(names, R))), heading)
        assert np.array_equal(got.R_sensed, want.R_sensed)
        assert np.array_equal(got.tracked, want.tracked)


def test_simulated_frames_stacked_solve_as_plain_ones(human: HumanModel) -> None:
    """``orientation_frames(..., stacked=True)`` (bench_ik's frames, stacked as the
    application's are) hold the plain frames' orientations and are solved to the same poses."""
    from ikfusion.ik import Solver
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=0.5, stand=0.2), rate=60.0)
    plain = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    stacked = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS, stacked=True)
    for a, b in zip(plain, stacked):
        assert a.orientations_stacked is None and b.orientations_stacked is not None
        assert np.array_equal(b.orientations_stacked, np.array(list(a.orientations.values())))
        assert all(np.array_equal(a.orientations[s], b.orientations[s]) for s in a.orientations)
    q_plain = Solver(human).solve(plain).q
    assert np.array_equal(Solver(human).solve(stacked).q, q_plain)


def test_frame_weighting_is_kept_while_the_segments_stay(human: HumanModel) -> None:
    """Frames with the same tracked segments share one weighting (row weights, posture
    weights, sensed joints: worked out once); a sensor that drops out or comes back gets what a
    fresh loader works out for that frame, and the chain tasks follow it."""
    from ikfusion.ik import Frame, Solver

    rng = np.random.default_rng(17)
    solver = Solver(human, contacts=False)
    every = ["Pelvis", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "T8", "Head"]
    dropped = [n for n in every if n != "LeftLowerLeg"]

    def frame(t: float, names: list[str]) -> Frame:
        return Frame(t, dict(zip(names, random_rotations(len(names), rng))))

    first = solver.targets.load(frame(0.0, every), None)
    second = solver.targets.load(frame(0.01, every), None)
    assert second.row_weights[0] is first.row_weights[0]  # not worked out again
    assert second.row_weights[1] is first.row_weights[1]
    assert second.sensed_joints is first.sensed_joints
    for t, names in ((0.02, dropped), (0.03, every), (0.04, dropped)):
        loaded = frame(t, names)
        got = solver.targets.load(loaded, None)
        fresh_solver = Solver(human, contacts=False)
        fresh = fresh_solver.targets.load(loaded, None)
        assert np.array_equal(got.tracked, fresh.tracked)
        assert np.array_equal(got.sensed_joints, fresh.sensed_joints)
        for mine, theirs in zip(got.row_weights, fresh.row_weights):
            assert np.array_equal(mine, theirs)
        assert np.array_equal(solver.tasks.posture.weights, fresh_solver.tasks.posture.weights)
        for task in ("even_chain", "chain_share"):
            assert np.array_equal(getattr(solver.tasks, task).active,
                                  getattr(fresh_solver.tasks, task).active)


def test_even_chain_objective_is_the_dense_sum_of_its_rows(human: HumanModel) -> None:
    """The even-chain task sums only its active pairs' rows, each joint rotation taken once:
    the numbers of the plain ``J^T W J`` and ``J^T W e`` of its error and Jacobian."""
    from ikfusion.ik.tasks import EvenChainTask

    settings = SolverSettings.load()
    task = EvenChainTask(human.ball_joints, settings.even_chains, 2.5, human.segment_names)
    rng = np.random.default_rng(17)
    nv = human.model.nv
    for active in ([True] * 4, [True, False, True, True], [False, False, False, True]):
        task.active = np.array(active)
        conf = Configuration(human.model, random_configuration(human, rng))
        H0, c0 = rng.normal(size=(nv, nv)), rng.normal(size=nv)
        H, c = H0.copy(), c0.copy()
        task.add_objective(conf, H, c)
        J, e, w = task.compute_jacobian(conf), task.compute_error(conf), task.row_weights()
        np.testing.assert_allclose(H, H0 + J.T @ (w[:, None] * J), rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(c, c0 + (w[:, None] * J).T @ e, rtol=1e-13, atol=1e-12)
    task.active[:] = False
    H, c = np.zeros((nv, nv)), np.zeros(nv)
    task.add_objective(Configuration(human.model, human.neutral()), H, c)
    assert not H.any() and not c.any()


def test_one_scalar_weighted_frame_is_summed_as_the_selected_rows(human: HumanModel) -> None:
    """The root (one frame, a scalar weight) skips the row selection: bit for bit the numbers
    of the same frame selected among others, and to rounding those of the plain formula."""
    rng = np.random.default_rng(13)
    nv = human.model.nv
    conf = Configuration(human.model, random_configuration(human, rng))
    sites = ["HeadTop", "LeftHeel"]
    ids = [human.site_frame_id(s) for s in sites]
    P, J = conf.positions(ids), conf.linear_jacobians(ids)
    target = rng.normal(size=(1, 3))
    H0, c0 = rng.normal(size=(nv, nv)), rng.normal(size=nv)
    one = PositionTask(ids[:1], sites[:1], weight=2.0)
    one.set_targets(target, [1.5])
    H1, c1 = H0.copy(), c0.copy()
    one.add_rows(P[:1], J[:1], H1, c1)
    among = PositionTask(ids, sites, weight=2.0)  # the same frame, the other one off
    among.set_targets(np.vstack([target, rng.normal(size=(1, 3))]), [1.5, 0.0])
    H2, c2 = H0.copy(), c0.copy()
    among.add_rows(P, J, H2, c2)
    assert np.array_equal(H1, H2) and np.array_equal(c1, c2)
    WJ = 3.0 * J[0]
    np.testing.assert_allclose(H1, H0 + J[0].T @ WJ, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(c1, c0 + WJ.T @ (P[0] - target[0]), rtol=1e-13, atol=1e-12)
    off = PositionTask(ids[:1], sites[:1])  # a lost target: nothing added
    off.set_targets(np.full((1, 3), np.nan), [1.5])
    H3, c3 = H0.copy(), c0.copy()
    off.add_rows(P[:1], J[:1], H3, c3)
    assert np.array_equal(H3, H0) and np.array_equal(c3, c0)


def test_a_step_copies_its_inputs_at_once_and_reads_only_its_outputs(
        human: HumanModel, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue #20: a Gauss-Newton step writes into the step function's slots only the inputs
    that changed (the geometry and the ranges once per step function, not at every step) and
    makes dense only the outputs its QP needs (H, c, the sites, the ranges), not the
    orientation errors, angles and angle rates; the walk is solved as with the NumPy tasks.
    Before, each input was copied by its own NumPy call and every output scattered."""
    from ikfusion.ik import Solver
    from ikfusion.ik.bound_function import BoundFunction
    from ikfusion.ik.compiled_inputs import SlotInputs
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=1.0, stand=0.3), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    plain = Solver(human, contacts=True, compiled=False).solve(frames)
    fast = Solver(human, contacts=True)
    assert fast.compiled is not None
    fast.compiled.rows = None  # the NumPy path (the native writer reads them in C)
    kinematics = fast.compiled.kinematics
    read: set[int] = set()
    written: list[int] = []
    output, output_into = BoundFunction.output, BoundFunction.output_into
    vectors, write = BoundFunction.vectors, SlotInputs._write

    def steps() -> list[BoundFunction]:
        return [inputs.call for inputs in kinematics._steps.values()]

    def counted_output(call: BoundFunction, i: int) -> np.ndarray:
        if call in steps():
            read.add(i)
        return output(call, i)

    def counted_output_into(call: BoundFunction, i: int, out: np.ndarray) -> None:
        if call in steps():
            read.add(i)
        output_into(call, i, out)

    def counted_vectors(call: BoundFunction, first: int, count: int) -> np.ndarray:
        if call in steps():
            read.update(range(first, first + count))
        return vectors(call, first, count)

    def counted_write(inputs: SlotInputs, i: int, value: np.ndarray) -> None:
        written.append(i)
        write(inputs, i, value)

    monkeypatch.setattr(BoundFunction, "output", counted_output)
    monkeypatch.setattr(BoundFunction, "output_into", counted_output_into)
    monkeypatch.setattr(BoundFunction, "vectors", counted_vectors)
    monkeypatch.setattr(SlotInputs, "_write", counted_write)
    motion = fast.solve(frames)
    names = kinematics.function.name_out()
    assert sorted(names[i] for i in read) == sorted(
        ["H", "c", "p_sites", "J_sites", "G_ranges", "room_up", "room_down"])
    # the geometry, the limits, the posture references and weights once per step function
    # (then left in their slots; the solver's first step came before the count)
    assert max(written.count(i) for i in (2, 4, 5, 6, 7)) <= len(kinematics._steps)
    np.testing.assert_allclose(motion.q, plain.q, atol=1e-6)


def test_add_to_diagonal_is_the_flat_sum() -> None:
    """Contiguous, transposed and strided matrices, vector and scalar values: the numbers of
    ``H.flat[::n + 1] += values``, in place (a view's base changes too)."""
    from ikfusion.ik.fast_math import add_to_diagonal

    rng = np.random.default_rng(14)
    base = rng.normal(size=(6, 12))
    for values in (rng.normal(size=6), 0.3):
        for make in (lambda: base[:, :6].copy(), lambda: base[:, :6].T.copy().T,
                     lambda: base.copy()[:, ::2]):
            H, expected = make(), make()
            add_to_diagonal(H, values)
            expected.flat[::7] += values
            assert np.array_equal(H, expected)
    big = base.copy()
    add_to_diagonal(big[:, ::2], 1.0)  # a strided view: its base is changed
    assert np.array_equal(np.diagonal(big[:, ::2]), np.diagonal(base[:, ::2]) + 1.0)


def test_an_orientation_only_solve_runs_no_pinocchio_pass(human: HumanModel,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue #20: without contact points nothing is held or planted, so the compiled solve of
    the orientations alone runs no Pinocchio kinematics pass (``Configuration._kinematics``)
    in any frame, and solves the walk as the NumPy tasks do. Before, every frame computed
    every joint Jacobian for the touch-down's empty list of points."""
    from ikfusion.ik import Solver
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=1.0, stand=0.3), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    plain = Solver(human, contacts=False, compiled=False).solve(frames)
    fast = Solver(human, contacts=False)
    assert fast.compiled is not None and fast.contact_names == []
    passes: list[float] = []
    kinematics = Configuration._kinematics

    def counted(conf: Configuration) -> None:
        if conf is fast._configuration and not conf._kinematics_done:
            passes.append(float(conf.q[2]))
        kinematics(conf)

    monkeypatch.setattr(Configuration, "_kinematics", counted)
    motion = fast.solve(frames)
    assert passes == []
    np.testing.assert_allclose(motion.q, plain.q, atol=1e-6)
