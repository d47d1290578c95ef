"""``ikfusion inspect``: what a recording holds."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from ..io.mtmanager import read_mtmanager
from ..rotations import matrix_to_quat_wxyz


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``inspect`` subcommand."""
    p = subparsers.add_parser(
        "inspect",
        help="what a recording holds (sensors, rows, lost packets, rate, channels)",
        description="Read MT Manager exports (a trial prefix, a folder or one file) and print, "
        "per sensor id: rows received, lost packets, rate, channels, coordinate system, and the "
        "first and last orientation as (w, x, y, z) quaternions.",
    )
    p.add_argument("path", metavar="PATH", help="trial prefix, folder or file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--rate", type=float, metavar="HZ",
                   help="sample rate when the files have no `// Update Rate:`")
    p.set_defaults(func=run)


def _quat(R: np.ndarray, valid: np.ndarray, last: bool) -> list[float] | None:
    idx = np.nonzero(valid)[0]
    if not len(idx):
        return None
    return [round(float(v), 6) for v in matrix_to_quat_wxyz(R[idx[-1] if last else idx[0]])]


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion inspect``."""
    recording = read_mtmanager(args.path, rate=args.rate)
    sensors: dict[str, dict[str, Any]] = {}
    for sid, s in recording.sensors.items():
        sensors[sid] = {
            "rows": s.rows, "lost": s.lost, "rate": recording.rate, "channels": s.channels,
            "coordinate_system": recording.coordinate_system,
            "first_quat_wxyz": _quat(s.R_world_sensor, s.valid, last=False),
            "last_quat_wxyz": _quat(s.R_world_sensor, s.valid, last=True),
        }
    if args.json:
        print(json.dumps({"sensors": sensors}, indent=2))
        return 0
    print(f"{len(sensors)} sensors at {recording.rate:g} Hz, {recording.time[-1]:.2f} s "
          f"(files in {recording.source_coordinate_system}, converted to ENU)")
    for sid, info in sensors.items():
        orientation = "orientation" if info["first_quat_wxyz"] else "no orientation"
        print(f"  {sid}: {info['rows']} rows, {info['lost']} lost, {orientation}, "
              f"{len(info['channels'])} channels")
    for warning in recording.warnings:
        print(f"warning: {warning}")
    return 0
