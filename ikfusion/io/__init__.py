"""Reading and writing recordings: MT Manager exports, sensor maps, BVH."""

from .bvh import BvhMotion, BvhSkeleton, guess_bvh_scale, read_bvh, write_bvh
from .imu_csv import read_imu_csv
from .mtmanager import ImuRecording, SensorStream, read_mtmanager, read_mtmanager_file
from .mtmanager_writer import write_mtmanager
from .mvnx import MvnxRecording, read_mvnx
from .sensor_map import check_sensors, load_sensor_map

__all__ = [
    "BvhMotion",
    "BvhSkeleton",
    "ImuRecording",
    "MvnxRecording",
    "SensorStream",
    "check_sensors",
    "guess_bvh_scale",
    "load_sensor_map",
    "read_bvh",
    "read_imu_csv",
    "read_mtmanager",
    "read_mtmanager_file",
    "read_mvnx",
    "write_bvh",
    "write_mtmanager",
]
