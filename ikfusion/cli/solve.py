"""``ikfusion solve``: an IMU recording to the result folder of SPEC section 6."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..correction import DriftCorrection
from ..errors import InputError
from ..ik import Solver
from ..imu.calibration import calibrate_recording
from ..io.reader import read_imu
from ..io.sensor_map import load_sensor_map
from ..model import Body, HumanModel
from ..pipeline import solve_recording
from ..results import write_result_folder
from ..uwb_aiding import UwbInputs, drift_correction, track_recording_tags, uwb_summary


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
    p.add_argument("--imu", required=True, metavar="PATH", help="MT Manager trial prefix, "
                   "folder or file, an IMU CSV or an MVNX file")
    p.add_argument("--map", required=True, metavar="FILE", help="sensor map YAML")
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
    p.add_argument("--bvh-up", choices=["z", "y"], default="z", help="up axis of motion.bvh")
    p.add_argument("--out", required=True, metavar="DIR", help="result folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def parse_calibrate(text: str, rate: float) -> tuple[tuple[int, int] | None, str]:
    """``--calibrate`` as (sample window or None for automatic, pose ``npose``/``tpose``).

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
    return (int(round(t0 * rate)), int(round(t1 * rate))), "npose"


def _uwb_files(args: argparse.Namespace) -> UwbInputs | None:
    given = [args.toa, args.readers, args.tags]
    if not any(given):
        return None
    if not all(given):
        raise InputError("UWB aiding needs all of --toa, --readers and --tags", field="toa")
    return UwbInputs(Path(args.toa), Path(args.readers), Path(args.tags))


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
    files = _uwb_files(args)
    sensor_map = load_sensor_map(args.map)
    recording = read_imu(args.imu, rate=args.rate, sensor_map=sensor_map)
    if args.body:
        model = HumanModel.from_body(Body.from_yaml(args.body))
    elif args.height is not None:
        model = HumanModel.from_body(Body.from_height(args.height))
    else:
        model = HumanModel.default()
    window, pose = parse_calibrate(args.calibrate, recording.rate)
    window_s = None if window is None else (window[0] / recording.rate,
                                            window[1] / recording.rate)
    cal = calibrate_recording(recording, sensor_map, window_s,
                              forward=parse_forward(args.forward), pose=pose)
    correction: DriftCorrection | None = None
    uwb: dict[str, object] = {"used": False}
    if files is not None:
        tags, tracks = track_recording_tags(recording, sensor_map, model, cal, files)
        correction = drift_correction(tags, tracks, recording.time,
                                      args.correction or "no-slide")
    elif args.correction:
        print("warning: --correction has no effect without UWB (--toa/--readers/--tags)",
              file=sys.stderr)
    result = solve_recording(recording, sensor_map, model, solver=Solver(model),
                             progress=not args.quiet, correction=correction, calibration=cal)
    if files is not None and correction is not None:
        uwb = uwb_summary(tracks, correction)
    write_result_folder(result.motion, args.out, bvh_up=args.bvh_up, extra_summary={
        "calibration": {"method": cal.method, "heading_deg": float(np.degrees(cal.heading)),
                        "window_s": [cal.window[0] / recording.rate,
                                     cal.window[1] / recording.rate]},
        "uwb": uwb,
    })
    for warning in result.motion.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"wrote {args.out}: {len(result.motion)} frames at {recording.rate:g} Hz")
    return 0
