"""Frame assembly: complete frames leave at once, a missing sensor never stalls the stream."""

from __future__ import annotations

import numpy as np

from ikfusion.live.frames import FrameAssembler
from ikfusion.live.samples import ImuSample

RATE = 100.0
SENSORS = ("A", "B", "C")


def sample(sensor: str, k: int, offset: float = 0.0) -> ImuSample:
    return ImuSample(sensor, k / RATE + offset, np.array([1.0, 0.0, 0.0, 0.0]))


def test_a_complete_frame_leaves_with_its_last_sample() -> None:
    frames = FrameAssembler(SENSORS, RATE)
    assert frames.add(sample("A", 0), 0.0) == []
    assert frames.add(sample("B", 0), 0.0) == []
    out = frames.add(sample("C", 0), 0.0)
    assert [f.time for f in out] == [0.0] and out[0].complete
    assert set(out[0].samples) == set(SENSORS)


def test_a_frame_missing_a_sensor_leaves_on_its_deadline() -> None:
    """Sensor C lost at frame 1: frame 1 waits for the samples of frame 2 (1 period later: not
    yet due) and leaves with the first sample of frame 3 (1.5 periods passed), then frame 2."""
    frames = FrameAssembler(SENSORS, RATE, deadline_periods=1.5)
    released = []
    for k in range(4):
        for s in SENSORS:
            if (s, k) != ("C", 1):
                released += frames.add(sample(s, k), 0.0)
        if k == 2:
            assert [f.time for f in released] == [0.0]
    assert [round(f.time * RATE) for f in released] == [0, 1, 2, 3]
    assert not released[1].complete and set(released[1].samples) == {"A", "B"}
    assert frames.counters.on_deadline == 1 and frames.counters.missing == {"C": 1}


def test_a_sensor_that_drops_out_and_comes_back_never_stalls() -> None:
    frames = FrameAssembler(SENSORS, RATE)
    released = []
    for k in range(300):
        for s in SENSORS:
            if s != "B" or not 50 <= k < 150:
                released += frames.add(sample(s, k), 0.0)
    released += frames.flush()
    assert [round(f.time * RATE) for f in released] == list(range(300))
    assert frames.counters.missing == {"B": 100}
    assert all(f.complete for f in released[150:])


def test_a_quiet_source_releases_pending_frames_on_the_wall_clock() -> None:
    """Nothing more arrives: the frame leaves once its wall deadline passed, not before."""
    frames = FrameAssembler(SENSORS, RATE, deadline_periods=1.5, wall_deadline_s=0.015)
    frames.add(sample("A", 0), now=10.0)
    frames.add(sample("B", 0), now=10.001)
    assert frames.poll(10.010) == []
    out = frames.poll(10.016)
    assert len(out) == 1 and set(out[0].samples) == {"A", "B"}


def test_late_and_duplicate_samples_are_dropped_and_counted() -> None:
    frames = FrameAssembler(SENSORS, RATE)
    for k in range(3):
        for s in SENSORS:
            frames.add(sample(s, k), 0.0)
    assert frames.add(sample("A", 1), 0.0) == []  # its frame is gone
    frames.add(sample("A", 3), 0.0)
    frames.add(sample("A", 3), 0.0)
    assert frames.counters.late == 1 and frames.counters.duplicates == 1


def test_a_clock_jump_of_one_sensor_is_taken_back_onto_the_stream() -> None:
    """Sensor C's clock jumps 100 s ahead at frame 10: the frames go on, C still in them."""
    frames = FrameAssembler(SENSORS, RATE, clock_jump_s=1.0)
    released = []
    for k in range(40):
        for s in SENSORS:
            released += frames.add(sample(s, k, offset=100.0 if s == "C" and k >= 10 else 0.0),
                                   0.0)
    assert [round(f.time * RATE) for f in released] == list(range(40))
    assert frames.counters.clock_jumps == 1
    assert all(f.complete for f in released)
