"""Parts of the calibration: the CasADi problem's derivatives, frames, the first estimate."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.uwb.calibration_frame import (
    Rigid2D,
    alignment_projector,
    fit_rigid_2d,
    gauge_transform,
    rigid_motions,
)
from ikfusion.uwb.calibration_init import distance_start, fit_reader_geometry, reader_table
from ikfusion.uwb.calibration_nlp import CalibrationNlp, Layout, Receptions


def small_problem(rng):
    """5 readers, 4 wand transmissions, 3 reader-tag transmissions, random values."""
    layout = Layout(readers=5, wand=4, tags=3)
    k_wand, r_wand = np.meshgrid(np.arange(4), np.arange(5), indexing="ij")
    tags = np.array([0, 2, 4])
    k_tag, r_tag = [], []
    for i, j in enumerate(tags):
        for m in range(5):
            if m != j:
                k_tag.append(4 + i)
                r_tag.append(m)
    k = np.concatenate([k_wand.ravel(), k_tag])
    r = np.concatenate([r_wand.ravel(), r_tag])
    emitter = np.where(k < 4, -1, tags[np.maximum(k - 4, 0)])
    receptions = Receptions(k, r, emitter, rng.uniform(5.0, 15.0, k.size))
    nlp = CalibrationNlp(layout, receptions, rng.uniform(1.0, 3.0, 5))
    x = rng.uniform(-8.0, 8.0, layout.size)
    return nlp, x


def test_jacobian_matches_finite_differences(rng):
    nlp, x = small_problem(rng)
    jac = nlp.jacobian(x).toarray()
    step = 1e-6
    numeric = np.column_stack([
        (nlp.residuals(x + step * e) - nlp.residuals(x - step * e)) / (2 * step)
        for e in np.eye(x.size)
    ])  # fmt: skip
    np.testing.assert_allclose(jac, numeric, atol=1e-7)


def test_ipopt_gets_the_exact_gradient_and_hessian(rng):
    nlp, x = small_problem(rng)
    w = rng.uniform(0.5, 2.0, nlp.receptions.size)
    grad_fn, _ = nlp.derivatives
    f, grad = (np.array(v).ravel() for v in grad_fn(x, w))
    r = nlp.residuals(x)
    jac = nlp.jacobian(x).toarray()
    np.testing.assert_allclose(f, 0.5 * np.sum(w * r**2), rtol=1e-12)
    np.testing.assert_allclose(grad, jac.T @ (w * r), atol=1e-9)
    hess = nlp.hessian(x, w).toarray()
    step = 1e-6
    numeric = np.column_stack([
        (np.array(grad_fn(x + step * e, w)[1]).ravel()
         - np.array(grad_fn(x - step * e, w)[1]).ravel()) / (2 * step)
        for e in np.eye(x.size)
    ])  # fmt: skip
    np.testing.assert_allclose(hess, numeric, atol=1e-5)


def test_solve_recovers_a_noise_free_layout(rng):
    """Exact times of arrival: IPOPT returns the truth in the gauge frame from a nearby start."""
    readers = np.array([[0, 0, 2.5], [9, 0, 1.0], [10, 7, 2.0], [1, 8, 1.5], [5, -1, 3.0],
                        [-1, 4, 1.2]], float)  # fmt: skip
    clocks = np.array([0.0, 3.0, -2.0, 5.0, 1.0, -4.0])
    wand = np.column_stack([rng.uniform(1, 8, 40), rng.uniform(1, 6, 40), rng.uniform(0.5, 2, 40)])
    k, r = (a.ravel() for a in np.meshgrid(np.arange(40), np.arange(6), indexing="ij"))
    tau = rng.uniform(0, 5, 40)
    toa = tau[k] + np.linalg.norm(wand[k] - readers[r], axis=1) + clocks[r]
    layout = Layout(readers=6, wand=40, tags=0)
    nlp = CalibrationNlp(layout, Receptions(k, r, np.full(k.size, -1), toa), readers[:, 2])
    truth = layout.pack(readers[:, :2], clocks, wand, tau)
    x0 = truth + rng.normal(0, 0.05, truth.size)
    fixed = np.zeros(truth.size, dtype=bool)
    fixed[[0, 1, 3, layout.clock]] = True
    x0[fixed] = truth[fixed]
    result = nlp.solve(x0, np.ones(k.size), np.where(fixed, x0, -np.inf),
                       np.where(fixed, x0, np.inf))  # fmt: skip
    assert result.success
    np.testing.assert_allclose(result.x[: 2 * 6], truth[: 2 * 6], atol=1e-6)


def test_rigid_fit_recovers_a_transform_and_a_mirror(rng):
    a = rng.uniform(-5, 5, (6, 3))
    angle = 0.7
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moved = Rigid2D(rot, np.array([2.0, -1.0])).apply(a)
    fit = fit_rigid_2d(a, moved)
    np.testing.assert_allclose(fit.apply(a), moved, atol=1e-12)
    mirrored = Rigid2D(rot @ np.diag([1.0, -1.0]), np.zeros(2)).apply(a)
    fit = fit_rigid_2d(a, mirrored, allow_mirror=True)
    assert fit.mirrored
    np.testing.assert_allclose(fit.apply(a), mirrored, atol=1e-12)


def test_gauge_transform_puts_origin_and_axis(rng):
    p = rng.uniform(-5, 5, (5, 2))
    moved = gauge_transform(p, 2, 4).apply(p)
    np.testing.assert_allclose(moved[2], 0.0, atol=1e-12)
    assert abs(moved[4, 1]) < 1e-12 and moved[4, 0] > 0
    assert moved[np.argmax(np.abs(moved[:, 1])), 1] > 0


def test_alignment_projector_removes_rigid_motions(rng):
    p = rng.uniform(-5, 5, (6, 2))
    s = alignment_projector(p)
    np.testing.assert_allclose(s @ rigid_motions(p), 0.0, atol=1e-12)
    np.testing.assert_allclose(s @ s, s, atol=1e-12)


def reader_log(readers, clocks, rng, *, own: bool, per_tag: int = 20, sigma: float = 0.0):
    """Reader-tag times of arrival (T, M) and emitters, optionally with own receptions."""
    m = readers.shape[0]
    emitter = np.repeat(np.arange(m), per_tag)
    tau = rng.uniform(0, 100, emitter.size)
    dist = np.linalg.norm(readers[emitter][:, None, :] - readers[None, :, :], axis=2)
    toa = tau[:, None] + dist + clocks[None, :] + rng.normal(0, sigma, dist.shape)
    if not own:
        toa[np.arange(emitter.size), emitter] = np.nan
    return toa, emitter


@pytest.mark.parametrize("own", [True, False])
def test_first_estimate_recovers_the_layout(rng, own):
    readers = np.column_stack([rng.uniform(0, 20, 8), rng.uniform(0, 15, 8), rng.uniform(1, 3, 8)])
    clocks = rng.uniform(-10, 10, 8)
    toa, emitter = reader_log(readers, clocks, rng, own=own, sigma=0.01)
    table = reader_table(toa, emitter)
    geometry = fit_reader_geometry(table, readers[:, 2], np.random.default_rng(0))
    assert geometry.placed.all()
    fit = fit_rigid_2d(geometry.p_xy, readers, allow_mirror=True)
    err = fit.apply(geometry.p_xy) - readers[:, :2]
    # Without own receptions distances and clock terms separate through geometry only.
    tolerance = 0.02 if own else 0.05
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < tolerance
    db = geometry.clock_offsets - (clocks - clocks[0])
    assert np.sqrt(np.mean(db**2)) < 1.5 * tolerance
    start = distance_start(table, readers[:, 2], geometry.placed)
    assert (start is not None) == own
