"""The residual report of a solved pose: how far it is from its frame's targets."""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from .configuration import Configuration
from .frame_problem import FrameTasks


def residual_source(model: pin.Model, tasks: FrameTasks, R_sensed: np.ndarray,
                    q: np.ndarray) -> Callable[[], dict[str, dict[str, float]]]:
    """The residuals of the pose ``q`` against this frame's targets, computed on demand.

    The tasks replace (never modify) their target arrays, so keeping the arrays of this frame
    keeps its targets.

    Args:
        model: The Pinocchio model.
        tasks: The solver's tasks, with this frame's targets.
        R_sensed: (n, 3, 3) this frame's sensed orientation targets (the residual is reported
            against the sensors, not against eased targets).
        q: The solved configuration.

    Returns:
        A function returning ``orientation_deg`` (per segment), ``position_m`` (per site) and
        ``contact_slide_m`` (per planted point).
    """
    orientation, position, contact = tasks.orientation, tasks.position, tasks.contact
    targets = (R_sensed, orientation.weights, position.targets, position.information,
               contact.active, contact.anchors, contact.free_z)
    names = contact.names

    def residuals() -> dict[str, dict[str, float]]:
        R, w, p, info, active, anchors, free_z = targets
        o, pos = copy.copy(orientation), copy.copy(position)
        o.targets, o.weights, pos.targets, pos.information = R, w, p, info
        held = copy.copy(contact)
        held.set_anchors(active, anchors, free_z)
        conf = Configuration(model, q)
        slide = held.slide_m(conf)
        return {
            "orientation_deg": o.errors_deg(conf),
            "position_m": pos.errors_m(conf),
            "contact_slide_m": {n: float(d) for n, d in zip(names, slide) if np.isfinite(d)},
        }

    return residuals
