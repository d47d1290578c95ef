"""Reader of the LIAS-CUHKSZ planar UWB data set (shared/data/uwb/lias_planar) for the tests.

Source: LIAS-CUHKSZ/Efficient-Pose-Estimation-via-UWB-measurements (MIT). Anchor and tag
coordinates are parsed from the data set's README tables (nothing is copied here).

Findings on this capture, checked by ``test_uwb_lias_real.py``:
- the optical quaternion columns are (w, x, y, z), scalar FIRST, and the optical rigid body
  has its z axis pointing down: the tag coordinates of the README are in the body frame turned
  180 degrees about its x axis, i.e. ``p_tag = p_body + R(q) diag(1, -1, -1) t_local``. With
  this, measured ranges agree with the optical truth twice as well (median absolute deviation
  per link) as with a scalar-last reading, which gives tilted, non-planar poses;
- optical timestamps are not monotonic (a few hundred out-of-order rows): they are sorted.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ikfusion.rotations import quat_wxyz_to_matrix

_ROW = re.compile(r"^\|\s*(Tag|Anchor)\s+(\d+)\s*\|\s*([-\d.]+)\s*\|\s*([-\d.]+)\s*\|\s*([-\d.]+)")


@dataclass
class Lias:
    anchors: np.ndarray  # (8, 3) [m]
    tags_local: np.ndarray  # (3, 3) [m]
    uwb_time: np.ndarray  # (N,) [s of day]
    ranges: np.ndarray  # (N, 3 tags, 8 anchors) [m], NaN where blank
    opt_time: np.ndarray  # (K,) [s of day], sorted
    opt_pos: np.ndarray  # (K, 3) [m]
    opt_quat_wxyz: np.ndarray  # (K, 4)

    def tag_truth(self, tag: int, flip: bool = True, scalar_first: bool = True) -> np.ndarray:
        """Optical tag positions (K, 3) under a quaternion convention."""
        q = self.opt_quat_wxyz if scalar_first else self.opt_quat_wxyz[:, [3, 0, 1, 2]]
        rot = quat_wxyz_to_matrix(q)
        if flip:
            rot = rot @ np.diag([1.0, -1.0, -1.0])
        return self.opt_pos + rot @ self.tags_local[tag]


def _seconds(stamp: str) -> float:
    clock = stamp.strip().split(" ")[-1]
    h, m, s = clock.split(":")
    return int(h) * 3600.0 + int(m) * 60.0 + float(s)


def load(folder: Path) -> Lias:
    anchors: dict[int, list[float]] = {}
    tags: dict[int, list[float]] = {}
    for line in (folder / "README.md").read_text(encoding="utf-8").splitlines():
        m = _ROW.match(line.strip())
        if m:
            target = tags if m.group(1) == "Tag" else anchors
            target[int(m.group(2))] = [float(m.group(i)) for i in (3, 4, 5)]
    uwb_t, uwb = [], []
    for line in (folder / "UWB_dynamic_exp_mid.csv").read_text().splitlines():
        f = line.split(",")
        if len(f) != 25:
            continue
        uwb_t.append(_seconds(f[0]))
        uwb.append([float(v) if v.strip() else np.nan for v in f[1:]])
    opt_t, opt = [], []
    for line in (folder / "motion_capture_dynamic_exp_mid.csv").read_text().splitlines()[1:]:
        f = line.split(",")
        opt_t.append(_seconds(f[0]))
        opt.append([float(v) for v in f[1:8]])
    o = np.array(opt)
    t = np.array(opt_t)
    order = np.argsort(t, kind="stable")
    ranges = np.array(uwb).reshape(len(uwb), 8, 3).transpose(0, 2, 1)
    return Lias(
        anchors=np.array([anchors[i] for i in range(8)]),
        tags_local=np.array([tags[i] for i in range(3)]),
        uwb_time=np.array(uwb_t),
        ranges=ranges,
        opt_time=t[order],
        opt_pos=o[order, :3],
        opt_quat_wxyz=o[order, 3:7],
    )
