"""``ikfusion model``: describe the human model of a body, and write its URDF."""

from __future__ import annotations

import argparse
import json

from ..model import Body, HumanModel
from ..model.urdf import write_urdf


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``model`` subcommand."""
    p = subparsers.add_parser(
        "model",
        help="describe the human model of a body; write its URDF",
        description="Build the 23-segment human model of a body (from --body FILE or --height M; "
        "the shipped 1.75 m subject otherwise), print its summary, and optionally write the URDF.",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--body", metavar="FILE", help="body file (YAML, SPEC section 2)")
    src.add_argument("--height", type=float, metavar="M", help="body height [m]")
    p.add_argument("--urdf", metavar="FILE", help="write the generated URDF here")
    p.add_argument("--json", action="store_true", help="print the resolved dimensions as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion model``."""
    if args.body:
        body = Body.from_yaml(args.body)
    elif args.height is not None:
        body = Body.from_height(args.height)
    else:
        body = None
    if args.urdf:
        write_urdf(body or Body(), args.urdf)
        model = HumanModel(args.urdf, body=body or Body())
    else:
        model = HumanModel.from_body(body) if body is not None else HumanModel.default()
    if args.json:
        print(json.dumps({"body": model.body.to_dict() if model.body else None,
                          "nq": model.model.nq, "nv": model.model.nv,
                          "segments": model.segment_names, "joints": model.joint_names,
                          "sites": model.site_names}, indent=2))
    else:
        print(model.summary())
    return 0
