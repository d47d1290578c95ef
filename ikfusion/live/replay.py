"""A recording or a simulated capture played back as a live source (``live --replay``).

:func:`recording_frames` turns an IMU recording into the samples a live source would have
delivered, frame by frame: one :class:`~ikfusion.live.samples.ImuSample` per received sample of a
mapped sensor (a lost packet delivers nothing; a sample flagged invalid delivers a NaN
orientation). ``solve --causal`` feeds exactly these to the same
:class:`~ikfusion.live.actor_stream.ActorStream`. :class:`ReplaySource` plays them, with the
TOAs of a UWB log, at the capture's own pace (``speed`` times faster; 0: as fast as possible).
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..io.recording import ImuRecording, normalize_sensor_id
from ..rotations import matrix_to_quat_wxyz
from .samples import ImuSample, Sample, ToaSample

if TYPE_CHECKING:  # the UWB package is loaded only by a solve that reads TOAs
    from ..uwb.toa_log import ToaLog


def recording_frames(recording: ImuRecording, sensor_map: Mapping[str, str],
                     actor: str | None = None) -> Iterator[tuple[float, dict[str, ImuSample]]]:
    """(time [s], sensor id -> sample) for every frame where a mapped sensor delivered one.

    ``actor`` names the actor in every sample (a replayed session).
    """
    wanted = {normalize_sensor_id(s) for s in sensor_map}
    streams = {sid: st for sid, st in recording.sensors.items()
               if normalize_sensor_id(sid) in wanted}
    quats = {sid: matrix_to_quat_wxyz(np.nan_to_num(st.R_world_sensor)) for sid, st in
             streams.items()}
    for k, t in enumerate(recording.time):
        samples = {}
        for sid, st in streams.items():
            if not st.received[k]:
                continue
            valid = bool(st.valid[k])
            counter = None if st.packet_counter is None else int(st.packet_counter[k]) % 65536
            samples[sid] = ImuSample(
                sid, float(t), quats[sid][k] if valid else np.full(4, np.nan),
                acc=None if st.acc is None or not valid else st.acc[k],
                gyr=None if st.gyr is None or not valid else st.gyr[k], counter=counter,
                actor=actor)
        if samples:
            yield float(t), samples


def recording_samples(recording: ImuRecording, sensor_map: Mapping[str, str],
                      actor: str | None = None) -> Iterator[ImuSample]:
    """The samples of :func:`recording_frames` one by one, in time order."""
    for _, samples in recording_frames(recording, sensor_map, actor):
        yield from samples.values()


def toa_samples(log: ToaLog) -> Iterator[ToaSample]:
    """The rows of a TOA log as samples, in the log's order."""
    for i in range(len(log.time)):
        yield ToaSample(float(log.time[i]), str(log.tag[i]), int(log.seq[i]),
                        str(log.reader[i]), float(log.toa[i]))


def merged(streams: Sequence[Iterator[Sample]]) -> Iterator[Sample]:
    """Samples of several time-ordered streams in one time order (ties: stream order)."""
    return heapq.merge(*streams, key=lambda s: s.time_s)


@dataclass
class ReplaySource:
    """Samples played back at the capture's pace (a :class:`~ikfusion.live.samples.SampleSource`).

    Args:
        streams: Time-ordered sample streams (one per actor, the TOA log).
        speed: Playback speed (1: real time; 0: as fast as possible).
        clock: Wall clock [s] (``time.perf_counter``); ``sleep`` waits [s].
    """

    streams: Sequence[Iterator[Sample]]
    speed: float = 1.0
    clock: Callable[[], float] = time.perf_counter
    sleep: Callable[[float], None] = time.sleep

    def samples(self) -> Iterator[Sample]:
        """Each sample once its capture time is due (capture time / speed after the start)."""
        start: tuple[float, float] | None = None  # wall, capture time of the first sample
        for sample in merged(self.streams):
            if self.speed > 0:
                if start is None:
                    start = (self.clock(), sample.time_s)
                due = start[0] + (sample.time_s - start[1]) / self.speed
                wait = due - self.clock()
                if wait > 0:
                    self.sleep(wait)
            yield sample

    def close(self) -> None:
        """Nothing to release."""
