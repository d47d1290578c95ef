"""The slide a solve adds beyond the truth's, and the same where the truth lies on the floor
(issue #19: dm-getup-faceup's ``beyond mm`` 5.8 mm, of which 1.1 mm was the solved body falling
behind a truth whose shoulder blade slid 5 cm while 5-7 cm under the floor)."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.app.slide_excess import SUNK_DEPTH, excess_slides, sunk_steps

N = 31
NAMES = ["LeftShoulderBlade", "LeftHeel"]
STEP = 0.001  # [m] the true back point's slide per frame, along x


def _scene(depth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A body lying on its back point (column 0, ``depth`` (N,) [m] under the floor in the
    truth, sliding ``STEP`` per frame there) with a heel on the floor (column 1, still in the
    truth). The solve holds the back point still on the floor, so its heel falls behind by the
    back point's slide. Returns P_est, P_true (N, 2, 3), the truth's contacts (N, 2) and the
    solver's holds (N, 2)."""
    slide = STEP * np.arange(N)
    P_true = np.zeros((N, 2, 3))
    P_true[:, 0, 0] = slide
    P_true[:, 0, 2] = -depth
    P_true[:, 1, :2] = [0.9, 0.1]
    P_est = P_true.copy()
    P_est[:, :, 0] -= slide[:, None]  # the whole solved body, held on the back point
    P_est[:, 0, 2] = 0.0
    contacts = np.ones((N, 2), dtype=bool)
    held = np.zeros((N, 2), dtype=bool)
    held[:, 0] = True
    return P_est, P_true, contacts, held


def test_a_back_sunk_under_the_floor_adds_no_slide_on_the_floor() -> None:
    P_est, P_true, contacts, held = _scene(np.full(N, 0.05))
    sunk = sunk_steps(held, P_true[:, :, 2], NAMES)
    assert sunk.all()
    # back point: held still while the truth's slides (0); heel: 30 mm behind the still truth
    np.testing.assert_allclose(excess_slides(P_est, P_true, contacts), [0.0, 0.030], atol=1e-12)
    np.testing.assert_allclose(excess_slides(P_est, P_true, contacts, sunk), [0.0, 0.0],
                               atol=1e-12)


def test_only_the_sunk_steps_are_left_out() -> None:
    """Strict: a point within the truth's floor scatter (1 cm deep) is on the floor, every step
    counts; a back that comes up out of the floor halfway counts from then on."""
    P_est, P_true, contacts, held = _scene(np.full(N, 0.01))
    sunk = sunk_steps(held, P_true[:, :, 2], NAMES)
    assert not sunk.any()
    np.testing.assert_allclose(excess_slides(P_est, P_true, contacts, sunk), [0.0, 0.030],
                               atol=1e-12)
    depth = np.where(np.arange(N) <= 10, 0.05, 0.0)
    P_est, P_true, contacts, held = _scene(depth)
    sunk = sunk_steps(held, P_true[:, :, 2], NAMES)
    assert sunk.tolist() == [True] * 10 + [False] * 20
    np.testing.assert_allclose(excess_slides(P_est, P_true, contacts, sunk), [0.0, 0.020],
                               atol=1e-12)
    # a sunk point the solver does not hold moves nothing
    held[:] = False
    assert not sunk_steps(held, P_true[:, :, 2], NAMES).any()


def test_limb_points_are_on_the_floor_however_deep() -> None:
    """The truth lifts its limb points onto the floor within its fit's scatter (a toe of
    amp-walk 2.5 cm deep): a held toe under the floor is the truth's floor, every step counts."""
    P_est, P_true, contacts, held = _scene(np.full(N, 0.05))
    sunk = sunk_steps(held, P_true[:, :, 2], ["LeftToe", "LeftHeel"])
    assert not sunk.any()
    np.testing.assert_allclose(excess_slides(P_est, P_true, contacts, sunk), [0.0, 0.030],
                               atol=1e-12)


def test_excess_per_phase_is_the_solved_slide_beyond_the_true_one() -> None:
    """Two phases of one point: the solve slides 5 mm more than the truth in the first, less in
    the second (0, not negative)."""
    P_true = np.zeros((10, 1, 3))
    P_est = np.zeros((10, 1, 3))
    P_true[:5, 0, 0] = np.linspace(0.0, 0.002, 5)
    P_est[:5, 0, 0] = np.linspace(0.0, 0.007, 5)
    P_true[5:, 0, 1] = np.linspace(0.0, 0.004, 5)
    contacts = np.ones((10, 1), dtype=bool)
    contacts[5] = False
    np.testing.assert_allclose(excess_slides(P_est, P_true, contacts), [0.005, 0.0],
                               atol=1e-12)


def test_the_sunk_depth_is_the_truths_floor_scatter() -> None:
    from ikfusion.mocap.from_bvh import FLOOR_OUTLIER

    assert pytest.approx(FLOOR_OUTLIER) == SUNK_DEPTH
