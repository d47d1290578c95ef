"""The frame step's glue (issue #20): what it keeps or defers gives what the full work gives."""

from __future__ import annotations

import numpy as np

from ikfusion.ik.limits import ContactConstraint
from ikfusion.ik.solver import Solver
from ikfusion.ik.swing_lead import LedBase
from ikfusion.model import HumanModel
from ikfusion.rotations import exp_so3

MODEL = HumanModel.default()
POINTS = MODEL.sites_of_kind("contact")


def _held(contact: ContactConstraint, p: np.ndarray, J: np.ndarray) -> list[bytes]:
    """Everything the constraint holds and the rows it makes, as bytes."""
    rows = contact.rows(p, J)
    return [contact.active.tobytes(), contact.anchors.tobytes(), contact.free_z.tobytes(),
            contact._held.tobytes(), contact._held_rows.tobytes(), rows.A.tobytes(),
            rows.b.tobytes(), contact.planted_slide_m(p).tobytes()]


def test_anchors_set_again_unchanged_hold_what_a_fresh_constraint_holds() -> None:
    rng = np.random.default_rng(5)
    k, nv = len(POINTS), MODEL.model.nv
    kept = ContactConstraint(list(range(k)), POINTS)
    patterns = []
    for _ in range(12):
        active = rng.random(k) < 0.4
        rising = None if rng.random() < 0.3 else rng.random(k) < 0.3
        patterns.append((active, rng.normal(size=(k, 3)), rising))
    p, J = rng.normal(size=(k, 3)), rng.normal(size=(k, 3, nv))
    order = [0, 0, 1, 1, 1, 0, 2, 3, 3, 2, 4, 5, 5, 6, 7, 7, 8, 9, 10, 11, 11, 0]
    for i in order:  # each pattern set again unchanged (the usual frame) and come back
        active, anchors, rising = patterns[i]
        kept.set_anchors(active, anchors, rising)
        fresh = ContactConstraint(list(range(k)), POINTS)
        fresh.set_anchors(active, anchors, rising)
        assert _held(kept, p, J) == _held(fresh, p, J)
        assert kept.slides(p, 0.1) == fresh.slides(p, 0.1)


def test_anchors_written_in_place_are_set_again() -> None:
    rng = np.random.default_rng(6)
    k = len(POINTS)
    contact = ContactConstraint(list(range(k)), POINTS)
    active, anchors, rising = rng.random(k) < 0.5, rng.normal(size=(k, 3)), rng.random(k) < 0.5
    contact.set_anchors(active, anchors, rising)
    held = contact.anchors
    contact.set_anchors(active, anchors, rising)  # unchanged: the same arrays are kept
    assert contact.anchors is held
    for name in ("active", "anchors", "free_z"):  # one of its arrays written in place
        mine = getattr(contact, name)
        mine.flat[0] = not mine.flat[0] if mine.dtype == bool else mine.flat[0] + 1.0
        contact.set_anchors(active, anchors, rising)
        assert contact.active.tobytes() == active.tobytes()
        assert contact.anchors.tobytes() == anchors.tobytes()
        assert contact.free_z.tobytes() == (rising & active).tobytes()
    given = anchors.copy()  # the caller's arrays written in place: set anew
    anchors[0] += 1.0
    contact.set_anchors(active, anchors, rising)
    assert contact.anchors.tobytes() == anchors.tobytes() != given.tobytes()
    contact.set_anchors(active, anchors, None)  # no rising heels now
    assert not contact.free_z.any()


def test_led_base_moved_by_a_kept_offset_is_the_sum_kept() -> None:
    rng = np.random.default_rng(7)
    k = len(POINTS)
    for _ in range(200):
        p_sensed, offset, p_solved = rng.normal(size=(k, 3)), rng.normal(size=3), \
            rng.normal(size=(k, 3))
        lag, lean = tuple(rng.normal(size=3).tolist()), tuple(rng.normal(size=3).tolist())
        summed, deferred = LedBase(k), LedBase(k)
        summed.keep(p_sensed + offset, lag, lean)
        deferred.keep(p_sensed, lag, lean, offset)
        summed.record(p_solved)
        deferred.record(p_solved)
        assert deferred.deviation().tobytes() == summed.deviation().tobytes()


def test_sensed_points_are_read_only_and_the_targets_reach_the_slot_transposed() -> None:
    solver = Solver(MODEL)
    rng = np.random.default_rng(8)
    n = len(MODEL.segment_names)
    q = MODEL.neutral()
    T = exp_so3(rng.normal(size=(n, 3)))
    _, p_sensed = solver.sensed.pose(q, T, np.ones(n, dtype=bool))
    assert not p_sensed.flags.writeable
    compiled = solver.sensed._compiled
    if compiled is not None:  # the function reads each 3 x 3 block column-major
        assert compiled.call.input_slot(1).tobytes() == T.transpose(0, 2, 1).tobytes()


def test_ballistic_velocity_kept_in_floats_is_the_filter_on_arrays() -> None:
    from ikfusion.ik.ballistic import BallisticRoot

    rng = np.random.default_rng(9)
    root = BallisticRoot(0.05)
    v = rng.normal(size=3)
    root.velocity = v.copy()
    assert root.velocity.tobytes() == v.tobytes()  # set and read back: the same numbers
    for _ in range(300):
        v_solved, a, dt = rng.normal(size=3), rng.normal(size=3) * 5.0, rng.uniform(0.005, 0.02)
        root.update(v_solved, dt, a, supported=True)
        predicted = v + a * dt  # the filter on (3,) arrays (no lever arm: no motion around)
        v = predicted + min(1.0, dt / 0.05) * (v_solved + np.zeros(3) / dt + 0.5 * a * dt
                                               - predicted)
        assert root.velocity.tobytes() == v.tobytes()
        assert root.velocity is not root.velocity  # a new array at each read
