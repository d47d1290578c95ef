"""The native smoothing of the sensed contact points (ikfusion.ik.sensed_evidence) is NumPy's.

The kernel replaces about twenty NumPy and Python operations at the start of every
:meth:`ContactTracker.release` (#20); it makes the same operations in the same order, so the
smoothed points and pitches, their steps and velocities, heights and bits are the same bytes as
:func:`python_evidence`'s: on random frames (NaN heights and pitches, frames without time, a
tracker restarted from outside arrays), and on the real Xsens walk (when ../shared is there),
where every fourth release and touch-down of the tracker is replayed from the state before it
with the NumPy path and must leave the tracker in the same state, bit for bit.
"""

from __future__ import annotations

import copy
import functools
from pathlib import Path

import numpy as np
import pytest
from real_walk import solve_real_walk_natively

from ikfusion.ik import contact_tracker
from ikfusion.ik.contact_tracker import ContactTracker
from ikfusion.ik.sensed_evidence import NativeSensing, Rules, Sensed, python_evidence, sensing

K = 14  # the default model's contact points
RULES = Rules(0.6, 0.3, 0.03, 0.05, 0.5, (8, 9, 13), (0, 2, 4, 6, 10), (1, 3, 5, 7))


def _same(a: Sensed, b: Sensed) -> None:
    """The same bytes in every array (NaN too) and the same bits."""
    for x, y, name in zip(a, b, Sensed._fields):
        if isinstance(x, np.ndarray):
            assert isinstance(y, np.ndarray) and x.shape == y.shape, name
            assert x.tobytes() == y.tobytes(), name
            assert x.flags.writeable == y.flags.writeable, name
        else:
            assert x == y, name


def _kernel_or_skip(rules: Rules = RULES, k: int = K) -> NativeSensing:
    native = sensing(rules, k)
    if native is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    return native


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_frames_give_numpys_bytes(seed: int) -> None:
    rng = np.random.default_rng(seed)
    native = _kernel_or_skip()
    p_native = p_numpy = rng.normal(scale=0.05, size=(K, 3))
    pitch_native = pitch_numpy = rng.normal(scale=0.6, size=K)
    for frame in range(300):
        p = rng.normal(scale=0.05, size=(K, 3)) + [0.0, 0.0, 0.02 * (frame % 7)]
        pitch = rng.normal(scale=0.6, size=K)
        if frame % 11 == 3:  # a lost sensor: NaN
            p[rng.integers(K), 2] = np.nan
            pitch[rng.integers(K)] = np.nan
        dt = [0.01, 0.0, -0.01, 1.0 / 60.0][frame % 4] if frame % 5 == 0 else 0.01
        if frame % 50 == 49:  # a restart from arrays of the caller's
            p_native = p_numpy = p_numpy.copy()
            pitch_native = pitch_numpy = pitch_numpy.copy()
        got = native(p_native, pitch_native, p, pitch, dt)
        want = python_evidence(RULES, p_numpy, pitch_numpy, p, pitch, dt)
        _same(got, want)
        assert (got.velocity is None) == (dt <= 0)
        p_native, pitch_native, p_numpy, pitch_numpy = got.p, got.pitch, want.p, want.pitch
        if not np.isnan(p_numpy[:, 2]).any():  # NaN stays in the smoothed points: start over
            continue
        p_native = p_numpy = rng.normal(scale=0.05, size=(K, 3))


def test_outputs_are_never_written_again() -> None:
    """Each frame's arrays are new memory: the last frames' stay as they were (blocks too)."""
    from ikfusion.ik.sensed_evidence import FRAMES_A_BLOCK

    native = _kernel_or_skip()
    frame = native(np.zeros((K, 3)), np.zeros(K), np.ones((K, 3)), np.ones(K), 0.01)
    frames, kept = [], []
    for n in range(2 * FRAMES_A_BLOCK + 3):  # across blocks of output memory
        frames.append(frame)
        kept.append([None if x is None else x.copy() for x in frame[:5]])
        frame = native(frame.p, frame.pitch, np.full((K, 3), n + 2.0), np.full(K, n + 2.0),
                       0.01 * (n % 3))
    for made, copies in zip(frames, kept):
        assert all(y is None if x is None else np.array_equal(x, y)
                   for x, y in zip(copies, made[:5]))
        assert not made.p.flags.writeable and not made.pitch.flags.writeable
        assert not np.shares_memory(made.p, frame.p)


def _tracker_state(tracker: ContactTracker) -> tuple[object, ...]:
    """Everything release and touch_down leave in a tracker, as bytes and ints."""
    s = tracker.state

    def b(a: np.ndarray | None) -> bytes | None:
        return None if a is None else a.tobytes()

    evidence = tracker._evidence
    return (b(s.active), b(s.anchors), b(s.age), b(s.released), b(tracker._p_sensed),
            b(tracker._pitch), b(tracker._v_sensed), tracker._rising, tracker._far,
            b(tracker.floor_points()), None if evidence is None else
            (b(evidence[3].height_rel), *evidence[3][1:]), len(tracker._history))


def test_real_walk_replayed_with_numpy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each release and touch-down of the real walk, replayed with NumPy: the same state."""
    _kernel_or_skip()
    calls: list[tuple[str, ContactTracker, tuple[object, ...], tuple[object, ...]]] = []
    originals = {name: getattr(ContactTracker, name) for name in ("release", "touch_down")}
    seen = dict.fromkeys(originals, 0)

    def captured(name: str):  # noqa: ANN202
        def call(self: ContactTracker, *args: object) -> object:
            seen[name] += 1
            if seen[name] % 4:  # every fourth call of each (a copy of the tracker costs ~2 ms)
                return originals[name](self, *args)
            before = copy.deepcopy((self, args), memo={id(self.model): self.model,
                                                       id(self._sense): self._sense})
            out = originals[name](self, *args)
            calls.append((name, *before, _tracker_state(self)))
            return out
        return call

    for name in originals:
        monkeypatch.setattr(contact_tracker.ContactTracker, name, captured(name))
    solve_real_walk_natively(tmp_path / "walk")
    assert len(calls) > 1000 and isinstance(calls[0][1]._sense, NativeSensing)
    for name, tracker, args, after in calls:
        tracker._sense = functools.partial(python_evidence, tracker._sense.rules)
        originals[name](tracker, *args)
        assert _tracker_state(tracker) == after, name
