"""One entry point for IMU recordings of any supported format."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from .imu_csv import read_imu_csv
from .mtmanager import read_mtmanager
from .mvnx import read_mvnx
from .recording import ImuRecording, check_sensor_ids

_SNIFF_BYTES = 4096


def _looks_like_mtmanager(path: Path) -> bool:
    """Whether a file starts like an MT Manager export (``//`` comments or a PacketCounter)."""
    try:
        with path.open("rb") as f:
            head = f.read(_SNIFF_BYTES).decode("latin-1").lstrip("\ufeff\xef\xbb\xbf \t\r\n")
    except OSError:
        return False
    return head.startswith("//") or head.lower().startswith("packetcounter")


def read_imu(path: str | Path, rate: float | None = None,
             sensor_map: Mapping[str, str] | None = None, *,
             require_rate: bool = True) -> ImuRecording:
    """Read an IMU recording: MT Manager exports, a generic IMU CSV or an MVNX file.

    ``*.mvnx`` is read with :func:`ikfusion.io.read_mvnx` (its sensor orientations, sensor ids =
    segment labels), ``*.csv`` with :func:`ikfusion.io.read_imu_csv` unless it starts like an MT
    Manager export (``//`` comment lines or a PacketCounter header), anything else (a trial
    prefix, a folder, one ``.txt`` export) with :func:`ikfusion.io.read_mtmanager`.

    Args:
        path: The recording.
        rate: Sample rate [Hz] when the files do not say it.
        sensor_map: Sensor id -> segment, checked against the recording.
        require_rate: When False, MT Manager exports whose rate nothing tells are read with a
            NaN rate (``rate_source == "unknown"``) instead of raising.

    Raises:
        InputError: Bad input (naming file, line and column) or mapped sensors missing.
    """
    p = Path(path)
    suffix = p.suffix.lower() if p.is_file() else ""
    if suffix == ".mvnx":
        recording = read_mvnx(p).imu_recording()
        recording.rate_source = recording.rate_source or "frameRate"
    elif suffix == ".csv" and not _looks_like_mtmanager(p):
        recording = read_imu_csv(p, rate=rate)
    else:
        return read_mtmanager(p, rate=rate, sensor_map=sensor_map, require_rate=require_rate)
    if sensor_map is not None:
        recording.warnings += check_sensor_ids(sensor_map, recording.sensors, p)
    return recording
