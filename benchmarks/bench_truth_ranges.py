"""The library's simulated truths against the model's ranges of motion (issue #19).

Usage: ``python benchmarks/bench_truth_ranges.py [--clips PATTERN] [--seconds S]``

Per clip of ``benchmarks/motions/library.yaml``, the truth as ``bench_motions`` builds it (60 Hz,
lead-in first), before and after the 50 ms smoothing a capture with UWB tags gets
(:func:`ikfusion.sim.uwb_capture.smooth_truth`). Columns: ``out``: frames with a joint angle
more than 1 deg outside its range (measured as the solver does, on the Euler triple nearest to
the range); ``beyond``: the largest excess [deg]; ``step``: the truth's own largest turn of a
joint over one frame [deg] (the geodesic angle, toes left out, as ``joint_angle_step_max_deg``
measures a solve) and where.
"""

from __future__ import annotations

import argparse
import fnmatch
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_motions import clip_truth, load_library  # noqa: E402

from ikfusion.app.evaluate import joint_angle_jump  # noqa: E402
from ikfusion.ik.limits.joint_range import JointRangeLimit  # noqa: E402
from ikfusion.mocap.model_motion import TruthMotion  # noqa: E402
from ikfusion.sim.uwb_capture import smooth_truth  # noqa: E402

#: An angle more than this outside its range counts [deg].
OUTSIDE_DEG = 1.0


def range_excess_deg(truth: TruthMotion) -> np.ndarray:
    """Per frame, the largest excess of a joint angle beyond its range (N,) [deg]."""
    limits = JointRangeLimit(truth.model.ball_joints, margin_deg=0.0)
    return np.array([limits.violation_deg(q).max(initial=0.0) for q in truth.q])


def truth_figures(truth: TruthMotion) -> str:
    """``out``, ``beyond`` and ``step`` of one truth (see the module docstring)."""
    excess = range_excess_deg(truth)
    angles = truth.model.joint_angle_matrix(truth.q)
    step, where = joint_angle_jump(truth.time, angles, np.zeros_like(angles),
                                   truth.model.angle_columns)
    return f"{int(np.sum(excess > OUTSIDE_DEG)):5d} {excess.max():7.1f} {step:6.1f} {where:28s}"


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clips", default="*", help="fnmatch pattern(s), comma separated")
    parser.add_argument("--seconds", type=float, default=None, help="cut each clip [s]")
    args = parser.parse_args(argv)
    patterns = args.clips.split(",")
    clips = [c for c in load_library().clips
             if any(fnmatch.fnmatch(c.name, p) for p in patterns)]
    head = f"{'out':>5s} {'beyond':>7s} {'step':>6s} {'at':28s}"
    print(f"{'clip':22s} {'frames':>6s} | raw: {head} | smoothed: {head}")
    for clip in clips:
        truth = clip_truth(clip, args.seconds)
        print(f"{clip.name:22s} {len(truth.time):6d} | {truth_figures(truth)} | "
              f"{truth_figures(smooth_truth(truth))}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
