"""IMU processing: still windows, the body heading from the data, sensor-to-segment calibration."""

from .calibration import (
    Calibration,
    calibrate,
    calibrate_recording,
    heading_from_axis,
    pose_rotation,
    tpose_arm_angles_deg,
)
from .heading import HeadingEstimate, heading_from_flexion, walking_heading, world_acceleration
from .still import StillThresholds, check_still, find_still_window, mean_rotation

__all__ = [
    "Calibration",
    "HeadingEstimate",
    "StillThresholds",
    "calibrate",
    "calibrate_recording",
    "check_still",
    "find_still_window",
    "heading_from_axis",
    "heading_from_flexion",
    "mean_rotation",
    "pose_rotation",
    "tpose_arm_angles_deg",
    "walking_heading",
    "world_acceleration",
]
