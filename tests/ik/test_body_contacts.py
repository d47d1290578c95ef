"""Contact points beyond the feet: knees and palms are planted and held like heels and toes."""

from __future__ import annotations

import numpy as np
from motions import frames_from

from ikfusion.ik import Solver
from ikfusion.mocap.model_motion import contact_phases, site_positions
from ikfusion.model import HumanModel


def kneeling_motion(model: HumanModel, seconds: float = 4.0, rate: float = 60.0) -> np.ndarray:
    """Kneeling upright on both knees, feet raised off the floor, swaying the trunk and hips.

    The knees stay where they are on the floor; the feet never come within 5 cm of it.
    """
    time = np.arange(int(seconds * rate)) / rate
    qs = []
    for t in time:
        sway = np.sin(2 * np.pi * 0.5 * t)
        angles = {"jLeftKnee_flex": 110.0, "jRightKnee_flex": 110.0,
                  "jLeftAnkle_flex": -60.0, "jRightAnkle_flex": -60.0,  # toes pointed back
                  "jLeftHip_flex": 15.0 * sway, "jRightHip_flex": 15.0 * sway,
                  "jL5S1_flex": 20.0 * (1 + sway), "jRightShoulder_flex": 40.0 * sway,
                  "jLeftShoulder_abd": 30.0 * (1 - sway)}
        qs.append(model.configuration(angles))
    q = np.array(qs)
    knee = site_positions(model, q, ["LeftKnee"])[:, 0]
    q[:, :3] -= knee - [0.0, knee[0, 1], 0.0]  # the left knee rests at (0, y, 0)
    return q


def test_kneeling_body_rests_on_its_knees(human: HumanModel) -> None:
    q = kneeling_motion(human)
    names = human.sites_of_kind("contact")
    truth_p = site_positions(human, q, names)
    truth_contacts = contact_phases(human, q, np.arange(len(q)) / 60.0, names)
    knees = [names.index("LeftKnee"), names.index("RightKnee")]
    feet = [names.index(n) for n in ("LeftHeel", "LeftToe", "RightHeel", "RightToe")]
    assert truth_contacts[:, knees].all() and not truth_contacts[:, feet].any()
    assert truth_p[:, feet, 2].min() > 0.05

    motion = Solver(human).solve(frames_from(human, q, stance=True))
    assert motion.contact_names == names
    assert motion.contacts[30:, knees].all()  # planted after the first half second
    p = site_positions(human, motion.q, names)
    # held without slip or sinking: the knees stay on the floor where they landed
    knee = p[30:, knees]
    assert np.ptp(knee[..., 0], axis=0).max() < 0.005
    assert np.ptp(knee[..., 1], axis=0).max() < 0.005
    assert np.abs(knee[..., 2]).max() < 0.01
    # the pelvis is carried by the knees: it keeps its height and does not wander
    err = motion.q[30:, :3] - q[30:, :3]
    assert np.ptp(err, axis=0).max() < 0.03
    assert np.abs(err[:, 2]).max() < 0.03
