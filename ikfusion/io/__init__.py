"""Reading and writing recordings: MT Manager exports, sensor maps, BVH."""

from .bvh import BvhMotion, BvhSkeleton, guess_bvh_scale, read_bvh, write_bvh
from .mtmanager import ImuRecording, SensorStream, read_mtmanager, read_mtmanager_file
from .mtmanager_writer import write_mtmanager
from .sensor_map import check_sensors, load_sensor_map

__all__ = [
    "BvhMotion",
    "BvhSkeleton",
    "ImuRecording",
    "SensorStream",
    "check_sensors",
    "guess_bvh_scale",
    "load_sensor_map",
    "read_bvh",
    "read_mtmanager",
    "read_mtmanager_file",
    "write_bvh",
    "write_mtmanager",
]
