"""The native contact clocks of a touch-down (ikfusion.ik.contact_clocks) are NumPy's.

The kernel replaces the touch-down's NumPy clocks and settling (#20); it makes the same
operations, so the released times, ages and settled anchors are the same bytes as
:func:`python_clocks`'s: on random states (anchors on, above and under the floor, signed zeros,
planted points sharing a segment, arrays the kernel has not seen, strided and written in place),
and on the real Xsens walk (when ../shared is there), where every fourth touch-down of the tracker
is replayed from the state before it with the NumPy path and must leave the same state, bit for
bit, with the clocks the touch-down always moved on.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from real_walk import solve_real_walk_natively

from ikfusion.ik import contact_tracker
from ikfusion.ik.contact_clocks import Clocks, NativeClocks, contact_clocks, python_clocks
from ikfusion.ik.contact_tracker import ContactTracker
from ikfusion.ik.point_bits import point_bits
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

MODEL = HumanModel.default()
POINTS = MODEL.sites_of_kind("contact")
LAYOUT = BodyTopology.of(MODEL).foot_layout(POINTS)
K = len(POINTS)


def _kernel_or_skip() -> NativeClocks:
    native = contact_clocks(K)
    if native is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    return native


def _same(got: Clocks, want: Clocks, anchors_in: np.ndarray) -> None:
    """The same bytes (NaN and signed zeros too), and the input anchors kept alike."""
    for x, y in zip(got, want):
        assert x.shape == y.shape and x.dtype == y.dtype
        assert x.tobytes() == y.tobytes()
    assert (got[2] is anchors_in) == (want[2] is anchors_in)


def _random_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Released times, ages, anchors and planted bits of every kind a solve makes, and odd ones."""
    released = rng.choice([0.0, np.inf, 0.01, 0.3, 2.5], size=K) + rng.random(K) * 1e-3
    released[rng.random(K) < 0.2] = np.inf
    age = rng.random(K) * rng.choice([0.0, 1.0, 10.0], size=K)
    anchors = rng.normal(scale=0.4, size=(K, 3))
    kind = rng.integers(6, size=K)  # heights: on the floor, just above, above, under, -0.0
    anchors[:, 2] = np.select([kind == 0, kind == 1, kind == 2, kind == 3, kind == 4],
                              [0.0, rng.random(K) * 1e-3, rng.random(K) * 0.1,
                               -rng.random(K) * 1e-3, -0.0], anchors[:, 2])
    if rng.random() < 0.3:
        anchors[:, 2] = 0.0  # every anchor on the floor (the usual frame)
    was = int(rng.integers(1 << K)) if rng.random() < 0.8 else 0
    if rng.random() < 0.5:  # no planted point sharing its segment (the feet)
        was &= ~point_bits(LAYOUT).shares_segment
    return released, age, anchors, was


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_random_states_give_numpys_bytes(seed: int) -> None:
    rng = np.random.default_rng(seed)
    native = _kernel_or_skip()
    released, age, anchors, was = _random_state(rng)
    for case in range(400):
        step = float(rng.choice([0.01, 0.0, -0.0, 0.04, 1.0]))
        drop = float(rng.choice([0.2 * step, 0.0, -0.0, -0.002, 1e-3]))
        floor_z = float(rng.choice([0.0, 0.0, -0.0, 0.01]))
        want = python_clocks(released, age, anchors, was, step, drop, floor_z, LAYOUT)
        got = native(released, age, anchors, was, step, drop, floor_z, LAYOUT)
        _same(got, want, anchors)
        released, age, anchors = got  # the usual frame: the last call's arrays again
        if case % 7 == 3:  # a new state from outside (a release, a move of the anchors)
            released, age, anchors, was = _random_state(rng)
        if case % 11 == 5:  # strided and single precision: read from copies or by NumPy
            released = np.repeat(released, 2)[::2]
            age = age.astype(np.float32)
            anchors = np.asfortranarray(anchors)


def test_arrays_written_in_place_are_read_as_they_are() -> None:
    """An array the kernel knows by identity is read where it is, as it is now."""
    native = _kernel_or_skip()
    rng = np.random.default_rng(7)
    released, age, anchors, was = _random_state(rng)
    anchors[:, 2] = 0.05
    released, age, anchors = native(released, age, anchors, was, 0.01, 0.002, 0.0, LAYOUT)
    for array in (released, age, anchors):
        array[...] = rng.random(array.shape)  # (a state is never written to: a caller's bug)
    want = python_clocks(released, age, anchors, was, 0.01, 0.002, 0.0, LAYOUT)
    _same(native(released, age, anchors, was, 0.01, 0.002, 0.0, LAYOUT), want, anchors)


def test_outputs_are_never_written_again() -> None:
    """Each call's arrays are new memory: the last call's stay as they were."""
    native = _kernel_or_skip()
    rng = np.random.default_rng(9)
    released, age, anchors, was = _random_state(rng)
    anchors[:, 2] = 0.05
    outputs = [native(released, age, anchors, was, 0.01, 0.002, 0.0, LAYOUT)]
    kept = [tuple(a.copy() for a in outputs[0])]
    for _ in range(200):  # across the blocks of output rows
        outputs.append(native(*outputs[-1], was, 0.01, 0.002, 0.0, LAYOUT))
    assert all(a.tobytes() == b.tobytes() for a, b in zip(kept[0], outputs[0]))
    assert not np.shares_memory(outputs[0][0], outputs[1][0])


def test_a_copied_tracker_shares_the_kernel() -> None:
    """A deep copy (of a tracker) keeps the kernel handle; each copy's arrays are its own."""
    native = _kernel_or_skip()
    rng = np.random.default_rng(4)
    state = _random_state(rng)
    first = native(*state[:3], state[3], 0.01, 0.002, 0.0, LAYOUT)
    twin = copy.deepcopy((native, first))
    assert twin[0] is native
    want = python_clocks(*twin[1], state[3], 0.01, 0.002, 0.0, LAYOUT)
    _same(native(*twin[1], state[3], 0.01, 0.002, 0.0, LAYOUT), want, twin[1][2])


def _clocks_of(tracker: ContactTracker) -> tuple[bytes, ...]:
    """What a touch-down leaves in a tracker's state, as bytes."""
    s = tracker.state
    return (s.active.tobytes(), s.anchors.tobytes(), s.age.tobytes(), s.released.tobytes())


def test_real_walk_replayed_with_numpy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each fourth touch-down of the real walk, replayed with NumPy: the same state; the clocks
    moved on as the touch-down always did (released: the free points'; age: the planted
    points', landing ones 0)."""
    _kernel_or_skip()
    calls: list[tuple[ContactTracker, tuple[object, ...], tuple[bytes, ...]]] = []
    original = ContactTracker.touch_down
    seen = [0]

    def captured(self: ContactTracker, *args: object) -> None:
        seen[0] += 1
        if seen[0] % 4:  # (a copy of the tracker costs ~2 ms)
            return original(self, *args)
        before = copy.deepcopy((self, args), memo={id(self.model): self.model,
                                                   id(self._sense): self._sense})
        original(self, *args)
        calls.append((*before, _clocks_of(self)))
        return None

    monkeypatch.setattr(contact_tracker.ContactTracker, "touch_down", captured)
    solve_real_walk_natively(tmp_path / "walk")
    assert len(calls) > 500 and isinstance(calls[0][0]._clocks, NativeClocks)
    for tracker, args, after in calls:
        was, state = tracker.state.active, tracker.state
        tracker._clocks = None
        original(tracker, *args)
        assert _clocks_of(tracker) == after
        step = max(args[0].time - tracker._history[0][0], 0.0)  # type: ignore[attr-defined]
        new = tracker.state
        assert new.released.tobytes() == np.where(was, state.released,
                                                  state.released + step).tobytes()
        age = np.where(new.active, state.age + step, 0.0)
        age[new.active & ~was] = 0.0
        assert new.age.tobytes() == age.tobytes()
