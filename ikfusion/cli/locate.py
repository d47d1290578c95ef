"""``ikfusion locate``: UWB-only fixes per transmission from a TOA log.

Writes ``time,tag,seq,x,y,z,clock,used,rejected,status`` (SPEC section 5), one row per
transmission in time order:

- ``time``: earliest reception time of the transmission [s];
- ``x,y,z``: the fix [m] (``z`` is the given height with ``--height``), blank without a fix;
- ``clock``: the estimated transmit time tau [m] (0 with ``--clock zero``);
- ``used`` / ``rejected``: reader ids separated by ``;`` (ids, not counts, so a reader that is
  often rejected can be found; the counts are the number of ids);
- ``status``: ``ok``; ``too_few_readers`` (fewer receptions than unknowns: 4 in 3-D, 3 with
  ``--height``); ``rejected`` (still inconsistent after NLOS rejection, or so many receptions
  rejected that another set of late receptions would explain the data as well);
  ``diverged``; ``bad_geometry`` (the readers heard cannot fix the unknowns, e.g. all in one
  plane with the tag in 3-D); ``outside_area`` / ``bad_height`` (the fix lies far outside the
  constellation's area, under the floor or far above the readers: :mod:`ikfusion.uwb.bounds`).

Exit 2 (bad input, nothing written) when no transmission has a usable fix; a warning on stderr
when more than :data:`BAD_SHARE_WARNING` of them have none, or when any fix lies outside.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from ..errors import InputError
from ..uwb import (
    LocateOptions,
    estimate_range_sigma,
    group_transmissions,
    load_constellation,
    locate_transmissions,
    read_toa_csv,
    write_fixes_csv,
)
from ..uwb.locate import Fixes
from .arg_types import positive_number

#: Share of transmissions without a usable fix above which ``locate`` warns (clean simulated
#: walks in room_6x8 have about 0.013 of them: NLOS and geometry at the edges).
BAD_SHARE_WARNING = 0.1


def _sigma(text: str) -> float | str:
    return text if text == "auto" else positive_number(text, "metres or 'auto'")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``locate`` subcommand."""
    p = subparsers.add_parser(
        "locate",
        help="UWB-only fixes per transmission from a TOA log",
        description="Solve every transmission of a TOA log for the tag position and its "
        "transmit time (weighted Gauss-Newton from a closed-form start), rejecting late (NLOS) "
        "receptions, and write one row per transmission: "
        "time,tag,seq,x,y,z,clock,used,rejected,status. used/rejected list reader ids "
        "separated by ';'. A fix far outside the constellation's area (or its readers' hull), "
        "under the floor or far above the readers is outside_area/bad_height, not ok. Exit 2, "
        "writing nothing, when no transmission has a usable fix.",
    )
    p.add_argument("toa", metavar="TOA.csv", help="TOA log (columns time,tag,seq,reader,toa)")
    p.add_argument("--readers", required=True, metavar="FILE", help="constellation YAML")
    p.add_argument(
        "--height",
        type=float,
        metavar="M",
        help="known tag height [m]: solve x, y only (3 readers suffice instead of 4)",
    )
    p.add_argument(
        "--clock",
        choices=("free", "zero"),
        default="free",
        help="free: estimate the transmit time (TOA, default); zero: the toa values are "
        "two-way ranges with no transmit time",
    )
    p.add_argument(
        "--sigma",
        type=_sigma,
        metavar="M|auto",
        help="range noise [m] (default: the constellation's sigma); 'auto' estimates it "
        "from the log, recommended for real ranges",
    )
    p.add_argument("--no-nlos", action="store_true", help="keep every reception (no rejection)")
    p.add_argument(
        "--threshold",
        type=float,
        default=LocateOptions.threshold,
        metavar="K",
        help="reject receptions more than K sigma late (default %(default)s)",
    )
    p.add_argument("--out", required=True, metavar="FILE.csv", help="fix CSV to write")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion locate``."""
    if args.threshold <= 0:
        raise InputError(f"--threshold must be positive, got {args.threshold}")
    constellation = load_constellation(args.readers)
    start = time.perf_counter()
    log = read_toa_csv(args.toa)
    transmissions = group_transmissions(log, constellation.ids)
    read_s = time.perf_counter() - start
    sigma = args.sigma
    source = "option" if sigma is not None else "constellation"
    if sigma == "auto":
        sigma = estimate_range_sigma(
            transmissions.toa, constellation, height=args.height, clock=args.clock
        )
        source = "estimated from the log"
    options = LocateOptions(
        height=args.height,
        clock=args.clock,
        sigma=sigma,
        reject_nlos=not args.no_nlos,
        threshold=args.threshold,
    )
    start = time.perf_counter()
    fixes = locate_transmissions(transmissions, constellation, options)
    solve_s = time.perf_counter() - start
    counts = fixes.status_counts()
    warnings = _check_fixes(fixes, counts, args.toa)
    write_fixes_csv(args.out, transmissions, fixes)
    used = fixes.used[fixes.ok].sum(axis=1)
    heard = int(np.isfinite(transmissions.toa).sum())
    summary = {
        "transmissions": len(transmissions),
        "tags": sorted({str(t) for t in transmissions.tag}),
        "receptions": heard,
        "missed_rows": log.missed,
        "status": counts,
        "rejected_receptions": int(fixes.rejected.sum()),
        "median_readers_used": float(np.median(used)) if used.size else None,
        "sigma_m": float(constellation.sigma if sigma is None else sigma),
        "sigma_source": source,
        "mode": "2d" if args.height is not None else "3d",
        "clock": args.clock,
        "read_s": round(read_s, 3),
        "solve_s": round(solve_s, 3),
        "out": str(args.out),
        "warnings": warnings,
    }
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    n = len(transmissions)
    status = ", ".join(f"{k} {v}" for k, v in counts.items() if v or k == "ok")
    print(
        f"located {n} transmissions of {len(summary['tags'])} tag(s) in {solve_s:.2f} s "
        f"(read {read_s:.2f} s): {status}"
    )
    print(
        f"range sigma {summary['sigma_m']:.3f} m ({source}); rejected receptions "
        f"{summary['rejected_receptions']} of {heard}; median readers per fix "
        f"{summary['median_readers_used']}"
    )
    print(f"wrote {args.out}")
    return 0


def _check_fixes(fixes: Fixes, counts: dict[str, int], toa: str) -> list[str]:
    """The warnings about the fixes.

    Raises:
        InputError: No transmission has a usable fix (the readers do not fit the log).
    """
    n = len(fixes)
    bad = n - counts["ok"]
    listed = ", ".join(f"{k} {v}" for k, v in counts.items() if v)
    if counts["ok"] == 0:
        raise InputError(
            f"no usable fix in {n} transmissions ({listed or 'no transmission'}): check that "
            "the readers file (ids, positions, clock offsets) belongs to this log",
            path=toa,
        )
    warnings = []
    outside = counts["outside_area"] + counts["bad_height"]
    if bad > BAD_SHARE_WARNING * n or outside:
        warnings.append(
            f"{bad} of {n} transmissions have no usable fix ({listed}); fixes outside the "
            f"capture area or height: {outside}"
        )
    return warnings
