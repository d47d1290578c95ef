"""Rest of a hand, a knee or the trunk from its IMU: the sensor barely accelerates while down.

A palm or a knee on the floor is a pivot: its segment may turn about it at a rad/s or more (a
crawling shin, a hand under a cartwheel) while the point itself stays put, so the gyroscope says
little. The sensor, a few centimetres from the pivot, then feels almost no acceleration
(``|omega|^2 r`` is a few tenths of m/s^2), whereas a hand or a knee that moves through the air
accelerates by metres per second squared. A segment is therefore *resting* where its world
acceleration (gravity removed, :func:`ikfusion.imu.flight.world_acceleration`) stays below a
threshold for a minimum duration. A slide at constant speed would pass; on a floor it does not
happen. The same holds for a body lying or sitting on the floor: its pelvis and upper trunk
rest, and so do they while it stands still, whence the contacts plant a
resting point only where it is also the lowest (:func:`ikfusion.ik.contacts.release_contacts`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .stance import _bridge_short_gaps, _drop_short_runs, _running_max

#: Segments whose contact points rest on the floor while their sensor is calm: knees, palms,
#: and where a lying or sitting body rests: the pelvis (sacrum, buttocks), the upper trunk (T8:
#: shoulder blades, chest).
RESTING_SEGMENTS = ("LeftLowerLeg", "RightLowerLeg", "LeftHand", "RightHand", "Pelvis", "T8")


@dataclass(frozen=True)
class RestThresholds:
    """What a resting hand or knee means.

    Attributes:
        max_acc: World acceleration below which the segment may rest [m/s^2].
        min_duration: Shortest resting stretch that counts [s].
        window: Width of the running maximum taken over the acceleration [s].
    """

    max_acc: float = 1.0
    min_duration: float = 0.1
    window: float = 0.05


def segment_resting(a_world: np.ndarray, rate: float,
                    thresholds: RestThresholds | None = None) -> np.ndarray:
    """Where a hand or knee IMU says its contact point rests (offline: looks ahead).

    Args:
        a_world: (N, 3) the sensor's acceleration in the world frame, gravity removed
            [m/s^2] (NaN where missing).
        rate: Sample rate [Hz].
        thresholds: What resting means.

    Returns:
        (N,) 1.0 resting, 0.0 moving, NaN unknown. Lost samples are bridged as in
        :func:`ikfusion.imu.stance.foot_still`.
    """
    th = thresholds or RestThresholds()
    min_length = max(1, int(round(th.min_duration * rate)))
    width = max(1, int(round(th.window * rate)))
    size = np.linalg.norm(np.asarray(a_world, dtype=float), axis=1)
    calm = _running_max(_bridge_short_gaps(size, min_length), width) < th.max_acc
    out = _drop_short_runs(calm, min_length).astype(float)
    out[~np.isfinite(size)] = np.nan
    return out
