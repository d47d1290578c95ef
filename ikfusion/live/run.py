"""The live loop: samples in, frames assembled, each actor solved causally, poses out.

A reader thread takes the samples from the source as they arrive and time-stamps their arrival;
the loop hands each IMU sample to its actor's :class:`~ikfusion.live.frames.FrameAssembler`
(routed by the sample's ``actor`` when the source names it, else by sensor id), solves every
released frame with the actor's :class:`~ikfusion.live.actor_stream.ActorStream`, and sends the
pose to every sink (one :class:`~ikfusion.live.actor_pose.ActorPose` per call, as soon as it is
solved) and to the actor's recorder. Nothing waits for a missing sample: frames are released on
their deadline, also when the source goes quiet.

When the solver falls behind a paced source (``max_lag_s`` of ``configs/live.yaml``), frames
released (complete or due) more than that long ago when their turn comes are dropped (not
solved, counted; their samples still feed the bridging and the stance) once the actor is
calibrated; those that arrived while it calibrated are counted apart. An unpaced replay
(``--speed 0``) drops nothing, so it gives the poses of ``solve --causal`` exactly. A paced
stream does not solve the frames of its start-up buffer (only the last one: the stream starts
at once instead of catching up; ``ActorStream(solve_startup=False)``), so its ``--record``
starts at the end of the calibration.
"""

from __future__ import annotations

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
            frames that arrived after the start-up buffer was solved.
        live_since: Wall time [s] the start-up buffer was solved (None before).
        cpu_s: CPU time [s] of the loop's thread per frame of ``latency_s`` (solve, outputs):
            what the latency would be on an idle machine, less the waiting.
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
    cpu_s: list[float] = field(default_factory=list)

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
        max_lag_s: Frames released longer ago than this when their turn comes are dropped
            (paced only) [s].
        status: Where the one-line status goes (None: nowhere).
        clock: Wall clock [s].
    """

    actors: list[LiveActor]
    sinks: Sequence[PoseSink] = ()
    paced: bool = True
    max_lag_s: float = 0.012
    status: TextIO | None = None
    clock: Callable[[], float] = time.perf_counter
    toa_samples: int = 0
    sink_errors: list[str] = field(default_factory=list)
    _route: dict[str, LiveActor] = field(default_factory=dict)
    _status_at: float = 0.0

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
        reader.start()
        try:
            while True:
                try:
                    item = inbox.get(timeout=poll_s)
                except queue.Empty:
                    item = None
                if item is _END:
                    break
                if isinstance(item, BaseException):
                    raise item
                if item is not None:
                    self.take(*item)
                now = self.clock()
                if inbox.empty():  # wall deadlines only once every sample that arrived is in
                    for actor in self.actors:
                        self._solve(actor, actor.assembler.poll(now))
                self._show_status(now)
        finally:
            source.close()
        self.finish()

    def take(self, sample: Sample, arrived: float) -> None:
        """One sample arrived at wall time ``arrived`` [s]."""
        if not isinstance(sample, ImuSample):
            self.toa_samples += 1
            for each in self.actors:  # each actor's tag feed keeps its own tags
                each.stream.toa(sample)
            return
        actor = self._by_name.get(sample.actor) if sample.actor else self._route.get(
            normalize_sensor_id(sample.sensor))
        if actor is not None:
            self._solve(actor, actor.assembler.add(sample, arrived))

    def finish(self) -> None:
        """The stream ended: the pending frames and the start-up buffers solved."""
        for actor in self.actors:
            self._solve(actor, actor.assembler.flush())
            self._send(actor, actor.stream.finish(), None)
        if self.status is not None:
            self._show_status(self.clock(), force=True)
            self.status.write("\n")

    def _solve(self, actor: LiveActor, frames: list[AssembledFrame]) -> None:
        for frame in frames:
            now = self.clock()
            steady = actor.live_since is not None and frame.first_arrival > actor.live_since
            if (self.paced and actor.live_since is not None
                    and now - frame.released > self.max_lag_s):
                if steady:
                    actor.dropped += 1
                else:  # arrived while the start-up buffer was calibrated
                    actor.dropped_startup += 1
                actor.stream.push(frame.time, frame.samples, solve=False)  # bridging, stance
                continue
            cpu = time.thread_time()
            poses = actor.stream.push(frame.time, frame.samples)
            self._send(actor, poses, frame if steady else None)
            if steady:
                actor.cpu_s.append(time.thread_time() - cpu)
            if actor.live_since is None and actor.stream.calibration is not None and poses:
                actor.live_since = self.clock()

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
