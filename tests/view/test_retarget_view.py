"""``ikfusion view`` on retarget outputs: the robot from its URDF, the resized human."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from view_motion import FRAMES

from ikfusion.retarget import retarget
from ikfusion.retarget.robot_config import robots_installed
from ikfusion.view import load_scene


def test_a_taller_human_is_drawn_at_its_height(result_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "tall"
    retarget(result_folder, "human", height=1.95, out=out)
    actor = load_scene(out).main
    assert actor.frames == FRAMES and len(actor.segment_names) == 23
    head = actor.p_world_site[0, actor.site_index("HeadTop"), 2]
    assert head == pytest.approx(1.95, abs=0.03)
    lit = actor.contacts[:, :4]
    feet = actor.p_world_site[:, :4, 2]
    assert lit.any() and np.all(feet[lit] < 0.01)


@pytest.mark.skipif(not robots_installed(), reason="example-robot-data is not installed "
                    "(pip install 'ikfusion[robots]')")
def test_the_robot_is_rebuilt_from_its_urdf_and_saved(result_folder: Path,
                                                      tmp_path: Path) -> None:
    out = tmp_path / "g1"
    motion, _ = retarget(result_folder, "g1", out=out)
    actor = load_scene(out).main
    assert actor.name == "robot" and actor.frames == FRAMES
    assert actor.segment_names[0] == "root_joint" and actor.segment_parents[0] == -1
    np.testing.assert_allclose(actor.p_world_segment[:, 0], motion.root_pos, atol=1e-9)
    # the root's frame turns as written, joint curves are the joint positions
    R0 = pin.Quaternion(*motion.root_quat_wxyz[5]).matrix()
    q0 = actor.quat_wxyz_world_segment[5, 0]
    np.testing.assert_allclose(pin.Quaternion(*q0).matrix(), R0, atol=1e-9)
    np.testing.assert_allclose(actor.joint_angles_deg, np.degrees(motion.dof_pos))
    # planted soles stand on the floor (from the frame after touch-down, which sets them down)
    held = actor.contacts[1:] & actor.contacts[:-1]
    assert held.any() and np.all(np.abs(actor.p_world_site[1:, :, 2][held]) < 1e-3)
    rrd = tmp_path / "g1.rrd"
    done = subprocess.run([sys.executable, "-m", "ikfusion", "view", str(out), "--save", str(rrd)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert rrd.stat().st_size > 10_000
