"""``ikfusion retarget``: a motion onto another body (today: the human model at another size)."""

from __future__ import annotations

import argparse

from ..retarget import ROBOTS, retarget


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``retarget`` subcommand."""
    p = subparsers.add_parser(
        "retarget",
        help="retarget a solve result or a BVH onto another body",
        description="Retarget a `solve` result folder or a BVH clip: every segment's orientation "
        "is tracked, the pelvis path is scaled by the ratio of hip heights, and the source's "
        "contact phases hold the planted feet without slip. Writes robot_motion.npz, "
        "robot_motion.csv and summary.json (limits, velocities, foot slide, floor "
        "penetration, tracking error, frames per second).",
    )
    p.add_argument("source", metavar="SOURCE", help="solve result folder or .bvh file")
    p.add_argument("--robot", choices=ROBOTS, default="human",
                   help="target body (human: our model at --height)")
    p.add_argument("--height", type=float, default=None, help="body height of a human target [m]")
    p.add_argument("--format", choices=["gmr"], default=None,
                   help="also write robot_motion.pkl in the layout of RL tracking pipelines")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion retarget``."""
    _, metrics = retarget(args.source, args.robot, height=args.height, out=args.out,
                          gmr=args.format == "gmr", progress=not args.quiet)
    print(f"wrote {args.out}: {metrics['frames']} frames, foot slide "
          f"{metrics['foot_slide_mm_max']:.2f} mm max, joint-limit violations "
          f"{metrics['joint_limit_violations']}, {metrics['frames_per_second']:.0f} frames/s")
    return 0
