"""What a solve writes: the result folder of SPEC section 6 and the model's BVH export."""

from .bvh_export import model_skeleton, write_motion_bvh
from .folder import SEGMENT_COLUMNS, SITE_COLUMNS, write_result_folder

__all__ = [
    "SEGMENT_COLUMNS",
    "SITE_COLUMNS",
    "model_skeleton",
    "write_motion_bvh",
    "write_result_folder",
]
