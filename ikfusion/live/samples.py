"""What live sources deliver: one sensor sample or one UWB time of arrival at a time."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class ImuSample:
    """One IMU sample as it arrives.

    Attributes:
        sensor: Sensor id, as in the sensor map (or the segment name for MVNX-like sources).
        time_s: Capture time of the sample [s] on the capture's timeline.
        q_world_sensor: (4,) orientation ``R_world_sensor`` as a quaternion (w, x, y, z);
            NaN when the sensor sent no valid orientation (a lost or flagged packet).
        acc: (3,) specific force in the sensor frame [m/s^2], or None.
        gyr: (3,) angular velocity in the sensor frame [rad/s], or None.
        counter: Packet counter of the sample when the source has one (16-bit, wraps), or None.
        actor: The actor wearing the sensor when the source says (a replayed session), else
            None (then the sensor id decides).
    """

    sensor: str
    time_s: float
    q_world_sensor: np.ndarray
    acc: np.ndarray | None = None
    gyr: np.ndarray | None = None
    counter: int | None = None
    actor: str | None = None


@dataclass(frozen=True)
class ToaSample:
    """One UWB time of arrival, the columns of a TOA CSV row (SPEC section 4).

    Attributes:
        time_s: Reception time on the common timeline [s].
        tag: Tag id.
        seq: Transmission number of that tag.
        reader: Reader id.
        toa_m: c x arrival time on the reader clock [m].
    """

    time_s: float
    tag: str
    seq: int
    reader: str
    toa_m: float


Sample = ImuSample | ToaSample


class SampleSource(Protocol):
    """A live source: yields samples in arrival order; ends when the stream ends."""

    def samples(self) -> Iterator[Sample]:
        """Samples as they arrive (blocking until the next one or the end)."""

    def close(self) -> None:
        """Release sockets and files."""
