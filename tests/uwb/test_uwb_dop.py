"""DOP against an independent closed form; coverage; reader-position uncertainty; maps."""

from __future__ import annotations

import numpy as np
import pytest
from uwb_sim import closed_form_dop

from ikfusion.paths import configs_dir
from ikfusion.uwb import (
    compute_dop,
    constellation_dop,
    dop_map,
    load_constellation,
    make_constellation,
)
from ikfusion.uwb.geometry import polygon_contains


@pytest.fixture(scope="module")
def stage():
    return load_constellation(configs_dir() / "constellations" / "stage_24x10.yaml")


POINTS = np.array([[12.0, 5.0, 1.5], [0.0, 0.0, 1.5], [3.3, 8.1, 0.2], [23.0, 1.0, 2.7]])


@pytest.mark.parametrize(("mode", "clock"), [("3d", True), ("2d", True), ("3d", False)])
def test_dop_matches_closed_form(stage, mode, clock):
    dims = 3 if mode == "3d" else 2
    dop = compute_dop(POINTS, stage.positions, mode=mode, clock=clock, sigma=0.03)
    for i, p in enumerate(POINTS):
        q = closed_form_dop(p, stage.positions, dims=dims, clock=clock, coverage=None)
        assert dop.position[i] == pytest.approx(np.sqrt(np.trace(q[:dims, :dims])), abs=1e-9)
        assert dop.hdop[i] == pytest.approx(np.sqrt(q[0, 0] + q[1, 1]), abs=1e-9)
        if dims == 3:
            assert dop.vdop[i] == pytest.approx(np.sqrt(q[2, 2]), abs=1e-9)
        if clock:
            assert dop.tdop[i] == pytest.approx(np.sqrt(q[dims, dims]), abs=1e-9)
        assert dop.expected_sigma[i] == pytest.approx(0.03 * dop.position[i], abs=1e-12)


def test_coverage_radius_removes_readers():
    readers = np.array(
        [[0, 0, 3], [10, 0, 0.5], [10, 10, 3], [0, 10, 0.5], [30, 30, 3], [31, 0, 1], [0, 31, 2]],
        dtype=float,
    )
    p = np.array([[5.0, 5.0, 1.5]])
    full = compute_dop(p, readers, coverage=None)
    near = compute_dop(p, readers, coverage=12.0)
    assert full.n_readers[0] == 7 and near.n_readers[0] == 4
    q = closed_form_dop(p[0], readers, dims=3, clock=True, coverage=12.0)
    assert near.position[0] == pytest.approx(np.sqrt(np.trace(q[:3, :3])), abs=1e-9)
    assert near.position[0] > full.position[0]
    # Outside the coverage of all but 3 readers: no 3-D value, but a 2-D one.
    far = np.array([[2.0, 2.0, 1.5]])  # within 11 m of readers 1, 2, 4 only (3 is 11.4 m)
    d3 = compute_dop(far, readers, coverage=11.0)
    d2 = compute_dop(far, readers, coverage=11.0, mode="2d")
    assert d3.n_readers[0] == 3 and np.isnan(d3.position[0]) and np.isnan(d3.expected_sigma[0])
    q2 = closed_form_dop(far[0], readers, dims=2, clock=True, coverage=11.0)
    assert d2.position[0] == pytest.approx(np.sqrt(q2[0, 0] + q2[1, 1]), abs=1e-9)


def test_reader_position_uncertainty_adds_line_of_sight_variance(stage):
    iso = np.broadcast_to(np.eye(3) * 0.02**2, (len(stage.readers), 3, 3))
    plain = compute_dop(POINTS, stage.positions, sigma=0.03)
    blurred = compute_dop(POINTS, stage.positions, sigma=0.03, reader_covariances=iso)
    # u^T (c^2 I) u = c^2 for every unit line of sight: the range sigma becomes sqrt(s^2 + c^2).
    np.testing.assert_allclose(blurred.expected_sigma, np.hypot(0.03, 0.02) * plain.position)
    # Uncertainty along one axis only matters for readers seen along that axis.
    cov = np.zeros((len(stage.readers), 3, 3))
    cov[:, 2, 2] = 0.05**2
    vertical = compute_dop(POINTS[:1], stage.positions, sigma=0.03, reader_covariances=cov)
    diff = POINTS[0] - stage.positions
    u = diff / np.linalg.norm(diff, axis=1, keepdims=True)
    w = 1.0 / (0.03**2 + 0.05**2 * u[:, 2] ** 2)
    h = np.column_stack([u, np.ones(len(u))])
    q = np.linalg.inv(h.T @ (w[:, None] * h))
    assert vertical.expected_sigma[0] == pytest.approx(np.sqrt(np.trace(q[:3, :3])), rel=1e-9)


def test_constellation_covariances_are_used(tmp_path):
    c = make_constellation([[0, 0, 3], [8, 0, 0.5], [8, 8, 3], [0, 8, 0.5], [4, 4, 5]])
    path = tmp_path / "c.yaml"
    text = "readers:\n"
    for r in c.readers:
        text += f"  - {{id: {r.id}, position: {r.p_world_reader.tolist()}, "
        text += "position_covariance: [[0.0004, 0, 0], [0, 0.0004, 0], [0, 0, 0.0004]]}\n"
    path.write_text(text)
    withcov = load_constellation(path)
    p = np.array([[3.0, 5.0, 1.2]])
    a = constellation_dop(withcov, p).expected_sigma[0]
    b = constellation_dop(withcov, p, use_reader_covariance=False).expected_sigma[0]
    assert a == pytest.approx(b * np.hypot(0.03, 0.02) / 0.03, rel=1e-9)


def test_map_grid_area_and_summary(stage):
    m = dop_map(stage, height=1.5, step=0.5)
    assert m.expected_sigma.shape == (m.y.size, m.x.size)
    # Corners of the area are grid points and inside.
    for corner in stage.area:
        i = np.argmin(np.abs(m.y - corner[1]))
        j = np.argmin(np.abs(m.x - corner[0]))
        assert m.x[j] == pytest.approx(corner[0]) and m.y[i] == pytest.approx(corner[1])
        assert m.inside[i, j]
    gx, gy = np.meshgrid(m.x, m.y)
    inside = polygon_contains(stage.area, np.column_stack([gx.ravel(), gy.ravel()]))
    np.testing.assert_array_equal(m.inside.ravel(), inside)
    vals = m.expected_sigma[m.inside]
    s = m.summary()
    assert s.points == vals.size
    assert s.max == pytest.approx(vals.max())
    assert s.median == pytest.approx(np.percentile(vals, 50, method="higher"))
    assert s.fraction_under_5cm == pytest.approx(np.mean(vals < 0.05))
    assert s.covered_fraction == 1.0
    # A reader farther than the coverage radius leaves part of the map without a fix.
    short = make_constellation(stage.positions, coverage=9.0, area=stage.area)
    s_short = dop_map(short, height=1.5, step=0.5).summary()
    assert s_short.covered_fraction < 1.0 and np.isinf(s_short.max)
    assert s_short.as_dict()["max_cm"] is None


def test_polygon_contains_concave_shape():
    ell = np.array([[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]], dtype=float)
    pts = np.array([[0.5, 3.0], [3.0, 3.0], [3.0, 0.5], [4.0, 0.5], [2.0, 1.0], [5, 5]])
    assert polygon_contains(ell, pts).tolist() == [True, False, True, True, True, False]
