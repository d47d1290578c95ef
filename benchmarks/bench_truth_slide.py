"""How much the ground truth read from each mocap clip skates, and where the skating comes from.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_truth_slide.py [--clips PATTERN]``

For every BVH clip of ``benchmarks/motions/library.yaml`` the truth is built as ``ikfusion
simulate --motion`` builds it (:func:`ikfusion.mocap.from_bvh.motion_from_bvh`), once without
and once with the foot lock (:func:`ikfusion.mocap.foot_lock.lock_planted_points`). Columns:

* ``phases``, ``slide``, ``max``: contact phases of the truth without the lock, and the mean and
  largest horizontal slide of its own contact points over a phase
  (:func:`ikfusion.app.evaluate.phase_slides`) [mm];
* ``bvh ank``, ``our ank``: over the flat-foot phases of that truth (heel and toe of a foot both
  planted), the mean largest horizontal slide of the BVH skeleton's own ankle joint and of our
  model's ankle [mm]: a still BVH ankle beside a sliding one of ours is our mapping's doing, a
  sliding BVH ankle is the capture's;
* ``locked``, ``lmax``: mean and largest slide per phase of the truth with the lock (phases
  labelled again on it) [mm]; ``shift``: the largest root offset the lock added [cm].
"""

from __future__ import annotations

import argparse
import fnmatch
import sys
from collections.abc import Sequence

import numpy as np

from ikfusion.app.evaluate import phase_slides
from ikfusion.io.bvh import read_bvh
from ikfusion.mocap.foot_lock import lock_planted_points
from ikfusion.mocap.from_bvh import motion_from_bvh
from ikfusion.mocap.model_motion import TruthMotion, contact_phases, frame_poses, site_positions
from ikfusion.mocap.skeleton_map import map_motion

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from bench_motions import RATE, load_library  # noqa: E402


def _flat_foot_runs(contacts: np.ndarray, names: list[str], side: str) -> np.ndarray:
    """(N,) frames where the heel and toe of one foot are both planted."""
    return contacts[:, names.index(f"{side}Heel")] & contacts[:, names.index(f"{side}Toe")]


def _bvh_ankles(path: str, truth: TruthMotion) -> dict[str, np.ndarray]:
    """The BVH skeleton's own ankle joints (N, 3) [m] at the truth's frames."""
    bvh = read_bvh(path)
    step = int(truth.info["step"])
    frames = np.arange(0, bvh.num_frames, step)[-len(truth.time):]
    joints = map_motion(bvh, frames=frames).p_world_joint
    return {side: joints[f"j{side}Ankle"] for side in ("Left", "Right")}


def _mean_slide(P: np.ndarray, runs: np.ndarray) -> float:
    """Mean largest horizontal slide [mm] of one point (N, 3) over its runs (N,)."""
    slides = phase_slides(P[:, None, :], runs[:, None])
    return 1000.0 * float(np.mean(slides)) if slides else float("nan")


def measure(path: str) -> str:
    """One line of the table for a BVH clip."""
    truth = motion_from_bvh(path, rate=RATE, lock_contacts=False)
    model, names = truth.model, truth.contact_names
    P = site_positions(model, truth.q, names)
    slides = 1000.0 * np.array(phase_slides(P, truth.contacts))
    bvh = _bvh_ankles(path, truth)
    ankle_ids = [model.segment_frame_id(f"{side}Foot") for side in ("Left", "Right")]
    ours = frame_poses(model.model, truth.q, ankle_ids)[0]
    bvh_ank, our_ank = [], []
    for i, side in enumerate(("Left", "Right")):
        flat = _flat_foot_runs(truth.contacts, names, side)
        bvh_ank.append(_mean_slide(bvh[side], flat))
        our_ank.append(_mean_slide(ours[:, i], flat))
    bvh_mm = np.nanmean(bvh_ank) if np.isfinite(bvh_ank).any() else float("nan")
    our_mm = np.nanmean(our_ank) if np.isfinite(our_ank).any() else float("nan")
    q, offset = lock_planted_points(model, truth.q, truth.time, names)
    locked = 1000.0 * np.array(phase_slides(site_positions(model, q, names),
                                            contact_phases(model, q, truth.time, names)))
    return (f"{len(slides):6d} {np.mean(slides) if len(slides) else 0:7.1f} "
            f"{slides.max(initial=0):7.1f} {bvh_mm:8.1f} {our_mm:8.1f} "
            f"{np.mean(locked) if len(locked) else 0:7.1f} {locked.max(initial=0):7.1f} "
            f"{100 * np.linalg.norm(offset, axis=1).max():6.1f}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clips", default="*", metavar="PATTERN",
                        help="clip names to measure (shell pattern; default all BVH clips)")
    args = parser.parse_args(argv)
    clips = [c for c in load_library().clips if not c.motion.startswith("gait")
             and fnmatch.fnmatch(c.name, args.clips)]
    if not clips:
        parser.error(f"no BVH clip matches {args.clips!r}")
    print(f"{'clip':<22s} {'phases':>6s} {'slide':>7s} {'max':>7s} {'bvh ank':>8s} "
          f"{'our ank':>8s} {'locked':>7s} {'lmax':>7s} {'shift':>6s}")
    for clip in clips:
        print(f"{clip.name:<22s} {measure(clip.motion)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
