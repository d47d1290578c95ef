"""IMU recordings in memory: every sensor of a trial on one common time base.

Whatever the file format (MT Manager exports, the generic IMU CSV, MVNX), a reader returns an
:class:`ImuRecording`: ``time`` (N,) [s] from 0, the ``rate`` [Hz] and one
:class:`SensorStream` per sensor id, each with ``R_world_sensor`` (N, 3, 3) in the ENU world
(x East, y North, z Up) and a per-sample ``valid`` mask. A sample that was not received (a lost
packet) keeps an orientation interpolated by slerp between its received neighbours but is flagged
invalid; samples before a sensor's first or after its last packet are NaN and invalid.
:meth:`ImuRecording.segment_streams` views the recording through a sensor map.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..rotations import matrix_to_quat_wxyz, quat_wxyz_to_matrix, slerp

#: Channel attributes of a :class:`SensorStream` that hold (N, 3) vectors.
VECTOR_CHANNELS: tuple[str, ...] = ("acc", "free_acc", "gyr", "mag")


@dataclass
class SensorStream:
    """One sensor on the recording's common time base (N samples).

    Attributes:
        sensor_id: Device id (8 hex digits for Xsens, e.g. ``00B421E6``) or the vendor's label.
        R_world_sensor: (N, 3, 3) orientation, ENU world; slerp-filled inside gaps (flagged
            invalid there), NaN outside the sensor's span.
        valid: (N,) True where the sample was received and every data channel it carries
            (orientation, acc, free acc, gyr, mag) is finite (a vector component that is NaN in
            every row, an absent column, does not count).
        received: (N,) True where a row of the file landed on that sample.
        acc: (N, 3) specific force in the sensor frame [m/s^2], or None.
        free_acc: (N, 3) acceleration without gravity in the ENU world frame [m/s^2], or None.
        gyr: (N, 3) angular rate in the sensor frame [rad/s], or None.
        mag: (N, 3) magnetic field in the sensor frame [a.u.], or None.
        rows: Samples received (data rows of the file).
        lost: Packets missing inside the sensor's PacketCounter span (first to last received).
        gaps: (k, 2) int array: first missing sample index and number of missing samples of
            every gap inside the span.
        channels: Column names found in the file (in file order).
        packet_counter: (N,) unwrapped PacketCounter of every sample of the time base (the same
            counter epoch for every sensor of the trial), or None when the format has none.
        orientation_source: Columns the orientation came from (``"Quat"``, ``"Mat"``,
            ``"Euler"``, a mix such as ``"Quat+Euler"`` when rows fell back, or ``""``).
        path: The file the stream was read from.
    """

    sensor_id: str
    R_world_sensor: np.ndarray
    valid: np.ndarray
    received: np.ndarray
    acc: np.ndarray | None = None
    free_acc: np.ndarray | None = None
    gyr: np.ndarray | None = None
    mag: np.ndarray | None = None
    rows: int = 0
    lost: int = 0
    gaps: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    channels: list[str] = field(default_factory=list)
    packet_counter: np.ndarray | None = None
    orientation_source: str = ""
    path: Path | None = None

    def __len__(self) -> int:
        return len(self.valid)

    @property
    def has_orientation(self) -> bool:
        """Whether any sample holds a finite orientation."""
        return bool(np.isfinite(self.R_world_sensor[self.received]).all(axis=(1, 2)).any())

    @property
    def orientation_valid(self) -> np.ndarray:
        """(N,) True where the orientation itself was received and finite.

        Looser than :attr:`valid`: a sample whose magnetometer field is NaN still has a usable
        orientation.
        """
        return self.received & np.isfinite(self.R_world_sensor).all(axis=(1, 2))

    @property
    def span(self) -> tuple[int, int]:
        """(first, last + 1) sample indices of the received samples, (0, 0) when none."""
        idx = np.flatnonzero(self.received)
        return (int(idx[0]), int(idx[-1]) + 1) if len(idx) else (0, 0)

    def quat_wxyz(self, index: int) -> np.ndarray:
        """Orientation of sample ``index`` as a unit quaternion (w, x, y, z), ``w >= 0``."""
        return matrix_to_quat_wxyz(self.R_world_sensor[index])


@dataclass
class ImuRecording:
    """A trial: every sensor on one common time base.

    Attributes:
        time: (N,) sample times [s], starting at 0 with the trial's first sample (NaN when the
            rate is unknown).
        rate: Sample rate [Hz]; NaN only when a reader was asked to read without a rate and
            nothing told it (``rate_source == "unknown"``).
        sensors: Sensor id -> :class:`SensorStream`.
        coordinate_system: World frame of every orientation and world vector: always ``"ENU"``
            after reading.
        source_coordinate_system: What the files declared (``"ENU"``, ``"NED"``, ``"NWU"``, or
            several joined by ``/``).
        source: The files read.
        warnings: Messages for the user (lost packets, late sensors, fallbacks, ...).
        rate_source: Where the rate came from: ``"Update Rate"`` (the ``// Update Rate:``
            line), ``"SampleTimeFine"``, ``"UTC"`` (the files' time columns), ``"--rate"``
            (given by the user), ``"time"`` (a CSV's time column), ``"frameRate"`` (MVNX) or
            ``"unknown"``.
    """

    time: np.ndarray
    rate: float
    sensors: dict[str, SensorStream]
    coordinate_system: str = "ENU"
    source_coordinate_system: str = "ENU"
    source: list[Path] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    rate_source: str = ""

    def __len__(self) -> int:
        return len(self.time)

    @property
    def rate_known(self) -> bool:
        """Whether the rate is a number (False only for recordings read without a rate)."""
        return bool(np.isfinite(self.rate))

    @property
    def sensor_ids(self) -> list[str]:
        """The sensor ids in reading order."""
        return list(self.sensors)

    @property
    def duration(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.time[-1]) if len(self.time) else 0.0

    def check_sensor_map(self, sensor_map: Mapping[str, str]) -> list[str]:
        """Check that every mapped sensor was recorded.

        Args:
            sensor_map: Sensor id -> segment.

        Returns:
            Warnings about recorded sensors the map does not use.

        Raises:
            InputError: Listing the mapped ids that are missing and the ids found.
        """
        return check_sensor_ids(sensor_map, self.sensors, self.source[0] if self.source else None)

    def segment_streams(self, sensor_map: Mapping[str, str]) -> dict[str, SensorStream]:
        """The recording seen through a sensor map: segment -> its sensor's stream.

        Args:
            sensor_map: Sensor id -> segment (e.g. from :func:`ikfusion.io.load_sensor_map`).

        Raises:
            InputError: A mapped sensor is not in the recording (listing missing and found ids).
        """
        self.check_sensor_map(sensor_map)
        lookup = {normalize_sensor_id(s): s for s in self.sensors}
        return {segment: self.sensors[lookup[normalize_sensor_id(sid)]]
                for sid, segment in sensor_map.items()}

    def R_world_sensor_by_segment(self, sensor_map: Mapping[str, str]) -> dict[str, np.ndarray]:
        """Segment -> ``R_world_sensor`` (N, 3, 3) of the sensor mapped to it."""
        return {s: st.R_world_sensor for s, st in self.segment_streams(sensor_map).items()}


def normalize_sensor_id(sensor_id: object) -> str:
    """Xsens ids (8 hex digits) in upper case; any other label unchanged (stripped)."""
    text = str(sensor_id).strip()
    if len(text) == 8 and all(c in "0123456789abcdefABCDEF" for c in text):
        return text.upper()
    return text


def check_sensor_ids(sensor_map: Mapping[str, str], found: Iterable[str],
                     source: str | Path | None = None) -> list[str]:
    """Check that every mapped sensor id was recorded.

    Args:
        sensor_map: Sensor id -> segment.
        found: The sensor ids of the recording.
        source: The recording's path, for the message.

    Returns:
        Warnings about recorded sensors that the map does not use.

    Raises:
        InputError: Listing the missing ids and the ids found.
    """
    ids = [normalize_sensor_id(f) for f in found]
    wanted = {normalize_sensor_id(s): seg for s, seg in sensor_map.items()}
    missing = [s for s in wanted if s not in ids]
    if missing:
        listed = ", ".join(f"{s} ({wanted[s]})" for s in missing)
        map_file = getattr(sensor_map, "path", None)
        named = f" {map_file}" if map_file is not None else ""
        raise InputError(f"the sensors {listed} of the sensor map{named} are not in the "
                         f"recording; sensors found: {', '.join(ids) or 'none'}", path=source,
                         field="sensors")
    return [f"sensor {s} is in the recording but not in the sensor map (not used)"
            for s in ids if s not in wanted]


def find_gaps(received: np.ndarray) -> np.ndarray:
    """Gaps inside the span of received samples.

    Args:
        received: (N,) bool.

    Returns:
        (k, 2) int64: first missing index and length of each gap.
    """
    idx = np.flatnonzero(received)
    if len(idx) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    step = np.diff(idx)
    where = np.flatnonzero(step > 1)
    return np.column_stack([idx[where] + 1, step[where] - 1]).astype(np.int64)


def fill_orientation_gaps(R_world_sensor: np.ndarray, good: np.ndarray,
                          fill: np.ndarray | None = None) -> None:
    """Slerp the orientation in place between the nearest good samples on either side.

    Args:
        R_world_sensor: (N, 3, 3), modified in place inside the span of ``good``.
        good: (N,) True where the orientation is trusted.
        fill: (N,) True where a sample may be filled (default: every sample that is not good).
            Readers pass the samples that were not received, so a NaN that the file holds stays
            NaN.
    """
    idx = np.flatnonzero(good)
    if len(idx) < 2:
        return
    inside = np.zeros(len(good), dtype=bool)
    inside[idx[0]:idx[-1] + 1] = True
    candidates = inside & ~good
    if fill is not None:
        candidates &= fill
    missing = np.flatnonzero(candidates)
    if not len(missing):
        return
    right = np.searchsorted(idx, missing)
    k0, k1 = idx[right - 1], idx[right]
    t = (missing - k0) / (k1 - k0)
    q0 = matrix_to_quat_wxyz(R_world_sensor[k0])
    q1 = matrix_to_quat_wxyz(R_world_sensor[k1])
    R_world_sensor[missing] = quat_wxyz_to_matrix(slerp(q0, q1, t))


def gap_summary(sensor_id: str, gaps: np.ndarray, rate: float) -> str | None:
    """One warning line about the lost packets of a sensor, or None without gaps."""
    if not len(gaps):
        return None
    lost = int(gaps[:, 1].sum())
    longest = int(np.argmax(gaps[:, 1]))
    first, length = gaps[longest]
    at = f"{first / rate:.2f} s" if np.isfinite(rate) else f"sample {first}"
    return (f"sensor {sensor_id}: {lost} lost packet{'s' if lost > 1 else ''} in {len(gaps)} "
            f"gap{'s' if len(gaps) > 1 else ''} (longest {length} at {at}); "
            "orientations inside gaps are slerp-filled and flagged invalid")


def place(values: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    """Rows of ``values`` at sample ``index`` of an (n, ...) array of NaN."""
    out = np.full((n,) + values.shape[1:], np.nan)
    out[index] = values
    return out


def build_stream(sensor_id: str, index: np.ndarray, n: int, R_world_sensor: np.ndarray,
                 vectors: Mapping[str, np.ndarray | None], *, rows: int, channels: list[str],
                 packet_counter: np.ndarray | None = None, orientation_source: str = "",
                 path: Path | None = None) -> SensorStream:
    """Place one sensor's received rows on the time base and fill its gaps.

    Args:
        sensor_id: The sensor.
        index: (r,) distinct sample indices of the received rows on the time base.
        n: Samples of the time base.
        R_world_sensor: (r, 3, 3) orientations of the received rows (NaN where absent).
        vectors: ``acc``/``free_acc``/``gyr``/``mag`` -> (r, 3) or None.
        rows: Data rows of the file.
        channels: Column names.
        packet_counter: (n,) unwrapped counter of the time base, or None.
        orientation_source: Which columns gave the orientation.
        path: The file.
    """
    received = np.zeros(n, dtype=bool)
    received[index] = True
    R = place(R_world_sensor, index, n)
    placed = {k: None if v is None else place(v, index, n) for k, v in vectors.items()}
    valid = received & np.isfinite(R).all(axis=(1, 2))
    for v in placed.values():
        if v is not None:  # components NaN in every received row (absent columns) do not count
            used = np.isfinite(v[received]).any(axis=0)
            valid &= np.isfinite(v[:, used]).all(axis=1)
    good_orientation = received & np.isfinite(R).all(axis=(1, 2))
    fill_orientation_gaps(R, good_orientation, fill=~received)
    gaps = find_gaps(received)
    return SensorStream(
        sensor_id=sensor_id, R_world_sensor=R, valid=valid, received=received,
        acc=placed.get("acc"), free_acc=placed.get("free_acc"), gyr=placed.get("gyr"),
        mag=placed.get("mag"), rows=rows, lost=int(gaps[:, 1].sum()) if len(gaps) else 0,
        gaps=gaps, channels=channels, packet_counter=packet_counter,
        orientation_source=orientation_source, path=path)
