"""``ikfusion retarget``: a motion onto a humanoid robot or the human model at another size."""

from __future__ import annotations

import argparse
import sys

from ..retarget import ROBOTS, retarget
from . import add_force_option


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``retarget`` subcommand."""
    p = subparsers.add_parser(
        "retarget",
        help="retarget a solve result or a BVH onto a humanoid robot or another body size",
        description="Retarget a `solve` result folder or a BVH clip onto a humanoid robot "
        "(g1, talos, icub, romeo from example-robot-data, or any URDF with --config) or onto "
        "the human model at --height: mapped links follow the segments' orientations, pelvis, "
        "hands and feet the positions scaled by the ratio of hip heights; joint and velocity "
        "limits, planted feet, the floor and self-collision capsules are hard constraints. "
        "Writes robot_motion.npz, robot_motion.csv (column names carry their units: time_s, "
        "root_x_m, <dof>_rad, <contact>_planted) and summary.json (limits, velocities, foot "
        "slide, floor penetration, self-collision distance, tracking error, frames per "
        "second, warnings); a human target also gets motion.bvh for animation tools.",
    )
    p.add_argument("source", metavar="SOURCE", help="solve result folder, .bvh or .mvnx file")
    p.add_argument("--robot", default="human", metavar="|".join(ROBOTS) + "|PATH.urdf",
                   help="target (human: our model at --height)")
    p.add_argument("--config", metavar="FILE",
                   help="retarget config (links, weights, feet, capsules); needed for a URDF")
    p.add_argument("--height", type=float, default=None, help="body height of a human target [m]")
    p.add_argument("--format", choices=["gmr"], default=None,
                   help="also write robot_motion.pkl in the layout of RL tracking pipelines")
    p.add_argument("--bvh-up", choices=["z", "y"], default="z",
                   help="up axis of the motion.bvh of a human target (y for Y-up tools)")
    p.add_argument("--out", required=True, help="output folder")
    add_force_option(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion retarget``."""
    _, metrics = retarget(args.source, args.robot, height=args.height, out=args.out,
                          gmr=args.format == "gmr", config=args.config,
                          progress=not args.quiet, force=args.force, bvh_up=args.bvh_up)
    gap = metrics.get("self_collision_min_distance_m")
    print(f"wrote {args.out}: {metrics['frames']} frames at {metrics['frames_per_second']:.0f} "
          f"frames/s; joint-limit violations {metrics['joint_limit_violations']}, velocity-limit "
          f"violations {metrics['velocity_limit_violations']}, foot slide "
          f"{metrics['foot_slide_mm_max']:.2f} mm max, floor penetration "
          f"{metrics['floor_penetration_mm_max']:.2f} mm"
          + ("" if gap is None else f", closest capsules {100 * gap:.1f} cm")
          + f", relaxed frames {metrics['relaxed_frames']}")
    for warning in metrics.get("warnings", []):
        print(f"ikfusion retarget: warning: {warning}", file=sys.stderr)
    return 0
