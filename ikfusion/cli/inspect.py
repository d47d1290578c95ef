"""``ikfusion inspect``: what a recording holds.

For every sensor: rows received, packets lost inside its PacketCounter span, the rate, the
channels (column names), the coordinate system of the orientations shown (ENU after reading)
and the first and last received orientation as (w, x, y, z) quaternions (``w >= 0``). ``--json``
prints ``{"sensors": {"<id>": {"rows", "lost", "rate", "rate_source", "channels",
"coordinate_system", "first_quat_wxyz", "last_quat_wxyz"}}}`` (SPEC section 5 plus
``rate_source``: where the rate came from); warnings go to standard error. Without it a table
is printed, warnings below it. A recording whose rate nothing tells is still shown, with the
rate ``null`` (JSON) or ``unknown`` and the spans in samples.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from ..io.reader import read_imu
from ..io.recording import ImuRecording, SensorStream
from ..io.sensor_map import load_sensor_map


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``inspect`` subcommand."""
    p = subparsers.add_parser(
        "inspect",
        help="what a recording holds (sensors, rows, lost packets, rate, channels)",
        description="Read an IMU recording (MT Manager exports given by a trial prefix, a "
        "folder or one file; a generic IMU .csv; an .mvnx) and print, per sensor id: rows "
        "received, packets lost, rate and where it came from (the `// Update Rate:` line, the "
        "SampleTimeFine or UTC columns, or --rate), channels, coordinate system, and the first "
        "and last orientation as (w, x, y, z) quaternions. Without a rate in the files or "
        "--rate, everything else is still shown.",
    )
    p.add_argument("path", metavar="PATH", help="trial prefix, folder or file")
    p.add_argument("--json", action="store_true", help="print one JSON object (SPEC layout)")
    p.add_argument("--rate", type=float, metavar="HZ",
                   help="sample rate when the files tell none (no `// Update Rate:` line, no "
                   "SampleTimeFine or UTC time values)")
    p.add_argument("--map", metavar="FILE",
                   help="sensor map (YAML or OpenSense XML): check that its sensors are there, "
                        "show their segments")
    p.set_defaults(func=run)


def _quat(stream: SensorStream, last: bool) -> list[float] | None:
    idx = np.flatnonzero(stream.orientation_valid)
    if not len(idx):
        return None
    q = stream.quat_wxyz(int(idx[-1] if last else idx[0]))
    return [round(float(v), 7) for v in q]


def summary(recording: ImuRecording) -> dict[str, Any]:
    """The JSON object of ``inspect --json`` (SPEC section 5)."""
    sensors: dict[str, dict[str, Any]] = {}
    for sid, s in recording.sensors.items():
        sensors[sid] = {
            "rows": int(s.rows), "lost": int(s.lost),
            "rate": float(recording.rate) if recording.rate_known else None,
            "rate_source": recording.rate_source or "unknown",
            "channels": list(s.channels), "coordinate_system": recording.coordinate_system,
            "first_quat_wxyz": _quat(s, last=False), "last_quat_wxyz": _quat(s, last=True),
        }
    return {"sensors": sensors}


def _channel_groups(stream: SensorStream) -> str:
    groups = [name for name in ("acc", "free_acc", "gyr", "mag")
              if getattr(stream, name) is not None]
    if stream.orientation_source:
        groups.append(stream.orientation_source.lower())
    return " ".join(groups) or "-"


def _format_quat(q: list[float] | None) -> str:
    return "-" if q is None else " ".join(f"{v:+.4f}" for v in q)


def table(recording: ImuRecording, segments: dict[str, str] | None = None) -> str:
    """A readable table of the recording."""
    source = recording.source
    where = source[0].parent if source else "?"
    known = recording.rate_known
    origin = {"Update Rate": "the // Update Rate: line", "--rate": "--rate"}.get(
        recording.rate_source, f"{recording.rate_source or 'the reader'}")
    timing = (f"{recording.rate:g} Hz, {len(recording)} samples ({recording.duration:.2f} s)"
              if known else f"rate unknown (give --rate HZ), {len(recording)} samples")
    lines = [f"{len(recording.sensors)} sensor(s) from {len(source)} file(s) in {where}",
             f"{timing}, world {recording.coordinate_system} (files: "
             f"{recording.source_coordinate_system})" + (f", rate from {origin}" if known else ""),
             ""]
    head = ["sensor", "segment", "rows", "lost", "span [s]" if known else "span [samples]",
            "channels", "first quat (w x y z)", "last quat (w x y z)"]
    rows = []
    for sid, s in recording.sensors.items():
        first, end = s.span
        last = max(end - 1, 0)
        span = (f"{first / recording.rate:.2f}-{last / recording.rate:.2f}" if known
                else f"{first}-{last}")
        rows.append([sid, (segments or {}).get(sid, "-"), str(s.rows), str(s.lost), span,
                     _channel_groups(s), _format_quat(_quat(s, False)),
                     _format_quat(_quat(s, True))])
    if segments is None:
        head.pop(1)
        for r in rows:
            r.pop(1)
    widths = [max(len(h), *(len(r[k]) for r in rows)) for k, h in enumerate(head)]
    numeric = {"rows", "lost"}
    for r in [head, *rows]:
        lines.append("  ".join(v.rjust(w) if head[k] in numeric else v.ljust(w)
                               for k, (v, w) in enumerate(zip(r, widths))).rstrip())
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion inspect``."""
    sensor_map = load_sensor_map(args.map) if args.map else None
    recording = read_imu(args.path, rate=args.rate, sensor_map=sensor_map, require_rate=False)
    if not recording.rate_known:
        recording.warnings.append("the sample rate is unknown: the files have no `// Update "
                                  "Rate:` line and no SampleTimeFine or UTC time values; give "
                                  "it with --rate HZ (spans are shown in samples)")
    if args.json:
        print(json.dumps(summary(recording), indent=2))
        for warning in recording.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        return 0
    segments = None if sensor_map is None else {
        sid: seg for sid, seg in sensor_map.items()}
    print(table(recording, segments))
    for warning in recording.warnings:
        print(f"warning: {warning}")
    return 0
