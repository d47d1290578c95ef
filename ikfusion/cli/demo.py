"""``ikfusion demo``: the main job on embedded data (simulate, solve, write, score)."""

from __future__ import annotations

import argparse

from ..demo import run_demo, table


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand."""
    p = subparsers.add_parser(
        "demo",
        help="run the main job on embedded data",
        description="Simulate a capture (a walk in circles in a 6 m x 8 m room, 17 IMUs with "
        "realistic errors), solve it, write the result folder and the truth, and print the "
        "accuracy and speed table.",
    )
    p.add_argument("--out", default="ikfusion-demo", metavar="DIR", help="output folder")
    p.add_argument("--seconds", type=float, default=60.0, metavar="S",
                   help="length of the simulated capture [s]")
    p.add_argument("--seed", type=int, default=7, help="random seed of the simulation")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion demo``."""
    result = run_demo(args.out, seconds=args.seconds, seed=args.seed, progress=not args.quiet)
    print(table(result))
    return 0
