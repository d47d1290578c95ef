"""The C kernel of the segment quaternions gives NumPy's numbers to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.results.quats_kernel import kernel_quats_wxyz
from ikfusion.rotations import _quat_wxyz_at_once, axis_rotation, matrix_to_quat_wxyz


def test_every_branch_and_awkward_matrices_as_numpy(rng) -> None:
    # random rotations, half turns about each axis (each branch of the largest component),
    # near-ties of the diagonal, matrices that are not rotations, exact identities
    turns = np.concatenate([axis_rotation(a, np.pi + rng.normal(0.0, 1e-3, 50)) for a in "xyz"])
    random = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(300)])
    random *= np.sign(np.linalg.det(random))[:, None, None]
    R = np.concatenate([turns, random, rng.normal(size=(100, 3, 3)),
                        np.broadcast_to(np.eye(3), (5, 3, 3)),
                        np.round(random[:50], 1)]).reshape(-1, 5, 3, 3)
    got = kernel_quats_wxyz(R)
    if got is None:
        pytest.skip("no C kernel (no compiler or IKFUSION_NO_COMPILE): NumPy converts")
    expected = _quat_wxyz_at_once(R)
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))
    assert np.array_equal(got.view(np.uint64), matrix_to_quat_wxyz(R).view(np.uint64))


def test_non_finite_matrices_are_left_to_numpy() -> None:
    R = np.full((2, 3, 3, 3), np.nan)
    assert kernel_quats_wxyz(R) is None
