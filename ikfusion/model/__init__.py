"""The human model: body dimensions, URDF generation, and the Pinocchio model with ball joints."""

from .ball_joints import BallJoint, merge_revolute_triplets
from .body import Body
from .human_model import HumanModel, SiteInfo
from .joints import ANGLE_NAMES, JOINTS, SEGMENTS, AngleSpec, JointSpec, load_joint_specs
from .layout import (
    BODY_CONTACT_SITES,
    CONTACT_SITES,
    SENSOR_SEGMENTS,
    TAG_SITES,
    TRUNK_CONTACT_SITES,
    BodyLayout,
    build_layout,
)
from .topology import BodyTopology, FootLayout, segment_parents
from .urdf import body_to_urdf, write_urdf

__all__ = [
    "ANGLE_NAMES",
    "BODY_CONTACT_SITES",
    "CONTACT_SITES",
    "JOINTS",
    "SEGMENTS",
    "SENSOR_SEGMENTS",
    "TAG_SITES",
    "TRUNK_CONTACT_SITES",
    "AngleSpec",
    "BallJoint",
    "Body",
    "BodyLayout",
    "BodyTopology",
    "HumanModel",
    "FootLayout",
    "JointSpec",
    "SiteInfo",
    "body_to_urdf",
    "build_layout",
    "load_joint_specs",
    "merge_revolute_triplets",
    "segment_parents",
    "write_urdf",
]
