"""The native soft-wall sink (ikfusion.ik.wall_sink) gives NumPy's numbers bit for bit (#20).

The kernel replaces eight NumPy calls of :meth:`SoftWall.update` per frame; it makes the same
operations in the same order, so the sink, the test "does an angle reach a limit" and the room
that follows are the same bytes: on random angles (near the limits, NaN too), and on every
frame of a joint driven past its limit and of the real Xsens walk (when ../shared is there),
each update made twice, by the kernel and by the NumPy path.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from test_soft_wall import ankle_running_into_its_limit, solve

from ikfusion.cli import main
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.ik.limits.soft_wall import SoftWall
from ikfusion.ik.wall_sink import wall_sink
from ikfusion.model import HumanModel


def _numpy_sink(limit: np.ndarray, now: np.ndarray, before: np.ndarray, grow: float,
                drift: float) -> np.ndarray:
    """The sink (2, joints, 3) as :meth:`SoftWall.update`'s NumPy path computes it."""
    sunk = np.multiply(np.array([1.0, -1.0])[:, None, None], now)
    sunk -= limit
    sunk *= grow
    change = (now - before) * drift
    sunk[0] += change
    sunk[1] -= change
    return sunk


def _same_bytes(a: np.ndarray, b: np.ndarray) -> bool:
    """The same numbers bit for bit (signed zeros too), NaN at the same places (any sign)."""
    nan = np.isnan(a)
    return bool(np.array_equal(nan, np.isnan(b))
                and np.where(nan, 0.0, a).tobytes() == np.where(nan, 0.0, b).tobytes())


def _kernel_or_skip(limit: np.ndarray):
    sink = wall_sink(limit)
    if sink is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    return sink


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_angles_near_the_limits(human: HumanModel, seed: int) -> None:
    rng = np.random.default_rng(seed)
    ranges = JointRangeLimit(human.ball_joints, 5.0)
    limit = np.stack([ranges.upper, -ranges.lower])
    sink = _kernel_or_skip(limit)
    before = ranges.upper + rng.normal(scale=0.05, size=ranges.upper.shape)
    sink.first(before)
    reached = 0
    for k in range(200):
        side = np.where(rng.random(ranges.upper.shape) < 0.5, ranges.upper, ranges.lower)
        now = side + rng.normal(scale=0.05 if k % 2 else 0.5, size=side.shape)
        if k % 37 == 5:
            now[rng.integers(len(now)), rng.integers(3)] = np.nan
        grow, drift = rng.uniform(0.5, 1.5), rng.uniform(0.0, 1.5)
        reaches = sink.reaches(now, grow, drift)
        expected = _numpy_sink(limit, now, before, grow, drift)
        assert _same_bytes(sink.sunk, expected)
        assert reaches == bool(expected.max() > 0.0)
        reached += reaches
        before = now
    assert 20 < reached < 190


class _Twins:
    """Every :meth:`SoftWall.update` made by the kernel and again by a NumPy-path twin."""

    def __init__(self) -> None:
        self.updates = self.rooms = 0
        self._twins: dict[int, tuple[SoftWall, SoftWall]] = {}
        self._update = SoftWall.update

    def __call__(self, wall: SoftWall, angles: np.ndarray, dt: float) -> None:
        assert wall._sink is not None or not wall.enabled
        twin = self._twins.get(id(wall), (wall, None))[1]
        if twin is None:
            twin = copy.copy(wall)
            twin._sink = None
            self._twins[id(wall)] = (wall, twin)
        twin._before, twin._previous = wall._before, wall._previous  # (reset by the solver)
        self._update(wall, angles, dt)
        self._update(twin, angles, dt)
        self.updates += 1
        if wall._room is None:
            assert twin._room is None
        else:
            self.rooms += 1
            assert twin._room is not None and wall._room.tobytes() == twin._room.tobytes()


@pytest.fixture
def twins(monkeypatch: pytest.MonkeyPatch) -> _Twins:
    made = _Twins()
    if wall_sink(np.zeros((2, 1, 3))) is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    monkeypatch.setattr(SoftWall, "update", lambda wall, angles, dt: made(wall, angles, dt))
    return made


def test_a_joint_driven_past_its_limit(human: HumanModel, twins: _Twins) -> None:
    solve(human, ankle_running_into_its_limit(human), 10.0)
    assert twins.updates >= 49 and twins.rooms >= 5


def test_the_real_walk(twins: _Twins, tmp_path: Path) -> None:
    trial = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "xsens" / \
        "opensense_walk"
    if not trial.is_dir():
        pytest.skip(f"real recordings not available: {trial} is absent (a user's clone)")
    assert main(["solve", "--imu", str(trial), "--map", str(trial / "myIMUMappings.xml"),
                 "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert twins.updates >= 2500
    print(f"{twins.rooms} rooms in {twins.updates} updates")


def test_without_a_compiler_the_numpy_path_stays(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IKFUSION_NO_COMPILE", "1")
    assert wall_sink(np.zeros((2, 1, 3))) is None
    assert SoftWall(np.full((1, 3), -1.0), np.ones((1, 3)), 0.1, 0.05)._sink is None
