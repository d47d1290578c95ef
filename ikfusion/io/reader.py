"""One entry point for IMU recordings of any supported format."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from .imu_csv import read_imu_csv
from .mtmanager import read_mtmanager
from .mvnx import read_mvnx
from .recording import ImuRecording, check_sensor_ids


def read_imu(path: str | Path, rate: float | None = None,
             sensor_map: Mapping[str, str] | None = None) -> ImuRecording:
    """Read an IMU recording: MT Manager exports, a generic IMU CSV or an MVNX file.

    ``*.mvnx`` is read with :func:`ikfusion.io.read_mvnx` (its sensor orientations, sensor ids =
    segment labels), ``*.csv`` with :func:`ikfusion.io.read_imu_csv`, anything else (a trial
    prefix, a folder, one ``.txt`` export) with :func:`ikfusion.io.read_mtmanager`.

    Args:
        path: The recording.
        rate: Sample rate [Hz] when the files do not say it.
        sensor_map: Sensor id -> segment, checked against the recording.

    Raises:
        InputError: Bad input (naming file, line and column) or mapped sensors missing.
    """
    p = Path(path)
    suffix = p.suffix.lower() if p.is_file() else ""
    if suffix == ".mvnx":
        recording = read_mvnx(p).imu_recording()
    elif suffix == ".csv":
        recording = read_imu_csv(p, rate=rate)
    else:
        return read_mtmanager(p, rate=rate, sensor_map=sensor_map)
    if sensor_map is not None:
        recording.warnings += check_sensor_ids(sensor_map, recording.sensors, p)
    return recording
