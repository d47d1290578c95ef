"""What a solve writes: the result folder of SPEC section 6, the model's BVH and OpenSim exports."""

from .bvh_export import model_skeleton, write_motion_bvh
from .folder import SEGMENT_COLUMNS, SITE_COLUMNS, write_result_folder
from .opensim_export import write_motion_mot

__all__ = [
    "SEGMENT_COLUMNS",
    "SITE_COLUMNS",
    "model_skeleton",
    "write_motion_bvh",
    "write_motion_mot",
    "write_result_folder",
]
