"""Samples as they arrive grouped into frames, never waiting long for a late or lost one.

A frame gathers the samples whose times are within half a sample period of each other. It is
*complete* when every expected sensor has delivered, or on its deadline: when a sample
``deadline_periods`` sample periods later has arrived (capture time, so a replay decides the same
way however fast it runs), or, live, when that long has passed on the wall clock since its first
sample arrived. Frames leave in time order. A sample for a frame already gone is *late* and
dropped (counted); a second sample of a sensor for the same frame is a *duplicate* (dropped,
counted). A sensor whose clock jumps (its time more than ``clock_jump_s`` away from the stream's
newest frame) is shifted back onto the stream's time (counted), so the frames go on.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable
from dataclasses import dataclass, field

from ..io.recording import normalize_sensor_id
from .samples import ImuSample


@dataclass(frozen=True)
class AssembledFrame:
    """One frame released by the assembler.

    Attributes:
        time: Frame time [s] on the stream's time (clock jumps taken out).
        samples: Sensor id -> sample (the missing sensors are absent).
        first_arrival: Wall time [s] its first sample arrived.
        released: Wall time [s] it was released (arrival of the sample that completed it or
            made it due, or the poll that found it due; NaN at the end of the stream).
        complete: Every expected sensor delivered.
    """

    time: float
    samples: dict[str, ImuSample]
    first_arrival: float
    released: float
    complete: bool


@dataclass
class _Pending:
    time: float
    samples: dict[str, ImuSample]
    first_arrival: float


@dataclass
class FrameCounters:
    """What the assembler dropped or decided on a deadline.

    Attributes:
        frames: Frames released.
        on_deadline: Frames released incomplete (a sensor missing) on their deadline.
        late: Samples dropped because their frame had already gone.
        duplicates: Second samples of one sensor for one frame, dropped.
        clock_jumps: Sensor clock jumps taken back onto the stream's time.
        missing: Sensor id -> frames released without it.
    """

    frames: int = 0
    on_deadline: int = 0
    late: int = 0
    duplicates: int = 0
    clock_jumps: int = 0
    missing: dict[str, int] = field(default_factory=dict)


class FrameAssembler:
    """Groups one actor's samples into frames (see the module docstring).

    Args:
        sensors: The sensor ids a complete frame holds.
        rate: Nominal sample rate [Hz].
        deadline_periods: Deadline after a frame's time, in sample periods.
        clock_jump_s: A sensor this far from the stream's newest frame has jumped [s].
        wall_deadline_s: Also release a frame this long after its first sample arrived [s]
            of wall time (live); None decides on capture time only (a replay as fast as
            possible).
    """

    def __init__(self, sensors: Iterable[str], rate: float, deadline_periods: float = 1.5,
                 clock_jump_s: float = 1.0, wall_deadline_s: float | None = None) -> None:
        self.sensors = {normalize_sensor_id(s) for s in sensors}
        self.period = 1.0 / rate
        self.deadline_s = deadline_periods * self.period
        self.clock_jump_s = clock_jump_s
        self.wall_deadline_s = wall_deadline_s
        self.counters = FrameCounters()
        self._pending: list[_Pending] = []
        self._offset: dict[str, float] = {}
        self._ids: dict[str, str] = {}  # sensor id as sent -> normalised
        self._last: float | None = None   # time of the last frame released
        self._newest: float | None = None  # newest sample time seen

    def add(self, sample: ImuSample, now: float) -> list[AssembledFrame]:
        """Take one sample arrived at wall time ``now`` [s]; the frames complete now."""
        sensor = self._ids.get(sample.sensor)
        if sensor is None:
            sensor = self._ids[sample.sensor] = normalize_sensor_id(sample.sensor)
        if sensor not in self.sensors:
            return []
        t = sample.time_s + self._offset.get(sensor, 0.0)
        reference = self._newest if self._newest is not None else self._last
        if reference is not None and abs(t - reference) > self.clock_jump_s:
            self._offset[sensor] = self._offset.get(sensor, 0.0) + reference - t
            t = reference
            self.counters.clock_jumps += 1
        half = 0.5 * self.period
        if self._last is not None and t < self._last + half:
            self.counters.late += 1
            return self._release(now)
        times = [p.time for p in self._pending]
        i = bisect.bisect_left(times, t - half)
        if i < len(self._pending) and abs(self._pending[i].time - t) < half:
            frame = self._pending[i]
            if sensor in frame.samples:
                self.counters.duplicates += 1
            else:
                frame.samples[sensor] = sample
        else:
            self._pending.insert(i, _Pending(t, {sensor: sample}, now))
        self._newest = t if self._newest is None else max(self._newest, t)
        return self._release(now)

    def poll(self, now: float) -> list[AssembledFrame]:
        """The frames whose wall-clock deadline has passed at ``now`` [s] (live)."""
        return self._release(now)

    def flush(self) -> list[AssembledFrame]:
        """Every pending frame (the stream ended)."""
        return self._release(None)

    def _release(self, now: float | None) -> list[AssembledFrame]:
        out: list[AssembledFrame] = []
        while self._pending:
            frame = self._pending[0]
            complete = len(frame.samples) == len(self.sensors)
            due = self._newest is not None and self._newest - frame.time >= \
                self.deadline_s - 1e-9
            late = self.wall_deadline_s is not None and now is not None and \
                now - frame.first_arrival >= self.wall_deadline_s
            if not (complete or due or late or now is None):
                break
            self._pending.pop(0)
            self._last = frame.time
            self.counters.frames += 1
            if not complete:
                self.counters.on_deadline += 1
                for s in self.sensors - set(frame.samples):
                    self.counters.missing[s] = self.counters.missing.get(s, 0) + 1
            out.append(AssembledFrame(frame.time, {s.sensor: s for s in frame.samples.values()},
                                      frame.first_arrival,
                                      float("nan") if now is None else now, complete))
        return out
