"""``ikfusion demo``: the main job on embedded data (simulate, solve, write, score)."""

from __future__ import annotations

import argparse

from ..app.demo import run_demo, table
from . import add_force_option


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand."""
    p = subparsers.add_parser(
        "demo",
        help="run the main job on embedded data",
        description="Simulate a capture (a walk in circles in a 6 m x 8 m room, 17 IMUs with "
        "realistic errors, UWB tags on head and feet heard by the 10 readers of "
        "configs/constellations/room_6x8.yaml), calibrate it and track the tags once, solve it "
        "IMU only and with UWB slide and no-slide correction, write the three result folders "
        "(result/ is no-slide, then result_slide/, result_imu_only/) and the truth, and print "
        "the accuracy and speed table with a column per mode.",
    )
    p.add_argument("--out", default="ikfusion-demo", metavar="DIR", help="output folder")
    add_force_option(p)
    p.add_argument("--seconds", type=float, default=60.0, metavar="S",
                   help="length of the simulated capture [s]")
    p.add_argument("--seed", type=int, default=7, help="random seed of the simulation")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bars (the table is still printed)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion demo``."""
    result = run_demo(args.out, seconds=args.seconds, seed=args.seed, progress=not args.quiet,
                      force=args.force)
    print(table(result))
    return 0
