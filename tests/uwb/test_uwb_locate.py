"""Positioning solver: exactness, statistics against sigma x DOP, NLOS rejection, statuses."""

from __future__ import annotations

import numpy as np
import pytest
from uwb_sim import closed_form_dop, toa_matrix

from ikfusion.errors import InputError
from ikfusion.paths import shipped_config
from ikfusion.uwb import (
    FixStatus,
    estimate_range_sigma,
    load_constellation,
    locate,
    make_constellation,
)
from ikfusion.uwb.initial_guess import bancroft


@pytest.fixture(scope="module")
def highend():
    """The shipped 12-reader constellation with non-zero clock offsets (as after calibration)."""
    c = load_constellation(shipped_config("constellations", "highend_12.yaml"))
    offsets = np.linspace(-7.5, 12.0, len(c.readers))
    return make_constellation(c.positions, clock_offsets=offsets, sigma=0.03, area=c.area)


def _pdop(c, p, dims=3):
    q = closed_form_dop(p, c.positions, dims=dims, clock=True, coverage=None)
    return float(np.sqrt(np.trace(q[:dims, :dims])))


@pytest.mark.parametrize("height", [None, 1.3])
@pytest.mark.parametrize("clock", ["free", "zero"])
def test_noise_free_fixes_are_exact(highend, rng, height, clock):
    p = np.column_stack([rng.uniform(-2, 22, 200), rng.uniform(-2, 22, 200), np.full(200, 1.3)])
    if height is None:
        p[:, 2] = rng.uniform(0.1, 2.2, 200)
    tau = np.zeros(200) if clock == "zero" else None
    toa, _, tau_true = toa_matrix(
        highend.positions, highend.clock_offsets, p, rng, sigma=0.0, tau=tau
    )
    fixes = locate(toa, highend, height=height, clock=clock)
    assert np.all(fixes.status == FixStatus.OK)
    np.testing.assert_allclose(fixes.p_world_tag, p, atol=1e-6)
    np.testing.assert_allclose(fixes.clock, tau_true, atol=1e-6)
    assert fixes.used.all() and not fixes.rejected.any()


@pytest.mark.parametrize(("dims", "clock"), [(3, True), (2, True), (3, False), (2, False)])
def test_bancroft_closed_form_recovers_the_truth(rng, dims, clock):
    readers = rng.uniform([-5, -5, 0], [5, 5, 3], (6, 3))
    p = rng.uniform([-4, -4, 0.5], [4, 4, 2], (50, 3))
    tau = rng.uniform(-3, 3, 50) if clock else np.zeros(50)
    y = tau[:, None] + np.linalg.norm(readers[None] - p[:, None], axis=2)
    w = np.full_like(y, 1 / 0.03**2)  # inverse variances, as the solver passes them
    x, ok = bancroft(readers, y, w, dims=dims, clock=clock, height=p[:, 2])
    assert ok.all()
    # Exact up to rounding, except near a double root of the quadratic (tag close to where
    # the two intersections merge), where the start is only good to sqrt(eps): GN polishes it.
    err = np.abs(x[:, :dims] - p[:, :dims]).max(axis=1)
    assert np.median(err) < 1e-9 and err.max() < 1e-3
    if clock:
        np.testing.assert_allclose(x[:, dims], tau, atol=1e-3)


def test_minimum_readers_and_status_words(highend, rng):
    p = np.array([[10.0, 10.0, 1.5]] * 4)
    toa, _, _ = toa_matrix(highend.positions, highend.clock_offsets, p, rng, sigma=0.0)
    toa[0, 3:] = np.nan  # 3 readers: too few in 3-D with clock ...
    toa[1, 4:] = np.nan  # 4 readers: exactly determined
    toa[2, :] = np.nan
    fixes = locate(toa, highend)
    assert fixes.status_labels() == ["too_few_readers", "ok", "too_few_readers", "ok"]
    assert np.isnan(fixes.p_world_tag[0]).all() and not fixes.used[0].any()
    np.testing.assert_allclose(fixes.p_world_tag[1], p[1], atol=1e-6)
    # ... but enough in 2-D with the height known.
    two_d = locate(toa[:1], highend, height=1.5)
    assert two_d.status_labels() == ["ok"]
    np.testing.assert_allclose(two_d.p_world_tag[0], p[0], atol=1e-6)


def test_coplanar_readers_give_bad_geometry_in_3d_not_in_2d(rng):
    flat = make_constellation([[0, 0, 1], [8, 0, 1], [8, 8, 1], [0, 8, 1], [4, -2, 1]])
    p = np.array([[3.0, 4.0, 1.0]])  # in the readers' plane: height unobservable
    toa, _, _ = toa_matrix(flat.positions, flat.clock_offsets, p, rng, sigma=0.0)
    assert locate(toa, flat).status_labels() == ["bad_geometry"]
    assert locate(toa, flat, height=1.0).status_labels() == ["ok"]


@pytest.mark.parametrize("where", ["centre", "corner"])
def test_monte_carlo_rms_matches_sigma_times_dop(highend, rng, where):
    """Acceptance: LOS, sigma 3 cm, 12 readers, 1000 fixes: RMS within 10 % of sigma x PDOP."""
    p = np.array([10.0, 10.0, 1.5]) if where == "centre" else np.array([0.0, 0.0, 1.5])
    toa, _, _ = toa_matrix(
        highend.positions, highend.clock_offsets, np.tile(p, (1000, 1)), rng, sigma=0.03
    )
    fixes = locate(toa, highend)
    assert fixes.ok.mean() >= 0.995  # the chi-square test at 1e-3 may flag a few
    err = fixes.p_world_tag[fixes.ok] - p
    rms = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    expected = 0.03 * _pdop(highend, p)
    print(
        f"\n{where}: RMS {100 * rms:.2f} cm, sigma x PDOP {100 * expected:.2f} cm, "
        f"ratio {rms / expected:.3f}"
    )
    assert abs(rms / expected - 1.0) < 0.10
    # The reported covariance is the same closed form (evaluated at the estimate, hence the
    # spread; a false NLOS rejection also makes a fix a little less precise).
    reported = np.sqrt(np.trace(fixes.cov[fixes.ok][:, :3, :3], axis1=1, axis2=2))
    assert np.median(reported) == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("where", ["centre", "corner"])
def test_nlos_rejection_keeps_rms_and_finds_the_delayed(highend, rng, where):
    """Acceptance: 10 % of receptions delayed 0.2-2 m: RMS within 1.3 sigma x PDOP."""
    p = np.array([10.0, 10.0, 1.5]) if where == "centre" else np.array([0.0, 0.0, 1.5])
    toa, delay, _ = toa_matrix(
        highend.positions,
        highend.clock_offsets,
        np.tile(p, (1000, 1)),
        rng,
        sigma=0.03,
        nlos_fraction=0.10,
    )
    fixes = locate(toa, highend)
    delayed = delay > 0
    tp = np.count_nonzero(fixes.rejected & delayed)
    precision = tp / max(np.count_nonzero(fixes.rejected), 1)
    recall = tp / np.count_nonzero(delayed)
    err = fixes.p_world_tag[fixes.ok] - p
    rms = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    expected = 0.03 * _pdop(highend, p)
    naive = locate(toa, highend, reject_nlos=False)
    naive_err = naive.p_world_tag[naive.ok] - p
    naive_rms = float(np.sqrt(np.mean(np.sum(naive_err**2, axis=1))))
    print(
        f"\n{where}: {delayed.mean():.3f} delayed; RMS {100 * rms:.2f} cm = "
        f"{rms / expected:.3f} sigma x PDOP (without rejection {100 * naive_rms:.1f} cm); "
        f"precision {precision:.3f} recall {recall:.3f}; fixes {fixes.ok.mean():.3f}"
    )
    assert rms < 1.3 * expected
    assert naive_rms > 2 * rms  # the rejection is what keeps the error down
    assert precision > 0.95 and recall > 0.95
    assert fixes.ok.mean() >= 0.99


def test_rejection_is_one_sided(highend, rng):
    """A late reception is rejected; an early one (impossible for NLOS) never is."""
    p = np.tile([8.0, 11.0, 1.2], (2, 1))
    toa, _, _ = toa_matrix(highend.positions, highend.clock_offsets, p, rng, sigma=0.0)
    toa[0, 5] += 0.5
    toa[1, 5] -= 0.5
    fixes = locate(toa, highend)
    assert fixes.rejected[0].tolist() == [j == 5 for j in range(12)]
    np.testing.assert_allclose(fixes.p_world_tag[0], p[0], atol=1e-6)
    # The early reception stays in: the model can only explain it by calling others late
    # (or not at all), never by rejecting it.
    assert not fixes.rejected[1, 5]
    assert fixes.used[1, 5] or fixes.status_labels()[1] == "rejected"


def test_many_simultaneous_nlos_do_not_lure_the_fix(highend, rng):
    """Four of twelve receptions late by 0.5-1 m at once: all four found, fix exact."""
    p = rng.uniform([2, 2, 0.5], [18, 18, 2], (300, 3))
    toa, _, _ = toa_matrix(highend.positions, highend.clock_offsets, p, rng, sigma=0.0)
    late = np.argsort(rng.random((300, 12)), axis=1)[:, :4]
    rows = np.arange(300)[:, None]
    toa[rows, late] += rng.uniform(0.5, 1.0, (300, 4))
    fixes = locate(toa, highend)
    truth = np.zeros((300, 12), dtype=bool)
    truth[rows, late] = True
    assert fixes.ok.mean() > 0.98
    assert np.mean(np.all(fixes.rejected == truth, axis=1)) > 0.97
    err = np.linalg.norm(fixes.p_world_tag[fixes.ok] - p[fixes.ok], axis=1)
    assert np.percentile(err, 98) < 1e-4


def test_covariance_matches_the_empirical_scatter_in_2d(highend, rng):
    p = np.array([3.0, 16.0, 1.1])
    toa, _, _ = toa_matrix(
        highend.positions, highend.clock_offsets, np.tile(p, (3000, 1)), rng, sigma=0.03
    )
    fixes = locate(toa, highend, height=1.1, reject_nlos=False)
    err = fixes.p_world_tag[:, :2] - p[:2]
    empirical = np.cov(err.T)
    predicted = fixes.cov[0, :2, :2]
    np.testing.assert_allclose(empirical, predicted, rtol=0.12, atol=2e-6)
    assert np.all(fixes.cov[:, 2, :] == 0)  # z known: no variance
    np.testing.assert_allclose(fixes.p_world_tag[:, 2], 1.1)


def test_sigma_auto_estimates_the_noise(highend, rng):
    p = rng.uniform([1, 1, 0.5], [19, 19, 2], (2000, 3))
    toa, _, _ = toa_matrix(highend.positions, highend.clock_offsets, p, rng, sigma=0.05)
    assert estimate_range_sigma(toa, highend) == pytest.approx(0.05, rel=0.08)
    fixes = locate(toa, highend, sigma="auto")
    assert fixes.ok.mean() > 0.99


def test_bad_arguments_raise_input_errors(highend):
    with pytest.raises(InputError, match="shape"):
        locate(np.zeros((3, 5)), highend)
    with pytest.raises(InputError, match="clock"):
        locate(np.zeros((3, 12)), highend, clock="sometimes")
    with pytest.raises(InputError, match="height"):
        locate(np.zeros((3, 12)), highend, height=[1.0, 2.0])
    empty = locate(np.zeros((0, 12)), highend)
    assert len(empty) == 0


@pytest.mark.parametrize(("height", "clock"), [(None, "free"), (1.2, "free"), (None, "zero")])
def test_model_jacobian_matches_finite_differences(highend, rng, height, clock):
    from ikfusion.uwb.locate import LocateOptions, _predict, _prepare

    toa = rng.uniform(0, 30, (5, 12))
    b, _, _ = _prepare(toa, highend, LocateOptions(height=height, clock=clock), 0.03)
    x = rng.uniform(-8, 8, (5, b.k))
    _, jac = _predict(x, b)
    for i in range(b.k):
        step = np.zeros(b.k)
        step[i] = 1e-6
        plus, _ = _predict(x + step, b)
        minus, _ = _predict(x - step, b)
        np.testing.assert_allclose(jac[i], (plus - minus) / 2e-6, atol=1e-8)


def test_unconverged_fixes_report_diverged(highend, rng):
    p = rng.uniform([1, 1, 0.5], [19, 19, 2], (50, 3))
    toa, _, _ = toa_matrix(highend.positions, highend.clock_offsets, p, rng, sigma=0.03)
    fixes = locate(toa, highend, max_iterations=1, tolerance=1e-12, reject_nlos=False)
    assert set(fixes.status_labels()) == {"diverged"}
    assert np.isnan(fixes.p_world_tag).all() and np.isnan(fixes.cov).all()
