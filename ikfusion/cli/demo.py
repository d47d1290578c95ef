"""``ikfusion demo``: the main job on embedded data.

Until the simulation and solver land, the demo builds the default human model and prints its
summary (a user's first check that the installation works).
"""

from __future__ import annotations

import argparse

from ..model import HumanModel


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand."""
    p = subparsers.add_parser(
        "demo",
        help="run the main job on embedded data",
        description="Simulate a capture, solve it, write the results and print accuracy and speed.",
    )
    p.add_argument("--out", default="ikfusion-demo", metavar="DIR", help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion demo``."""
    model = HumanModel.default()
    print(model.summary())
    return 0
