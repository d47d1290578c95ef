"""Reading and writing recordings: MT Manager exports, generic IMU CSV, MVNX, sensor maps, BVH.

Every IMU reader returns an :class:`ImuRecording`: one time base, one :class:`SensorStream` per
sensor with ``R_world_sensor`` in the ENU world and a per-sample validity mask.
"""

from .bvh import BvhMotion, BvhSkeleton, guess_bvh_scale, read_bvh, write_bvh
from .imu_csv import read_imu_csv
from .mtmanager import MtManagerFile, read_mtmanager, read_mtmanager_file, trial_files
from .mtmanager_writer import write_mtmanager
from .mvnx import MvnxRecording, read_mvnx
from .reader import read_imu
from .recording import ImuRecording, SensorStream, check_sensor_ids, normalize_sensor_id
from .sensor_map import SensorMap, check_sensors, load_sensor_map

__all__ = [
    "BvhMotion",
    "BvhSkeleton",
    "ImuRecording",
    "MtManagerFile",
    "MvnxRecording",
    "SensorMap",
    "SensorStream",
    "check_sensor_ids",
    "check_sensors",
    "guess_bvh_scale",
    "load_sensor_map",
    "normalize_sensor_id",
    "read_bvh",
    "read_imu",
    "read_imu_csv",
    "read_mtmanager",
    "read_mtmanager_file",
    "read_mvnx",
    "trial_files",
    "write_bvh",
    "write_mtmanager",
]
