"""``ikfusion simulate``: a capture in the real input formats, with its ground truth."""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from ..output_folders import check_output_folder
from ..sim.area_fit import DEFAULT_MARGIN, place_in_area
from ..sim.capture import truth_motion, write_capture
from ..sim.gait import GAIT_PRESETS
from ..sim.imu import ImuNoise
from ..uwb.constellation import load_constellation
from ..uwb.dop import capture_area
from . import add_force_option


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` subcommand."""
    p = subparsers.add_parser(
        "simulate",
        help="simulate a capture (MT Manager files, sensor map, body, truth.npz)",
        description="Simulate 17 body-worn IMUs (random mountings, orientation noise and "
        "heading wander, specific force and rate) on a procedural walk or a BVH clip, and write "
        "imu/ (MT Manager files), sensors.yaml, body.yaml and truth.npz.",
    )
    p.add_argument("--motion", default="gait", metavar="gait|gait:WALK|FILE.bvh",
                   help="procedural walk (in circles by default; WALK is one of "
                   f"{', '.join(GAIT_PRESETS)}) or a BVH clip (.bvh or gzip-compressed .bvh.gz)")
    p.add_argument("--seconds", type=float, default=30.0, metavar="S",
                   help="length of a procedural walk [s]")
    p.add_argument("--rate", type=float, default=60.0, metavar="HZ", help="sensor rate [Hz]")
    p.add_argument("--noise", choices=["default", "none"], default="default",
                   help="sensor errors (none: perfect sensors)")
    p.add_argument("--readers", metavar="FILE",
                   help="UWB constellation YAML; the motion is turned about z and moved so its "
                   "ground track lies inside the constellation's area (else the readers' "
                   "footprint) with a margin, and a warning says when it cannot fit")
    p.add_argument("--margin", type=float, default=DEFAULT_MARGIN, metavar="M",
                   help="clearance of the ground track from the area border with --readers "
                   "[m] (default %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="random seed")
    p.add_argument("--out", required=True, metavar="DIR", help="capture folder")
    add_force_option(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion simulate``."""
    if args.margin < 0:
        raise InputError(f"--margin must not be negative, got {args.margin}", field="margin")
    if args.rate <= 0 or args.seconds <= 2.5:
        raise InputError("--rate must be positive and --seconds above 2.5 (2 s of N-pose "
                         "come first)", field="seconds")
    check_output_folder(args.out, args.force)  # before the simulation, not after it
    truth = truth_motion(args.motion, args.seconds, args.rate, progress=not args.quiet)
    noise = ImuNoise() if args.noise == "default" else ImuNoise.none()
    constellation = load_constellation(args.readers) if args.readers else None
    if constellation is not None:
        truth, fit = place_in_area(truth, capture_area(constellation), args.margin)
        print(fit.describe())
        if not fit.fits:
            print(f"warning: {truth.source} does not fit inside the capture area of "
                  f"{args.readers} with a {fit.margin:g} m margin: "
                  f"{100 * fit.inside_after:.0f} % of its ground track is inside, the rest "
                  f"reaches {max(-fit.clearance, 0.0):.2f} m beyond the border; the readers "
                  "cover it less well there", file=sys.stderr)
    capture = write_capture(args.out, truth, noise, args.seed, constellation=constellation,
                            force=args.force)
    print(f"wrote {capture.folder}: {len(truth.time)} samples at {truth.rate:g} Hz from "
          f"{truth.source}")
    for warning in truth.info.get("warnings", []):  # bad samples bridged in a BVH source
        print(f"ikfusion simulate: warning: {warning}", file=sys.stderr)
    return 0
