"""``ikfusion view``: the motion in the browser (works offline), or saved as an ``.rrd`` file."""

from __future__ import annotations

import argparse
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``view`` subcommand."""
    p = subparsers.add_parser(
        "view",
        help="show a result, a capture or a BVH in the browser (offline)",
        description="Show the body, floor, contact points, UWB readers and tag paths in 3-D "
        "with joint-angle curves, contact phases and solve time on one timeline (play, pause, "
        "scrub, speed). PATH is a `solve` result folder (or a folder of them: one actor each), "
        "a `simulate` capture folder (truth.npz), a `retarget` output (the robot with its "
        "URDF meshes) or a BVH file; the human is drawn as capsules, every curve is named and "
        "coloured apart. Uses Rerun's web viewer, "
        "served from the installed package (pip install 'ikfusion[view]').",
    )
    p.add_argument("path", metavar="PATH", help="result folder, capture folder or .bvh file")
    p.add_argument("--truth", metavar="TRUTH.npz", help="draw this truth as a ghost")
    p.add_argument("--readers", metavar="FILE",
                   help="UWB constellation YAML (default: readers.yaml next to PATH)")
    p.add_argument("--port", type=int, default=9090,
                   help="HTTP port of the viewer page (default 9090)")
    p.add_argument("--host", default="127.0.0.1",
                   help="interface the viewer listens on (default 127.0.0.1: this machine "
                   "only; the page has no password, so give 0.0.0.0 only to show the motion "
                   "to every machine of a trusted network)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    p.add_argument("--save", metavar="FILE.rrd",
                   help="write a Rerun recording instead of serving; open it with `rerun FILE` "
                   "or drop it on any Rerun viewer")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion view``."""
    from ..view.draw import require_rerun
    from ..view.load import load_scene
    from ..view.serve import save_recording, serve

    require_rerun()
    scene = load_scene(args.path, truth=args.truth, readers=args.readers)
    actors = ", ".join(f"{a.name} ({a.frames} frames, {a.duration:.2f} s)" for a in scene.actors)
    print(f"ikfusion view: {actors}", file=sys.stderr)
    for note in scene.notes:
        if note.startswith("warning: ") or ": warning: " in note:
            print(f"ikfusion view: {note}", file=sys.stderr)
    if args.save:
        out = save_recording(scene, args.save)
        print(f"wrote {out}")
        return 0

    def announce(url: str) -> None:
        print(f"viewer at {url}", flush=True)
        print("press Ctrl+C to stop", file=sys.stderr, flush=True)

    try:
        serve(scene, port=args.port, open_browser=not args.no_browser, announce=announce,
              host=args.host)
    except KeyboardInterrupt:
        return 0
    return 0
