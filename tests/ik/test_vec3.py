"""The support's float 3-vectors compute NumPy's numbers bit for bit (:mod:`ikfusion.ik.vec3`)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from ikfusion.ik import fast_math, support_motion, vec3
from ikfusion.ik.support import SupportFollower
from ikfusion.ik.tasks.position import PositionTask
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

RNG = np.random.default_rng(7)
# vectors of every scale the support meets, zero ones and ones with negative zeros among them
VECTORS = [RNG.standard_normal(3) * s for s in (1e-4, 1e-2, 0.3, 1.0, 7.0) for _ in range(200)]
VECTORS += [np.zeros(3), np.array([-0.0, 0.0, -0.0]), np.array([0.0, 1e-300, 0.0])]


def _bits(v: np.ndarray | tuple[float, ...]) -> bytes:
    return np.asarray(v, dtype=float).tobytes()


def test_norms_clips_and_shrinks_are_numpys_numbers() -> None:
    buffer = np.zeros(3)
    for v in VECTORS:
        t = tuple(v.tolist())
        assert vec3.norm(t, buffer) == float(np.linalg.norm(v))
        for limit in (0.0, 1e-3, 0.05, 1.0, math.inf):
            assert _bits(vec3.clip_norm(t, limit, buffer)) == _bits(fast_math.clip_norm(v, limit))
            assert _bits(vec3.shrink(t, limit, buffer)) == _bits(fast_math.shrink(v, limit))


def test_sums_and_means_are_numpys_numbers() -> None:
    a, b = RNG.standard_normal((14, 3)), RNG.standard_normal((14, 3))
    a[3] = -0.0  # a sum of negative zeros is +0 in NumPy's reduction (it starts from 0.0)
    for rows in [(3,), (0, 1), (2, 3, 5), (0, 1, 2, 3), tuple(range(14)), (1, 3, 4, 8, 9, 13)]:
        mask = np.zeros(14, dtype=bool)
        mask[list(rows)] = True
        assert _bits(vec3.mean_rows(a, rows)) == _bits(np.mean(a[mask], axis=0))
        assert _bits(vec3.mean_rows(a, rows, b)) == _bits(np.mean((a - b)[mask], axis=0))
    u, w = tuple(a[0].tolist()), tuple(b[0].tolist())
    assert _bits(vec3.add(u, w)) == _bits(a[0] + b[0])
    assert _bits(vec3.sub(u, w)) == _bits(a[0] - b[0])


def test_floats_are_an_arrays_floats() -> None:
    v = vec3.floats(np.array([0.1, -0.2, -0.0]))
    assert v == (0.1, -0.2, -0.0) and all(type(x) is float for x in v)
    assert math.copysign(1.0, v[2]) == -1.0  # the sign of a zero kept


def test_a_support_lag_is_read_as_a_new_array() -> None:
    follower = SupportFollower(BodyTopology.of(HumanModel.default()).foot_layout(
        HumanModel.default().sites_of_kind("contact")), 0.2, 0.1, 0.4, 0.05, 0.1, 0.1)
    follower.lag = np.array([0.1, -0.2, 0.3])
    view = follower.lag
    view[0] = 5.0  # a new array: the follower's floats stay
    assert follower.lag.tolist() == [0.1, -0.2, 0.3]


@pytest.mark.parametrize("weight", [0.0, 2.5])
@pytest.mark.parametrize("target", [(0.1, -0.2, 0.9), (math.nan, 0.0, 1.0)])
def test_one_target_is_set_as_set_targets_sets_it(weight: float,
                                                  target: tuple[float, float, float]) -> None:
    one, many = PositionTask([3], ["root"]), PositionTask([3], ["root"])
    one.set_target(target, weight)
    many.set_targets(np.array(target)[None], [weight])
    assert _bits(one.targets) == _bits(many.targets)
    assert _bits(one.information) == _bits(many.information)
    assert np.array_equal(one._active, many._active)
    assert (one._scalar is None) == (many._scalar is None)
    if one._scalar is not None:
        assert _bits(one._scalar) == _bits(many._scalar)


def test_clips_and_shrinks_at_their_limits_are_numpys_numbers() -> None:
    """Limits at a vector's norm and at |x| + |y| + |z|, a few ulps either side (the shortcut's
    bound), and zeros of either sign: the numbers of NumPy's formulas."""
    buffer = np.zeros(3)
    for v in VECTORS[::7]:
        t = tuple(v.tolist())
        n, a = float(np.linalg.norm(v)), float(np.abs(v).sum())
        for base in (n, a, a * (1 + 1e-12)):
            for ulps in (-3, -1, 0, 1, 3):
                limit = base + ulps * math.ulp(base) if base else 0.0
                assert _bits(vec3.clip_norm(t, limit, buffer)) == _bits(
                    fast_math.clip_norm(v, limit))
                assert _bits(vec3.shrink(t, limit, buffer)) == _bits(fast_math.shrink(v, limit))


def test_the_supports_motions_are_numpys_numbers() -> None:
    """:mod:`.support_motion`'s shortcuts (zeros, a kept clip) give the full formulas' numbers."""
    buffer = np.zeros(3)
    zeros = [np.zeros(3), np.array([-0.0, 0.0, -0.0])]
    vectors = VECTORS[::11] + zeros
    clip = support_motion.KeptClip()
    for i, v in enumerate(vectors):
        g, m = vectors[(3 * i + 1) % len(vectors)], vectors[(5 * i + 2) % len(vectors)]
        t, tg, tm = (tuple(x.tolist()) for x in (v, g, m))
        for by in (0.0, 1e-3, 0.05):
            full = v + fast_math.clip_norm(g - v, by)
            assert _bits(support_motion.moved_toward(t, tg, by, buffer)) == _bits(full)
            assert _bits(support_motion.swing_toward(t, tg, by, tm, buffer)) == _bits(full - m)
            lag = fast_math.clip_norm(fast_math.shrink(v, by), 0.04)
            assert _bits(support_motion.shrunk_lag(t, by, 0.04, buffer)) == _bits(lag)
            for again in (t, tuple((v * -1.0 * -1.0).tolist())):  # kept, then the same floats
                assert _bits(clip(again, by, buffer)) == _bits(fast_math.clip_norm(v, by))
    for z, w in [(a, b) for a in zeros for b in zeros]:  # a kept clip of a zero of either sign
        clip(tuple(z.tolist()), 0.01, buffer)
        assert _bits(clip(tuple(w.tolist()), 0.01, buffer)) == _bits(fast_math.clip_norm(w, 0.01))


@pytest.mark.parametrize("lean_max", [0.03, 0.0, -1.0, math.inf, math.nan])
def test_the_lean_moves_as_the_full_formula_moves_it(lean_max: float) -> None:
    """:func:`.support_motion.leaned` (zeros: no lean at once) is the full formula bit for bit."""
    buffer = np.zeros(3)
    zeros = [np.zeros(3), np.array([-0.0, 0.0, -0.0]), np.array([0.0, -0.0, 0.0])]
    vectors = VECTORS[::23] + zeros
    for i, lean in enumerate(vectors):
        for step in (vectors[(3 * i + 1) % len(vectors)], *zeros):
            for lag in (vectors[(5 * i + 2) % len(vectors)], *zeros):
                pending = np.array([-lag[0], -lag[1], 0.0])
                for by in (0.0, 1e-3):
                    full = lean + fast_math.clip_norm(
                        fast_math.clip_norm(lean + step - pending, lean_max) - lean, by)
                    got = support_motion.leaned(*(tuple(x.tolist()) for x in (lean, step, lag)),
                                                support_motion.KeptClip(), lean_max, by, buffer)
                    assert _bits(got) == _bits(full)


@pytest.mark.parametrize("lean_max", [0.03, 0.0, math.inf, math.nan])
def test_a_lean_that_reached_its_goal_stays_as_the_general_path_keeps_it(lean_max: float) -> None:
    """:func:`.support_motion.leaned`'s kept lean (no step, no lag) is its general path's.

    The general path: the goal clipped (by a copy of the kept clip), the lean moved toward it.
    """
    buffer = np.zeros(3)
    zeros = [(0.0, 0.0, 0.0), (-0.0, 0.0, -0.0)]
    odd = [(math.inf, 0.0, 0.0), (1e308, 1e308, 0.0), (0.0, math.nan, 0.0), (-0.0, 1e-3, -0.0)]
    for start in [tuple(v.tolist()) for v in VECTORS[::7]] + zeros + odd:
        clip, lean = support_motion.KeptClip(), start
        for step in (start, *zeros):  # led toward ``2 start``, then standing with no step
            for by in (math.inf, 1e-3, 0.0):  # it reaches its goal at once, creeps, stands
                for lag in (zeros * 2):
                    wanted = (lean[0] + step[0] - -lag[0], lean[1] + step[1] - -lag[1],
                              lean[2] + step[2] - 0.0)
                    goal = copy.deepcopy(clip)(wanted, lean_max, buffer)
                    full = support_motion.moved_toward(lean, goal, by, buffer)
                    lean = support_motion.leaned(lean, step, lag, clip, lean_max, by, buffer)
                    assert _bits(lean) == _bits(full)
