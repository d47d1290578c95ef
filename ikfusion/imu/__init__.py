"""IMU processing: sensor-to-segment calibration."""

from .calibration import Calibration, calibrate, find_still_window, mean_rotation

__all__ = ["Calibration", "calibrate", "find_still_window", "mean_rotation"]
