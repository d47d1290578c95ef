"""The contact flags of a frame and the contact rows of a motion against their plain definitions."""

import numpy as np

from ikfusion.ik.contact_flags import ContactFlags
from ikfusion.ik.pose import Motion, Pose
from ikfusion.model import HumanModel


def test_contact_flags_are_held_and_not_rising() -> None:
    names = [f"p{i}" for i in range(6)]
    flags = ContactFlags(names, kept=4)  # small: the patterns are dropped and made again
    rng = np.random.default_rng(3)
    for _ in range(200):
        active = rng.random(6) > 0.5
        free_z = (rng.random(6) > 0.7) & active
        got = flags(active, free_z)
        assert got == {n: bool(a and not f) for n, a, f in zip(names, active, free_z)}
        assert all(type(v) is bool for v in got.values())
        got[names[0]] = "changed"  # a copy: the kept pattern stays as it was
        assert flags(active, free_z)[names[0]] is bool(active[0] and not free_z[0])
    assert ContactFlags([])(np.zeros(0, bool), np.zeros(0, bool)) == {}


def test_motion_contact_rows_match_each_pose() -> None:
    model = HumanModel.default()
    names = model.sites_of_kind("contact")
    rng = np.random.default_rng(5)
    patterns = [{n: bool(rng.random() > 0.5) for n in names[:-2]} for _ in range(7)]
    patterns.append({names[0]: np.True_, names[1]: 0.0, "elsewhere": True})  # other values
    poses = [Pose(model, 0.01 * k, model.neutral(), dict(patterns[rng.integers(8)]), 0.0, 1)
             for k in range(300)]
    motion = Motion.from_poses(model, poses, names)
    expected = np.array([[p.contacts.get(n, False) for n in names] for p in poses], dtype=bool)
    assert motion.contacts.dtype == bool
    np.testing.assert_array_equal(motion.contacts, expected)
    assert Motion.from_poses(model, [], names).contacts.shape == (0, len(names))
    assert Motion.from_poses(model, poses, []).contacts.shape == (300, 0)
