"""``ikfusion solve``: an IMU recording (or a session of actors) to result folders (SPEC 6)."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from ..app.session import ActorInputs, load_session, solve_actor, solve_session
from ..app.uwb_aiding import UwbInputs
from ..errors import InputError
from . import add_force_option


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``solve`` subcommand."""
    p = subparsers.add_parser(
        "solve",
        help="solve an IMU recording into full-body motion",
        description="Calibrate sensor-to-segment on the still pose at the start (the body heading "
        "is found from the first knee movements; no sensor mounting is assumed), solve every "
        "frame, and write the result folder (motion.bvh, joint_angles.csv, segments.csv, "
        "sites.csv, contacts.csv, summary.json).",
    )
    p.add_argument("--imu", metavar="PATH", help="MT Manager trial prefix, "
                   "folder or file, an IMU CSV or an MVNX file")
    p.add_argument("--map", metavar="FILE", help="sensor map: YAML or OpenSense's mapping XML "
                   "(not needed for an MVNX file, whose sensors are named by segment)")
    p.add_argument("--session", metavar="FILE", help="several actors in one world frame: a "
                   "YAML naming each actor's recording, map and body and the shared UWB files "
                   "(instead of --imu/--map); one result folder per actor under --out")
    body = p.add_mutually_exclusive_group()
    body.add_argument("--body", metavar="FILE", help="body dimensions YAML")
    body.add_argument("--height", type=float, metavar="M", help="body height [m]")
    p.add_argument("--calibrate", default="auto", metavar="auto|T0:T1|npose|tpose",
                   help="calibration window (auto: the stillest second at the start) or pose")
    p.add_argument("--forward", metavar="SEGMENT:AXIS",
                   help="the sensor axis that points forward, e.g. Pelvis:-z (overrides the "
                   "heading found from the data)")
    p.add_argument("--rate", type=float, metavar="HZ", help="rate for files without one")
    p.add_argument("--toa", metavar="FILE", help="UWB TOA CSV (needs --readers and --tags)")
    p.add_argument("--readers", metavar="FILE", help="UWB constellation YAML")
    p.add_argument("--tags", metavar="FILE", help="UWB tags YAML")
    p.add_argument("--correction", choices=["off", "slide", "no-slide"], default=None,
                   help="how UWB corrects drift")
    p.add_argument("--causal", action="store_true",
                   help="use the past only at each instant, as live: the UWB tag filters are "
                        "not smoothed backward, and a sensor's lost samples are bridged by "
                        "holding it relative to its neighbour and blending it back in when it "
                        "returns (by default the whole recording is used: tags smoothed, gaps "
                        "interpolated across)")
    p.add_argument("--bvh-up", choices=["z", "y"], default="z", help="up axis of motion.bvh")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="result folder (with --session: the folder of the actors' folders)")
    add_force_option(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


#: Warning of a ``--correction`` given without UWB files.
NO_UWB_CORRECTION = "--correction has no effect without UWB (--toa/--readers/--tags)"


def parse_calibrate(text: str) -> tuple[tuple[float, float] | None, str]:
    """``--calibrate`` as (window [s] or None for automatic, pose ``npose``/``tpose``).

    Raises:
        InputError: Not ``auto``, ``npose``, ``tpose`` or ``T0:T1`` [s] with 0 <= T0 < T1.
    """
    if text in ("auto", "npose"):
        return None, "npose"
    if text == "tpose":
        return None, "tpose"
    try:
        t0, t1 = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"--calibrate must be auto, npose, tpose or T0:T1 in seconds, not "
                         f"{text!r}", field="calibrate") from None
    if not 0 <= t0 < t1:
        raise InputError("--calibrate T0:T1 needs 0 <= T0 < T1", field="calibrate")
    return (t0, t1), "npose"


def _uwb_files(args: argparse.Namespace) -> UwbInputs | None:
    given = [args.toa, args.readers, args.tags]
    if not any(given):
        return None
    if not all(given):
        raise InputError("UWB aiding needs all of --toa, --readers and --tags", field="toa")
    return UwbInputs(Path(args.toa), Path(args.readers), Path(args.tags),
                     smooth=not args.causal)


def parse_forward(text: str | None) -> dict[str, str] | None:
    """``--forward SEGMENT:AXIS`` as ``{segment: axis}`` (None when not given).

    Raises:
        InputError: Not of the form ``SEGMENT:AXIS``.
    """
    if not text:
        return None
    if ":" not in text:
        raise InputError("--forward must be SEGMENT:AXIS, e.g. Pelvis:-z", field="forward")
    segment, axis = text.split(":", 1)
    return {segment: axis}


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion solve``."""
    if args.session:
        return _run_session(args)
    if not args.imu:
        raise InputError("give --imu and --map (or --session FILE)", field="imu")
    if not args.map and Path(args.imu).suffix.lower() != ".mvnx":
        raise InputError("give --map (only an MVNX file solves without one)", field="map")
    files = _uwb_files(args)
    if files is None and args.correction:
        print(f"warning: {NO_UWB_CORRECTION}", file=sys.stderr)
    window, pose = parse_calibrate(args.calibrate)
    actor = ActorInputs(None, Path(args.imu), Path(args.map) if args.map else None,
                        Path(args.body) if args.body else None, args.height, window, pose,
                        parse_forward(args.forward), args.rate, args.causal)
    motion = solve_actor(actor, args.out, files, args.correction, args.bvh_up,
                         progress=not args.quiet, force=args.force)
    for warning in motion.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"wrote {args.out}: {len(motion)} frames at {motion.rate:g} Hz")
    return 0


def _run_session(args: argparse.Namespace) -> int:
    """``solve --session FILE``: every actor into ``--out/<actor>``."""
    clash = [o for o in ("imu", "map", "body", "height", "toa", "readers", "tags")
             if getattr(args, o) is not None]
    if clash:
        raise InputError(f"--session names every file; drop --{clash[0]}", field=clash[0])
    session = load_session(args.session)
    if args.correction:
        session.correction = args.correction
    if args.causal:
        session.actors = [replace(a, causal=True) for a in session.actors]
        if session.uwb is not None:
            session.uwb = replace(session.uwb, smooth=False)
    motions = solve_session(session, args.out, args.bvh_up, progress=not args.quiet,
                            force=args.force)
    for name, motion in motions.items():
        for warning in motion.warnings:
            print(f"warning: {name}: {warning}", file=sys.stderr)
        print(f"wrote {Path(args.out) / name}: {len(motion)} frames at {motion.rate:g} Hz")
    return 0
