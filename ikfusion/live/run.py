"""The live loop: samples in, frames assembled, each actor solved causally, poses out.

A reader thread takes the samples from the source as they arrive and time-stamps their arrival;
the loop hands each IMU sample to its actor's :class:`~ikfusion.live.frames.FrameAssembler`
(routed by the sample's ``actor`` when the source names it, else by sensor id), solves every
released frame with the actor's :class:`~ikfusion.live.actor_stream.ActorStream`, and sends the
pose to every sink (one :class:`~ikfusion.live.actor_pose.ActorPose` per call, as soon as it is
solved) and to the actor's recorder. Nothing waits for a missing sample: frames are released on
their deadline, also when the source goes quiet.

When the solver falls behind a paced source, the loop skips to the newest frame: every sample
that arrived meanwhile is taken first (one that arrives while they are taken waits for the next
round, so a source faster than the assembly cannot hold the solves back), and of the frames
then waiting only those whose pose can
still leave within ``latency_budget_s`` of ``configs/live.yaml`` (counted from their first
sample's arrival, with the recent solve time as the cost of each frame still to solve) are
solved; the others are dropped (not solved, counted; their samples still feed the bridging, the
stance, the flight detection and the UWB tags). The newest frame waiting is always solved, so
the poses go on at a lower rate and the latency stays bounded. The calibration blocks the loop
(a fraction of a second); the frames that arrived until the actor caught up after it (its
first pose within the budget) are the start-up: their drops are counted apart and their
latency is not in the percentiles. An unpaced replay (``--speed 0``) drops nothing,
so it gives the poses of ``solve --causal`` exactly. A paced stream does not solve the frames of
its start-up buffer (only the last one: the stream starts at once instead of catching up;
``ActorStream(solve_startup=False)``), so its ``--record`` starts at the end of the calibration.

During :meth:`LiveLoop.run` the objects made before the stream and by each calibration (models,
solvers: most of the heap) are frozen out of Python's garbage collector (``gc.freeze``), whose
full passes over them took tens of milliseconds in the middle of a frame.
"""

from __future__ import annotations

import gc
import queue
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, TextIO

import numpy as np

from ..io.recording import normalize_sensor_id
from .actor_pose import PoseSink
from .actor_stream import ActorStream
from .frames import AssembledFrame, FrameAssembler
from .kinematics import PoseKinematics
from .record import ResultRecorder
from .samples import ImuSample, Sample, SampleSource

_END = object()


@dataclass
class LiveActor:
    """One actor of a live session and what happened to it.

    Attributes:
        name: Actor name; ``character_id`` its number in the streams.
        stream: Its causal solver; ``assembler`` its frame assembly.
        kinematics: Forward kinematics of its model.
        recorder: Its result folder (``--record``), or None.
        frames: Frames solved; ``dropped``: frames dropped because the solver fell behind;
            ``dropped_startup``: those of them that arrived during the calibration.
        latency_s: (frame time [s], arrival of its first sample to its pose sent [s]) of the
            frames that arrived after ``live_since``.
        live_since: Wall time [s] the actor caught up after its calibration: its first pose
            sent within the latency budget, or of a frame that arrived after the calibration
            (None before; the frames that arrived until then are the start-up).
        calibrated_at: Wall time [s] its calibration ended (None before).
        cpu_s: CPU time [s] of the loop's thread per frame of ``latency_s`` (solve, outputs):
            what the latency would be on an idle machine, less the waiting.
        solve_s: Recent wall time [s] to solve and send one frame (a running mean), what a
            frame still to solve is expected to cost.
    """

    name: str
    character_id: int
    stream: ActorStream
    assembler: FrameAssembler
    kinematics: PoseKinematics
    recorder: ResultRecorder | None = None
    frames: int = 0
    dropped: int = 0
    dropped_startup: int = 0
    latency_s: list[tuple[float, float]] = field(default_factory=list)
    live_since: float | None = None
    calibrated_at: float | None = None
    cpu_s: list[float] = field(default_factory=list)
    solve_s: float = 0.0

    def summary(self) -> dict[str, Any]:
        """The ``live`` block of its ``summary.json``."""
        c = self.assembler.counters
        lat = np.array([v for _, v in self.latency_s]) * 1e3
        return {"character_id": self.character_id, "frames_solved": self.frames,
                "frames_dropped": self.dropped,
                "frames_dropped_at_startup": self.dropped_startup,
                "frames_on_deadline": c.on_deadline,
                "late_samples": c.late, "duplicate_samples": c.duplicates,
                "clock_jumps": c.clock_jumps, "missing_frames_by_sensor": dict(c.missing),
                "latency_ms_p50": float(np.percentile(lat, 50)) if len(lat) else None,
                "latency_ms_p99": float(np.percentile(lat, 99)) if len(lat) else None}


@dataclass
class LiveLoop:
    """Runs one live session (see the module docstring).

    Args:
        actors: The actors, in session order.
        sinks: Outputs receiving every pose.
        paced: The source delivers at the capture's pace (live, or a replay at a speed > 0):
            frames may then be dropped when the solver falls behind.
        latency_budget_s: A frame waiting behind a newer one is solved only when its pose can
            still leave this soon after its first sample arrived (paced only) [s].
        status: Where the one-line status goes (None: nowhere).
        clock: Wall clock [s].
    """

    actors: list[LiveActor]
    sinks: Sequence[PoseSink] = ()
    paced: bool = True
    latency_budget_s: float = 0.015
    status: TextIO | None = None
    clock: Callable[[], float] = time.perf_counter
    toa_samples: int = 0
    sink_errors: list[str] = field(default_factory=list)
    _route: dict[str, LiveActor] = field(default_factory=dict)
    _route_sent: dict[str, LiveActor | None] = field(default_factory=dict)
    _status_at: float = 0.0
    _frozen: bool = False

    def __post_init__(self) -> None:
        for actor in reversed(self.actors):  # the first actor naming a sensor gets it
            for sensor in actor.stream.segment_of:
                self._route[sensor] = actor
        self._by_name = {a.name: a for a in self.actors}

    def run(self, source: SampleSource, poll_s: float = 0.005) -> None:
        """Until the source ends (or Ctrl-C): every sample taken, every frame released solved."""
        inbox: queue.Queue[Any] = queue.Queue()

        def read() -> None:
            try:
                for sample in source.samples():
                    inbox.put((sample, self.clock()))
            except BaseException as err:  # handed to the loop, which raises it
                inbox.put(err)
            inbox.put(_END)

        reader = threading.Thread(target=read, name="ikfusion-live-source", daemon=True)
        gc.freeze()  # what exists now (models, solvers) is left out of every collection
        self._frozen = True
        try:
            reader.start()
            try:
                ended = False
                while not ended:
                    try:
                        item = inbox.get(timeout=poll_s)
                    except queue.Empty:
                        item = None
                    waiting, ended = self._arrived(inbox, item)
                    now = self.clock()
                    for actor in self.actors:
                        if inbox.empty():  # wall deadlines once every sample that arrived is in
                            waiting[actor.name] += actor.assembler.poll(now)
                        self._solve(actor, waiting[actor.name])
                    self._show_status(self.clock())
            finally:
                source.close()
            self.finish()
        finally:
            self._frozen = False
            gc.unfreeze()

    def _arrived(self, inbox: queue.Queue[Any], item: Any
                 ) -> tuple[dict[str, list[AssembledFrame]], bool]:
        """The frames released by ``item`` and the samples arrived before; the source ended.

        Paced, the samples that arrived before this round began are taken after ``item``; one
        that arrives while they are assembled waits for the next round, so a source delivering
        faster than they are assembled cannot hold the solves back.
        """
        waiting: dict[str, list[AssembledFrame]] = {a.name: [] for a in self.actors}
        started = self.clock()
        while item is not None:
            if item is _END:
                return waiting, True
            if isinstance(item, BaseException):
                raise item
            actor, frames = self._assemble(*item)
            if actor is not None:
                waiting[actor.name] += frames
            if not self.paced or item[1] > started:
                break
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                item = None
        return waiting, False

    def take(self, sample: Sample, arrived: float) -> None:
        """One sample arrived at wall time ``arrived`` [s]: the frames it releases solved."""
        actor, frames = self._assemble(sample, arrived)
        if actor is not None:
            self._solve(actor, frames)

    def _assemble(self, sample: Sample, arrived: float
                  ) -> tuple[LiveActor | None, list[AssembledFrame]]:
        """One sample to its actor's assembler (TOAs to every tag feed); the frames released."""
        if not isinstance(sample, ImuSample):
            self.toa_samples += 1
            for each in self.actors:  # each actor's tag feed keeps its own tags
                each.stream.toa(sample)
            return None, []
        if sample.actor:
            actor = self._by_name.get(sample.actor)
        elif sample.sensor in self._route_sent:
            actor = self._route_sent[sample.sensor]
        else:  # the id as sent, normalised once
            actor = self._route_sent[sample.sensor] = self._route.get(
                normalize_sensor_id(sample.sensor))
        if actor is None:
            return None, []
        return actor, actor.assembler.add(sample, arrived)

    def finish(self) -> None:
        """The stream ended: the pending frames and the start-up buffers solved."""
        for actor in self.actors:
            self._solve(actor, actor.assembler.flush())
            self._send(actor, actor.stream.finish(), None)
        if self.status is not None:
            self._show_status(self.clock(), force=True)
            self.status.write("\n")

    def _solve(self, actor: LiveActor, frames: list[AssembledFrame]) -> None:
        """Solve the frames waiting, in time order; behind, those too late are dropped."""
        for i, frame in enumerate(frames):
            calibrated = actor.stream.calibration is not None
            steady = actor.live_since is not None and frame.first_arrival > actor.live_since
            if self.paced and calibrated and i < len(frames) - 1 \
                    and not self._in_budget(actor, frames[i:]):
                if steady:
                    actor.dropped += 1
                else:  # arrived while the actor calibrated or caught up after it
                    actor.dropped_startup += 1
                actor.stream.push(frame.time, frame.samples, solve=False)  # bridging, stance
                continue
            cpu, start = time.thread_time(), self.clock()
            poses = actor.stream.push(frame.time, frame.samples)
            self._send(actor, poses, frame if steady else None)
            done = self.clock()
            if calibrated:  # not the calibration itself
                spent = done - start
                actor.solve_s = spent if not actor.solve_s else 0.9 * actor.solve_s + 0.1 * spent
            elif actor.stream.calibration is not None:
                actor.calibrated_at = done
                if self._frozen:  # the calibration's objects too
                    gc.freeze()
            if steady:
                actor.cpu_s.append(time.thread_time() - cpu)
            if actor.live_since is None and actor.calibrated_at is not None and poses and (
                    not self.paced or done - frame.first_arrival <= self.latency_budget_s
                    or frame.first_arrival > actor.calibrated_at):
                actor.live_since = done

    def _in_budget(self, actor: LiveActor, backlog: list[AssembledFrame]) -> bool:
        """Solving ``backlog[0]`` keeps it and the newest waiting frame within the budget.

        Each frame still to solve is expected to cost ``actor.solve_s``; the newest waiting
        frame leaves after all of them.
        """
        now, cost = self.clock(), actor.solve_s
        return (now + cost - backlog[0].first_arrival <= self.latency_budget_s
                and now + len(backlog) * cost - backlog[-1].first_arrival
                <= self.latency_budget_s)

    def _send(self, actor: LiveActor, poses: list[Any], frame: AssembledFrame | None) -> None:
        for pose in poses:
            values = actor.kinematics.values(pose.q)
            out = [actor.kinematics.actor_pose(pose, values, actor.name, actor.character_id,
                                               actor.frames)]
            for sink in self.sinks:
                try:
                    sink.send(out)
                except OSError as err:  # a network output down does not stop the stream
                    if len(self.sink_errors) < 10:
                        self.sink_errors.append(f"{type(sink).__name__}: {err}")
            if actor.recorder is not None:
                actor.recorder.add(pose, values)
            actor.frames += 1
            if frame is not None:
                actor.latency_s.append((frame.time, self.clock() - frame.first_arrival))

    def _show_status(self, now: float, force: bool = False) -> None:
        """One line on the terminal, rewritten at most 4 times a second."""
        if self.status is None or (now - self._status_at < 0.25 and not force):
            return
        self._status_at = now
        parts = [f"{a.name}: {a.frames} frames, {a.dropped} dropped, {a.stream.status()}"
                 for a in self.actors]
        line = " | ".join(parts)
        self.status.write("\r" + line[:200].ljust(80))
        self.status.flush()


def status_stream(quiet: bool) -> TextIO | None:
    """The terminal (stderr) for the status line, unless ``quiet``."""
    return None if quiet else sys.stderr
