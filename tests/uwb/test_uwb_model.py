"""TOA model and simulator against the formula; batched linear algebra against LAPACK."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ikfusion.uwb import make_constellation, predict_toa, simulate_toa, toa_residuals
from ikfusion.uwb.linalg import inverse_batched, solve_batched


def test_predict_and_simulate_follow_the_formula(rng):
    c = make_constellation(
        [[0, 0, 2], [9, 0, 1], [9, 7, 2.5], [0, 7, 0.3]],
        clock_offsets=[0.0, 3.5, -1.25, 10.0],
        coverage=9.0,
        sigma=0.04,
    )
    p = rng.uniform([0, 0, 0.5], [9, 7, 2], (20000, 3))
    tau = rng.uniform(0, 100, 20000)
    expected = np.empty((20000, 4))
    for m, r in enumerate(c.readers):
        expected[:, m] = tau + np.linalg.norm(r.p_world_reader - p, axis=1) + r.clock_offset
    np.testing.assert_allclose(predict_toa(p, tau, c), expected, rtol=0, atol=1e-12)
    sim = simulate_toa(p, c, rng, tau=tau, nlos_fraction=0.2, nlos_delay=(0.5, 1.0))
    heard = np.isfinite(sim.toa)
    in_range = np.linalg.norm(c.positions[None] - p[:, None], axis=2) <= 9.0
    np.testing.assert_array_equal(heard, in_range)
    noise = (sim.toa - expected - sim.nlos_delay)[heard]
    assert abs(noise.std() - 0.04) < 0.002 and abs(noise.mean()) < 0.002
    delayed = sim.nlos_delay[heard] > 0
    assert abs(delayed.mean() - 0.2) < 0.01
    assert sim.nlos_delay[heard][delayed].min() >= 0.5
    assert sim.nlos_delay[heard][delayed].max() <= 1.0
    res = toa_residuals(sim.toa, p, tau, c)
    np.testing.assert_allclose(res[heard], (sim.toa - expected)[heard])


spd = arrays(np.float64, (5, 6, 4), elements=st.floats(-10, 10, allow_nan=False))


@settings(max_examples=60, deadline=None)
@given(spd, arrays(np.float64, (5, 4), elements=st.floats(-10, 10, allow_nan=False)))
def test_batched_solve_and_inverse_match_lapack(j, b):
    a = np.swapaxes(j, 1, 2) @ j + 1e-3 * np.eye(4)
    x, ok = solve_batched(a, b)
    cond = np.linalg.cond(a)
    good = cond < 1e8
    assert np.all(ok[good])
    np.testing.assert_allclose(
        x[good], np.linalg.solve(a[good], b[good][..., None])[..., 0], rtol=1e-6, atol=1e-8
    )
    inv, ok = inverse_batched(a)
    np.testing.assert_allclose(inv[good], np.linalg.inv(a[good]), rtol=1e-6, atol=1e-8)


def test_singular_systems_are_flagged_not_fatal():
    a = np.stack([np.eye(3), np.diag([1.0, 1.0, 0.0]), np.full((3, 3), np.nan)])
    x, ok = solve_batched(a, np.ones((3, 3)))
    assert ok.tolist() == [True, False, False]
    np.testing.assert_array_equal(x[0], 1.0)
    np.testing.assert_array_equal(x[1:], 0.0)
    inv, ok = inverse_batched(a)
    assert ok.tolist() == [True, False, False] and np.isnan(inv[1:]).all()
