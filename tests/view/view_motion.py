"""A short stepping motion of the default model, for the viewer tests."""

from __future__ import annotations

import numpy as np

from ikfusion.ik import Motion
from ikfusion.model import CONTACT_SITES, HumanModel

#: Frames and rate of the test motion: 2 s at 20 Hz.
FRAMES = 41
RATE = 20.0


def stepping_motion(model: HumanModel, frames: int = FRAMES, rate: float = RATE) -> Motion:
    """The body walks 1.2 m along +X, swinging legs and arms once per second.

    Contacts alternate: left foot down in the first half of each second, right in the second.
    """
    time = np.arange(frames) / rate
    phase = 2 * np.pi * time
    qs = []
    for t, a in zip(time, phase):
        swing = float(np.sin(a))
        angles = {
            "jRightHip_flex": 30 * swing, "jLeftHip_flex": -30 * swing,
            "jRightKnee_flex": 40 * max(swing, 0.0), "jLeftKnee_flex": 40 * max(-swing, 0.0),
            "jRightShoulder_flex": -40 * swing, "jLeftShoulder_flex": 40 * swing,
            "jRightElbow_flex": 30.0, "jLeftElbow_flex": 30.0,
        }
        qs.append(model.configuration(angles, p_world_pelvis=[0.6 * t, 0.0, 0.95]))
    left_down = (time % 1.0) < 0.5
    contacts = np.column_stack([left_down, left_down, ~left_down, ~left_down])
    n = len(time)
    return Motion(model, time, np.array(qs), list(CONTACT_SITES), contacts,
                  np.full(n, 2e-3), np.full(n, 3), np.zeros(n, dtype=bool), [])
