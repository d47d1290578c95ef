"""Retargeting speed and quality on the shared clips, per shipped robot, and batch throughput.

For every robot of ``configs/retarget/`` and every clip of ``../shared/data/mocap/`` plus the
MVNX file: frames per second of the retargeting solve itself (one process, one core; as
``summary.json`` reports it), of the ``retarget`` call (loading the URDF and computing the
metrics too; the source loaded before the clock starts) and of the whole command after start-up
(``whole``: reading the clip, building its body's model as a fresh process does, solving a BVH
onto the human model, retargeting, the metrics and writing the output folder), joint-limit
and velocity-limit violations, foot slide over the planted phases (max mm), floor penetration
(max mm), the closest capsule pair (cm), relaxed frames, and the worst mapped link's orientation
RMS (deg). The peer, GMR (general-motion-retargeting), is not a dependency: its figure is
printed as a reference, with where it comes from. Then ``ikfusion batch retarget`` over
``--copies`` copies of all clips onto G1 with 1 and 2 workers (files and frames per second of
wall time, source loading included; the start-up and CPU seconds of all processes, see
``batch_timing.py``).

``--cpu`` times ``call`` and ``whole`` by this process's CPU time instead of the wall clock
(fair on a machine other jobs share; ``fps`` stays ``summary.json``'s wall-clock figure);
``--repeat N`` keeps the best of N timings of each (other jobs only ever slow a run down).

``--phases N`` prints instead of the table where a whole command's CPU time goes, phase by
phase (``retarget_phases.py``), the least of N runs per clip.

Run: .venv/bin/python benchmarks/bench_retarget.py [--robots g1 talos] [--clips walk] [--cpu]
[--repeat N] [--no-batch | --no-table] [--copies N] [--phases N]
"""

from __future__ import annotations

import argparse
import math
import shutil
import tempfile
import time
from pathlib import Path

from batch_timing import batch_rows, print_batch_rows
from retarget_phases import print_phase_rows

from ikfusion.mocap.skeleton_map import _default_alias_table
from ikfusion.model.human_model import _model_of_body
from ikfusion.model.model_cache import code_fingerprint
from ikfusion.retarget import load_source, retarget
from ikfusion.retarget.robot_config import SHIPPED_ROBOTS

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"

#: The peer's speed on this machine class, from issue #20 (GMR is not installed here): its IK
#: alone, without reading or solving the source, frames per second on one core.
GMR_REFERENCE = ("GMR (general-motion-retargeting) IK alone: 290-360 frames/s "
                 "(issue #20's figure, not run here)")


def clips(pattern: str = "") -> list[Path]:
    """The shared BVH clips and the MVNX file (those whose name contains ``pattern``)."""
    found = sorted((SHARED / "mocap").glob("*.bvh")) + sorted((SHARED / "mvnx").glob("*.mvnx"))
    found = [c for c in found if pattern in c.name]
    if not found:
        raise SystemExit(f"no clips matching {pattern!r} under {SHARED} (../shared/data beside "
                         "the repository)")
    return found


def forget_loaded_clips() -> None:
    """Drop what loading clips left in this process, as a fresh command starts without it.

    That is each body's parsed model, the fingerprint of the model code that keys the model
    cache, and the expanded joint-name aliases. A ``retarget`` command loads its one clip in a
    fresh process: timing ``whole`` after the table's own loads of the same clip would leave
    out getting its body's model. As in a fresh process, ``whole`` then loads it from the user
    cache (``human_models/``, filled by the table's first load, as by a command's first run on
    that body; building it instead costs about 10 ms more once).
    """
    _model_of_body.cache_clear()
    code_fingerprint.cache_clear()
    _default_alias_table.cache_clear()


def robot_table(robots: list[str], pattern: str = "", cpu: bool = False,
                repeat: int = 1) -> None:
    """One row per robot and clip, and a total row per robot (``cpu``: CPU time).

    ``call`` and ``whole`` are the best of ``repeat`` runs.
    """
    clock = time.process_time if cpu else time.perf_counter
    sources = {clip: load_source(clip) for clip in clips(pattern)}  # also warms up
    print(f"{'robot':6} {'clip':24} {'frames':>6} {'fps':>6} {'call':>6} {'whole':>6} "
          f"{'limit':>5} {'vel':>4} {'slide mm':>8} {'floor mm':>8} {'caps cm':>7} {'relax':>5}"
          "  worst link (deg)")
    for robot in robots:
        retarget(next(iter(sources.values())), robot)  # start-up: URDF, step function
        frames = seconds = calls = wholes = 0.0
        for clip, source in sources.items():
            elapsed = whole = math.inf
            for _ in range(repeat):  # the best of a few: other work on the machine only slows
                start = clock()
                _, m = retarget(source, robot)
                elapsed = min(elapsed, clock() - start)
                with tempfile.TemporaryDirectory() as tmp:
                    forget_loaded_clips()  # as in a fresh command: the body is built anew
                    start = clock()
                    retarget(load_source(clip), robot, out=Path(tmp) / "out")
                    whole = min(whole, clock() - start)
            frames += m["frames"]
            seconds += m["frames"] / m["frames_per_second"]
            calls += elapsed
            wholes += whole
            worst = max(m["tracking_orientation_rms_deg"].items(), key=lambda kv: kv[1])
            print(f"{robot:6} {clip.stem[:24]:24} {m['frames']:6d} {m['frames_per_second']:6.0f} "
                  f"{m['frames'] / elapsed:6.0f} {m['frames'] / whole:6.0f} "
                  f"{m['joint_limit_violations']:5d} {m['velocity_limit_violations']:4d} "
                  f"{m['foot_slide_mm_max']:8.3f} {m['floor_penetration_mm_max']:8.3f} "
                  f"{100 * m['self_collision_min_distance_m']:7.2f} {m['relaxed_frames']:5d}  "
                  f"{worst[0].split('->')[0]} {worst[1]:.1f}")
        print(f"{robot:6} {'all clips':24} {int(frames):6d} {frames / seconds:6.0f} "
              f"{frames / calls:6.0f} {frames / wholes:6.0f}  (frames per second, one core"
              f"{', call and whole by CPU time' if cpu else ''})")
    print(f"peer: {GMR_REFERENCE}")


def batch_table(copies: int) -> None:
    """``batch retarget`` of ``copies`` copies of every clip onto G1 with 1 and 2 local workers.

    Copies (each its own file, as distinct recordings are) make a batch long enough that the
    start-up of the cluster and its workers (the ``start s`` column) is not the whole story.
    """
    with tempfile.TemporaryDirectory() as tmp:
        inputs = []
        for i in range(copies):
            folder = Path(tmp) / f"copy{i}"
            folder.mkdir()
            for clip in clips():
                inputs.append(str(shutil.copy(clip, folder / clip.name)))
        frames = sum(len(load_source(c)) for c in clips())
        print(f"\nbatch retarget onto g1: {copies} copies of the {len(clips())} clips, "
              f"{len(inputs)} inputs, {copies * frames} frames (source loading included)")
        print_batch_rows(batch_rows("retarget", inputs, {"robot": "g1"}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(SHIPPED_ROBOTS))
    parser.add_argument("--clips", default="", help="only clips whose name contains this")
    parser.add_argument("--cpu", action="store_true",
                        help="time call and whole by CPU time (a shared machine)")
    parser.add_argument("--no-batch", action="store_true", help="skip the batch throughput")
    parser.add_argument("--copies", type=int, default=4,
                        help="copies of every clip in the batch (start-up counts less)")
    parser.add_argument("--no-table", action="store_true", help="only the batch throughput")
    parser.add_argument("--repeat", type=int, default=1,
                        help="time call and whole this many times, keep the best (a busy machine)")
    parser.add_argument("--phases", type=int, default=0, metavar="N",
                        help="instead of the table: each phase's CPU time of a whole command on "
                             "the first robot, the least of N runs per clip")
    args = parser.parse_args()
    if args.phases > 0:
        print_phase_rows(clips(args.clips), args.robots[0], args.phases, forget_loaded_clips)
    elif not args.no_table:
        robot_table(args.robots, args.clips, args.cpu, max(1, args.repeat))
    if not args.no_batch:
        batch_table(max(1, args.copies))


if __name__ == "__main__":
    main()
