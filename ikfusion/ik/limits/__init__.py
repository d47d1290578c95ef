"""Constraints of the IK step: ranges of motion, contacts, floor, velocity."""

from .base import Equality, Inequality
from .contact import ContactConstraint, FloorLimit
from .joint_range import JointRangeLimit
from .velocity import VelocityLimit

__all__ = [
    "ContactConstraint",
    "Equality",
    "FloorLimit",
    "Inequality",
    "JointRangeLimit",
    "VelocityLimit",
]
