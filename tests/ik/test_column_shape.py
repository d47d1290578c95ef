"""The column shape task moves a site only through how unsensed columns share their bend."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ikfusion.ik.configuration import Configuration
from ikfusion.ik.tasks import ColumnShapeTask
from ikfusion.model.human_model import HumanModel

SPINE = ["jL5S1", "jL4L3", "jL1T12", "jT9T8"]
NECK = ["jT1C7", "jC1Head"]


def test_a_shape_step_moves_the_head_but_not_the_root_nor_the_columns_ends(
        rng: np.random.Generator) -> None:
    """The Jacobian has no root or limb column; a step along it keeps each column's summed
    rotation, so the chest and the head keep their orientations to first order while the
    head moves: the share changes, hardly what the sensors see."""
    human = HumanModel.default()
    model, nv = human.model, human.model.nv
    q = pin.integrate(model, human.neutral(), 0.05 * rng.standard_normal(nv))
    head = human.site_frame_id("HeadTop")
    task = ColumnShapeTask([head], ["HeadTop"], human.ball_joints, [SPINE, NECK], nv)
    task.set_targets(np.zeros((1, 3)), np.ones(1))
    conf = Configuration(model, q)
    J = task.compute_jacobian(conf)
    joints = [human.ball_joints[n] for n in SPINE + NECK]
    columns = np.concatenate([np.arange(j.idx_v, j.idx_v + 3) for j in joints])
    others = np.setdiff1d(np.arange(nv), columns)
    np.testing.assert_allclose(J[:, others], 0.0, atol=1e-12)
    step = np.linalg.pinv(J[0:1]) @ np.array([0.01])  # the head 1 cm along x
    q_next = pin.integrate(model, q, 1e-3 * step / np.linalg.norm(step))
    data, data_next = model.createData(), model.createData()
    for d, qq in ((data, q), (data_next, q_next)):
        pin.framesForwardKinematics(model, d, qq)
    moved = data_next.oMf[head].translation - data.oMf[head].translation
    assert abs(moved[0]) > 1e-4  # 1 mrad of share moves the head by a tenth of a millimetre
    for segment in ("T8", "Head"):
        f = human.segment_frame_id(segment)
        turn = pin.log3(data.oMf[f].rotation.T @ data_next.oMf[f].rotation)
        # exact for aligned joint frames; the random bends (3 deg) leave a few percent
        assert np.linalg.norm(turn) < 0.15 * 1e-3
