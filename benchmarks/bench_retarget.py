"""Retargeting speed and quality on the shared clips, per shipped robot, and batch throughput.

For every robot of ``configs/retarget/`` and every clip of ``../shared/data/mocap/`` plus the
MVNX file: frames per second of the retargeting solve itself (one process, one core; as
``summary.json`` reports it) and of the whole call (loading the URDF and computing the metrics
too; the source is loaded before the clock starts, since a BVH is first solved onto the human
model), joint-limit
and velocity-limit violations, foot slide over the planted phases (max mm), floor penetration
(max mm), the closest capsule pair (cm), relaxed frames, and the worst mapped link's orientation
RMS (deg). Then ``ikfusion batch retarget`` over all clips onto G1 with 1 and 2 workers (files
and frames per second of wall time, source loading included).

Run: .venv/bin/python benchmarks/bench_retarget.py [--robots g1 talos icub] [--no-batch]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from batch_timing import batch_rows, print_batch_rows

from ikfusion.retarget import load_source, retarget
from ikfusion.retarget.robot_config import SHIPPED_ROBOTS

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def clips() -> list[Path]:
    """The shared BVH clips and the MVNX file."""
    found = sorted((SHARED / "mocap").glob("*.bvh")) + sorted((SHARED / "mvnx").glob("*.mvnx"))
    if not found:
        raise SystemExit(f"no clips under {SHARED} (../shared/data beside the repository)")
    return found


def robot_table(robots: list[str]) -> None:
    """One row per robot and clip, and a total row per robot."""
    sources = {clip: load_source(clip) for clip in clips()}
    print(f"{'robot':6} {'clip':24} {'frames':>6} {'fps':>6} {'call':>6} {'limit':>5} {'vel':>4} "
          f"{'slide mm':>8} {'floor mm':>8} {'caps cm':>7} {'relax':>5}  worst link (deg)")
    for robot in robots:
        frames = seconds = calls = 0.0
        for clip, source in sources.items():
            start = time.perf_counter()
            _, m = retarget(source, robot)
            elapsed = time.perf_counter() - start
            frames += m["frames"]
            seconds += m["frames"] / m["frames_per_second"]
            calls += elapsed
            worst = max(m["tracking_orientation_rms_deg"].items(), key=lambda kv: kv[1])
            print(f"{robot:6} {clip.stem[:24]:24} {m['frames']:6d} {m['frames_per_second']:6.0f} "
                  f"{m['frames'] / elapsed:6.0f} "
                  f"{m['joint_limit_violations']:5d} {m['velocity_limit_violations']:4d} "
                  f"{m['foot_slide_mm_max']:8.3f} {m['floor_penetration_mm_max']:8.3f} "
                  f"{100 * m['self_collision_min_distance_m']:7.2f} {m['relaxed_frames']:5d}  "
                  f"{worst[0].split('->')[0]} {worst[1]:.1f}")
        print(f"{robot:6} {'all clips':24} {int(frames):6d} {frames / seconds:6.0f} "
              f"{frames / calls:6.0f}  (frames per second, one core)")


def batch_table() -> None:
    """``batch retarget`` of every clip onto G1 with 1 and 2 local workers."""
    inputs = [str(c) for c in clips()]
    print(f"\nbatch retarget onto g1, {len(inputs)} inputs (source loading included)")
    print_batch_rows(batch_rows("retarget", inputs, {"robot": "g1"}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(SHIPPED_ROBOTS))
    parser.add_argument("--no-batch", action="store_true", help="skip the batch throughput")
    args = parser.parse_args()
    robot_table(args.robots)
    if not args.no_batch:
        batch_table()


if __name__ == "__main__":
    main()
