"""A paced live stream whose solver fell behind: it skips to the newest frame and never stops
sending poses, and it does not drop a frame that can still leave within the latency budget."""

from __future__ import annotations

from pathlib import Path

from ikfusion.io.reader import read_imu
from ikfusion.io.sensor_map import load_sensor_map
from ikfusion.live.actor_stream import ActorStream
from ikfusion.live.frames import AssembledFrame, FrameAssembler
from ikfusion.live.kinematics import PoseKinematics
from ikfusion.live.replay import recording_samples
from ikfusion.live.run import LiveActor, LiveLoop
from ikfusion.live.samples import ImuSample
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
