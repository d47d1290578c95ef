"""``ikfusion calibrate-uwb``: reader positions and clock offsets from a calibration log.

Reads a TOA log (SPEC section 4: the calibration tag inside each reader has the reader's id as
tag id, any other tag is the wand) and the reader heights, and writes the readers YAML
(SPEC section 3) with positions, clock offsets, a ``position_covariance`` per reader and the
calibration figures under ``metadata.calibration`` (residual RMS, outlier fraction, ...).
"""

from __future__ import annotations

import argparse
import json

from ..errors import InputError
from ..uwb.calibration import CalibrationOptions, calibrate


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``calibrate-uwb`` subcommand."""
    p = subparsers.add_parser(
        "calibrate-uwb",
        help="reader positions and clock offsets from a calibration log",
        description="Estimate reader positions (horizontal; heights given) and clock offsets "
        "from reader-to-reader transmissions and a wand swayed for about a minute: a first "
        "estimate from the reader tags, wand fixes, then the joint maximum-likelihood problem "
        "(IPOPT) with NLOS rejection. Writes the readers YAML with a position covariance per "
        "reader.",
    )
    p.add_argument("toa", metavar="TOA.csv", help="calibration log (time,tag,seq,reader,toa)")
    p.add_argument(
        "--heights", required=True, metavar="FILE", help="YAML 'heights: {<reader id>: z [m]}'"
    )
    p.add_argument("--out", required=True, metavar="readers.yaml", help="readers YAML to write")
    p.add_argument(
        "--survey",
        metavar="FILE",
        help="YAML 'points: {<reader id>: [x, y, z]}' of 2 or 3 surveyed readers: align the "
        "result to their frame",
    )
    p.add_argument("--sigma", type=float, metavar="M", help="range noise [m] (default: estimated)")
    p.add_argument("--origin", metavar="ID", help="reader at the origin (default: the first)")
    p.add_argument("--axis", metavar="ID", help="reader on the +x axis (default: the second)")
    p.add_argument(
        "--wand-only",
        action="store_true",
        help="use the reader-to-reader transmissions for the first estimate only",
    )
    p.add_argument("--plot", metavar="FILE.png", help="draw readers and wand path (matplotlib)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion calibrate-uwb``."""
    if args.sigma is not None and not args.sigma > 0:
        raise InputError(f"--sigma must be positive, got {args.sigma}", field="--sigma")
    options = CalibrationOptions(
        sigma=args.sigma, origin=args.origin, axis=args.axis, reader_links=not args.wand_only
    )
    result = calibrate(args.toa, args.heights, options, survey=args.survey)
    result.save(args.out)
    if args.plot:
        from ..uwb.calibration_plot import plot_calibration

        plot_calibration(result, args.plot)
    summary = result.summary()
    if args.json:
        print(json.dumps({**summary, "out": str(args.out)}, indent=2))
        return 0
    print(
        f"calibrated {summary['readers']} readers from {summary['wand_transmissions']} wand "
        f"transmissions in {summary['timings_s']['total']:.1f} s ({result.rounds} rounds)"
    )
    print(
        f"residual RMS {100 * result.residual_rms:.1f} cm, sigma {100 * result.sigma:.1f} cm, "
        f"outliers {100 * result.outliers.fraction:.1f} %, predicted reader error "
        f"{100 * result.predicted_rms:.1f} cm RMS"
    )
    print(f"frame: {result.frame}")
    for warning in result.warnings:
        print(f"warning: {warning}")
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0
