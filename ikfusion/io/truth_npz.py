"""Reading ``truth.npz``, the ground truth ``ikfusion simulate`` writes (SPEC section 5).

The writer is :func:`ikfusion.sim.truth.write_truth`; ``evaluate`` and ``view`` read it here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .npz import read_npz

#: The arrays of ``truth.npz`` with their shapes (names of sizes: N frames, S segments, M
#: sites, C contacts, J joint-angle columns; integers are fixed sizes).
TRUTH_SHAPES: dict[str, tuple[str | int, ...]] = {
    "time": ("N",), "segment_names": ("S",), "p_world_segment": ("N", "S", 3),
    "quat_wxyz_world_segment": ("N", "S", 4), "site_names": ("M",),
    "p_world_site": ("N", "M", 3), "contact_names": ("C",), "contacts": ("N", "C"),
    "joint_angle_names": ("J",), "joint_angles": ("N", "J"),
}


def read_truth(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a ``truth.npz`` (see :func:`write_truth`), checked.

    Raises:
        InputError: A damaged file, a missing array, shapes that do not agree, times that do
            not increase, or non-finite values (file and array named).
    """
    data = read_npz(path, TRUTH_SHAPES, "truth.npz")
    sizes: dict[str, int] = {}
    for name, shape in TRUTH_SHAPES.items():
        array = data[name]
        if array.ndim != len(shape) or any(
                isinstance(d, int) and array.shape[k] != d for k, d in enumerate(shape)):
            raise InputError(f"expected shape ({', '.join(map(str, shape))}), found "
                             f"{array.shape}", path=path, field=name)
        for k, d in enumerate(shape):
            if isinstance(d, str) and sizes.setdefault(d, array.shape[k]) != array.shape[k]:
                raise InputError(f"{d} = {array.shape[k]} along axis {k} disagrees with "
                                 f"{sizes[d]} in the other arrays", path=path, field=name)
        if array.dtype.kind in "fiub" and not np.isfinite(array.astype(float)).all():
            raise InputError("non-finite values", path=path, field=name)
    if sizes["N"] < 2 or not (np.diff(data["time"].astype(float)) > 0).all():
        raise InputError("expected at least two frames with increasing times", path=path,
                         field="time")
    return data
