"""IMU samples from Lab Streaming Layer inlets, mapped to sensors by a YAML file.

The map (``ikfusion live --lsl FILE``)::

    streams:
      - name: MTw 00B458EE      # the stream's name and/or its type (at least one)
        type: Orientation
        timeout: 5.0            # optional: seconds to wait for the stream to appear
        sensors:
          00B458EE:             # sensor id, as in the sensor map
            quat: [0, 1, 2, 3]  # channel indices of R_world_sensor as w, x, y, z
            acc: [4, 5, 6]      # optional: specific force, sensor frame [m/s^2]
            gyr: [7, 8, 9]      # optional: angular velocity, sensor frame [rad/s]
            counter: 10         # optional: packet counter channel

One stream may carry several sensors. Sample times are the LSL timestamps (synchronised to
this machine's clock) less the first one received, so the capture starts at 0 s. Anything
that does not hold is a :class:`~ikfusion.errors.ConfigError` naming the file, the line and the
field (``streams[0].sensors.00B458EE.quat``); a stream that cannot be found, or has fewer
channels than the map uses, is an :class:`~ikfusion.errors.InputError` naming the same.
Needs the ``live`` extra (``pylsl``).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, InputError
from ..io.sensor_map import _text_loader
from ..yaml_files import YamlDocument, read_yaml_document
from .lsl_outlet import require_pylsl
from .samples import ImuSample, Sample

_CHANNEL_KEYS = {"quat": 4, "acc": 3, "gyr": 3}


@dataclass(frozen=True)
class SensorChannels:
    """Where one sensor's values are in a stream's sample (channel indices)."""

    sensor: str
    quat: tuple[int, ...]
    acc: tuple[int, ...] | None = None
    gyr: tuple[int, ...] | None = None
    counter: int | None = None

    def highest(self) -> int:
        """The largest channel index used."""
        used = [*self.quat, *(self.acc or ()), *(self.gyr or ())]
        return max(used + ([] if self.counter is None else [self.counter]))


@dataclass(frozen=True)
class LslStreamMap:
    """One stream of the map: how to find it and its sensors.

    Attributes:
        field: The stream's place in the file (``streams[0]``), for messages.
        line: Its line in the file.
    """

    name: str | None
    type: str | None
    timeout_s: float
    sensors: tuple[SensorChannels, ...]
    field: str
    line: int | None


def _index(doc: YamlDocument, value: Any, field: str, keys: tuple[object, ...]) -> int:
    try:
        index = int(str(value))
    except ValueError:
        index = -1
    if index < 0:
        raise ConfigError(f"a channel index must be an integer >= 0, got {value!r}",
                          path=doc.path, line=doc.line_of(*keys), field=field)
    return index


def _channels(doc: YamlDocument, sensor: str, entry: Any, field: str,
              keys: tuple[object, ...]) -> SensorChannels:
    if not isinstance(entry, dict) or "quat" not in entry:
        raise ConfigError("each sensor needs at least 'quat: [w, x, y, z channel indices]'",
                          path=doc.path, line=doc.line_of(*keys), field=field)
    unknown = set(entry) - {*_CHANNEL_KEYS, "counter"}
    if unknown:
        raise ConfigError(f"unknown key(s) {sorted(unknown)}; expected quat, acc, gyr, counter",
                          path=doc.path, line=doc.line_of(*keys), field=field)
    found: dict[str, tuple[int, ...]] = {}
    for key, n in _CHANNEL_KEYS.items():
        if key not in entry:
            continue
        value = entry[key]
        if not isinstance(value, list) or len(value) != n:
            raise ConfigError(f"expected a list of {n} channel indices, got {value!r}",
                              path=doc.path, line=doc.line_of(*keys, key), field=f"{field}.{key}")
        found[key] = tuple(_index(doc, v, f"{field}.{key}", (*keys, key)) for v in value)
    counter = (None if "counter" not in entry else
               _index(doc, entry["counter"], f"{field}.counter", (*keys, "counter")))
    return SensorChannels(sensor, found["quat"], found.get("acc"), found.get("gyr"), counter)


def load_lsl_map(path: str | Path) -> list[LslStreamMap]:
    """The streams of an LSL map file (see the module docstring).

    Raises:
        ConfigError: The file does not hold, naming the file, line and field.
    """
    doc = read_yaml_document(path, "LSL map", loader=_text_loader())
    streams = doc.data.get("streams") if isinstance(doc.data, dict) else None
    if not isinstance(streams, list) or not streams:
        raise ConfigError("expected 'streams:' with a list of streams", path=doc.path,
                          line=doc.line_of("streams"), field="streams")
    out = []
    for i, stream in enumerate(streams):
        field = f"streams[{i}]"
        if not isinstance(stream, dict) or not (stream.get("name") or stream.get("type")):
            raise ConfigError("a stream needs a 'name' or a 'type'", path=doc.path,
                              line=doc.line_of("streams", i), field=field)
        sensors = stream.get("sensors")
        if not isinstance(sensors, dict) or not sensors:
            raise ConfigError("expected 'sensors:' mapping sensor ids to channels",
                              path=doc.path, line=doc.line_of("streams", i),
                              field=f"{field}.sensors")
        try:
            timeout = float(stream.get("timeout", 5.0))
        except ValueError:
            raise ConfigError(f"timeout must be a number of seconds, got {stream['timeout']!r}",
                              path=doc.path, line=doc.line_of("streams", i, "timeout"),
                              field=f"{field}.timeout") from None
        channels = tuple(
            _channels(doc, str(sensor), entry, f"{field}.sensors.{sensor}",
                      ("streams", i, "sensors", sensor))
            for sensor, entry in sensors.items())
        out.append(LslStreamMap(stream.get("name"), stream.get("type"), timeout, channels,
                                field, doc.line_of("streams", i)))
    return out


class LslSource:
    """A :class:`~ikfusion.live.samples.SampleSource` reading LSL inlets.

    The streams are resolved (and their inlets opened) when the source is made.

    Args:
        path: The LSL map file.
        idle_timeout_s: The stream ends after this long without a sample [s]; None: only
            :meth:`close` ends it.

    Raises:
        ConfigError: The map does not hold.
        InputError: A stream is not found or has too few channels; pylsl is missing.
    """

    def __init__(self, path: str | Path, idle_timeout_s: float | None = None) -> None:
        self.path = Path(path)
        self.streams = load_lsl_map(self.path)
        lsl = require_pylsl("--lsl")
        self.idle_timeout_s = idle_timeout_s
        self._inlets: list[tuple[LslStreamMap, Any]] = []
        for stream in self.streams:
            prop, value = ("name", stream.name) if stream.name else ("type", stream.type)
            found = [info for info in lsl.resolve_byprop(prop, value, timeout=stream.timeout_s)
                     if stream.type is None or info.type() == stream.type]
            if not found:
                raise InputError(f"no LSL stream with {prop} {value!r} found within "
                                 f"{stream.timeout_s:g} s (is its sender running?)",
                                 path=self.path, line=stream.line, field=stream.field)
            info = found[0]
            need = max(s.highest() for s in stream.sensors) + 1
            if info.channel_count() < need:
                raise InputError(f"stream {value!r} has {info.channel_count()} channels, the map "
                                 f"uses channel index {need - 1}", path=self.path,
                                 line=stream.line, field=stream.field)
            inlet = lsl.StreamInlet(info, processing_flags=lsl.proc_clocksync)
            inlet.open_stream(timeout=stream.timeout_s)
            self._inlets.append((stream, inlet))
        self._t0: float | None = None
        self._closed = False

    def _samples_of(self, stream: LslStreamMap, row: np.ndarray, stamp: float) -> list[Sample]:
        if self._t0 is None:
            self._t0 = stamp
        t = stamp - self._t0
        out: list[Sample] = []
        for s in stream.sensors:
            out.append(ImuSample(
                s.sensor, t, row[list(s.quat)],
                None if s.acc is None else row[list(s.acc)],
                None if s.gyr is None else row[list(s.gyr)],
                None if s.counter is None or not np.isfinite(row[s.counter])
                else int(row[s.counter]) & 0xFFFF))
        return out

    def samples(self) -> Iterator[Sample]:
        """Samples as they arrive (each round of the inlets in time order)."""
        idle_since = time.monotonic()
        while not self._closed:
            batch: list[Sample] = []
            for stream, inlet in self._inlets:
                rows, stamps = inlet.pull_chunk(timeout=0.0)
                for row, stamp in zip(rows, stamps):
                    batch += self._samples_of(stream, np.asarray(row, dtype=float), stamp)
            if batch:
                idle_since = time.monotonic()
                yield from sorted(batch, key=lambda s: s.time_s)
                continue
            if (self.idle_timeout_s is not None
                    and time.monotonic() - idle_since >= self.idle_timeout_s):
                return
            time.sleep(0.002)

    def close(self) -> None:
        """Close the inlets."""
        self._closed = True
        for _, inlet in self._inlets:
            inlet.close_stream()
