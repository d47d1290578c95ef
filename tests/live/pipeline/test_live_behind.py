"""A paced live stream whose solver fell behind: it skips to the newest frame and never stops
sending poses, and it does not drop a frame that can still leave within the latency budget."""

from __future__ import annotations

import gc
import queue
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from ikfusion.io.reader import read_imu
from ikfusion.io.sensor_map import load_sensor_map
from ikfusion.live.actor_pose import ActorPose
from ikfusion.live.actor_stream import ActorStream
from ikfusion.live.frames import AssembledFrame, FrameAssembler
from ikfusion.live.kinematics import PoseKinematics
from ikfusion.live.replay import recording_samples
from ikfusion.live.run import LiveActor, LiveLoop
from ikfusion.live.samples import ImuSample, Sample
from ikfusion.live.settings import LiveSettings
from ikfusion.model import Body, HumanModel


class _Clock:
    """A wall clock [s] the test sets."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _calibrated(capture: Path) -> tuple[LiveLoop, LiveActor, _Clock, list[list[ImuSample]]]:
    """A paced loop whose actor has calibrated on the capture's first 7 s, and the samples of
    the later frames, frame by frame."""
    sensor_map = load_sensor_map(capture / "sensors.yaml")
    recording = read_imu(capture / "imu", sensor_map=sensor_map)
    model = HumanModel.from_body(Body.from_yaml(capture / "body.yaml"))
    stream = ActorStream(model, sensor_map, recording.rate, solve_startup=False)
    actor = LiveActor("a", 0, stream, FrameAssembler(sensor_map, recording.rate),
                      PoseKinematics(model))
    clock = _Clock()
    loop = LiveLoop([actor], paced=False, clock=clock)
    later: dict[float, list[ImuSample]] = {}
    for sample in recording_samples(recording, sensor_map):
        if sample.time_s < 7.0:
            loop.take(sample, 0.0)
        else:
            later.setdefault(round(sample.time_s, 6), []).append(sample)
    assert actor.live_since is not None and actor.frames > 0  # calibrated, live
    loop.paced = True
    return loop, actor, clock, [later[t] for t in sorted(later)]


def _frames(actor: LiveActor, frames: list[list[ImuSample]], arrived: list[float]
            ) -> list[AssembledFrame]:
    """The frames released when ``frames``' samples arrived at wall times ``arrived`` [s]."""
    out = []
    for samples, t in zip(frames, arrived):
        for s in samples:
            out += actor.assembler.add(s, t)
    return out + actor.assembler.flush()


def test_a_solver_far_behind_still_sends_the_newest_frame(capture: Path) -> None:
    """Five frames waiting, all of them released long ago (the solver was busy): the newest is
    solved and sent, the four before it dropped and counted (before, every frame released
    longer ago than the lag was dropped, so a solver behind sent nothing at all)."""
    loop, actor, clock, later = _calibrated(capture)
    clock.now = 100.0
    actor.live_since = 99.0  # live for a second
    frames = _frames(actor, later[:5], [clock.now + 0.001 * i for i in range(5)])
    assert len(frames) == 5
    clock.now += 0.050  # the oldest arrived 50 ms ago, the newest 46 ms ago
    solved, dropped = actor.frames, actor.dropped
    loop._solve(actor, frames)
    assert actor.frames - solved == 1
    assert actor.dropped - dropped == 4
    assert actor.latency_s[-1][0] == frames[-1].time  # the newest one was sent


def test_a_frame_that_can_leave_within_the_budget_is_not_dropped(capture: Path) -> None:
    """Two frames waiting after a hiccup: the older one, 2 solve times short of the budget,
    and the newest just in: both are solved (dropping a frame that can still leave in time
    is worse than sending it a little late)."""
    loop, actor, clock, later = _calibrated(capture)
    budget = LiveSettings.load().latency_budget_s
    cost = 0.001
    clock.now = 100.0
    actor.live_since = 99.0  # live for a second
    frames = _frames(actor, later[:2], [clock.now, clock.now + budget - 2 * cost])
    clock.now += budget - 2 * cost
    actor.solve_s = cost
    solved = actor.frames
    loop._solve(actor, frames)
    assert actor.frames - solved == 2
    assert actor.dropped == 0
    # and a backlog that cannot all leave in time: the older frame dropped, the newest sent
    frames = _frames(actor, later[2:4], [clock.now, clock.now])
    clock.now += budget
    loop._solve(actor, frames)
    assert actor.dropped == 1 and actor.latency_s[-1][0] == frames[-1].time


def test_samples_arriving_while_the_loop_takes_them_wait_for_the_next_round(
        capture: Path) -> None:
    """A source delivering faster than the loop assembles (240 Hz on a loaded machine): the
    samples that arrived before the round began are taken, with the first one after it, and
    the rest wait in the inbox while the frames released so far are solved (before, the loop
    took samples until the inbox was empty, so a source that kept ahead held every solve back:
    at 240 Hz under load not one pose in 6 s)."""
    loop, actor, clock, later = _calibrated(capture)
    clock.now = 100.0  # the round begins
    inbox: queue.Queue[Any] = queue.Queue()
    for k, samples in enumerate(later[:20]):  # frames 0-9 arrived before it, 10-19 during it
        for sample in samples:
            inbox.put((sample, 99.905 + 0.01 * k))
    waiting, ended = loop._arrived(inbox, inbox.get_nowait())
    assert not ended
    assert [f.time for f in waiting["a"]] == [samples[0].time_s for samples in later[:10]]
    assert inbox.qsize() == sum(len(samples) for samples in later[10:20]) - 1


class _Samples:
    """A source: the given samples, then the end."""

    def __init__(self, samples: list[ImuSample]) -> None:
        self._samples = samples

    def samples(self) -> Iterator[Sample]:
        return iter(self._samples)

    def close(self) -> None:
        pass


class _FrozenAtSend:
    """A pose sink noting the garbage collector's frozen objects at every pose."""

    def __init__(self) -> None:
        self.frozen: list[int] = []

    def send(self, poses: Sequence[ActorPose]) -> None:
        self.frozen.append(gc.get_freeze_count())

    def close(self) -> None:
        pass


def test_the_heap_made_before_the_stream_is_left_out_of_garbage_collections(
        capture: Path) -> None:
    """While the stream runs, the objects made before it (the model, the solver: tens of
    thousands) and by the calibration are frozen out of Python's garbage collector, whose full
    pass over them took 45 ms in the middle of a frame (before, nothing was: a few frames
    dropped at every full pass); the end of the stream gives them back."""
    sensor_map = load_sensor_map(capture / "sensors.yaml")
    recording = read_imu(capture / "imu", sensor_map=sensor_map)
    model = HumanModel.from_body(Body.from_yaml(capture / "body.yaml"))
    stream = ActorStream(model, sensor_map, recording.rate)
    actor = LiveActor("a", 0, stream, FrameAssembler(sensor_map, recording.rate),
                      PoseKinematics(model))
    sink = _FrozenAtSend()
    gc.collect()
    alive = len(gc.get_objects())
    LiveLoop([actor], [sink], paced=False).run(
        _Samples(list(recording_samples(recording, sensor_map))))
    assert len(sink.frozen) == actor.frames == len(recording)
    assert min(sink.frozen) >= 0.9 * alive
    assert sink.frozen[-1] > sink.frozen[0]  # the calibration's objects too
    assert gc.get_freeze_count() == 0
