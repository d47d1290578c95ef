"""``ikfusion plan``: DOP maps of a reader constellation, and reader placement.

``ikfusion plan FILE.yaml`` draws the expected position sigma (range sigma x DOP) over the
capture area at one tag height and prints its summary. ``ikfusion plan FILE.yaml --optimize N``
chooses N reader positions among candidate mounting points (the area border at
``--mount-heights`` by default, plus the file's own readers) minimising the 95th-percentile
expected sigma. The search starts from the file's readers when there are N of them (else from a
naive layout evenly spaced along the border, and says so), never returns a layout worse than
that start, and reports "start -> optimised" on the same map grid.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..uwb import (
    Constellation,
    DopMap,
    capture_area,
    dop_map,
    load_constellation,
    make_constellation,
    optimize_placement,
    save_constellation,
)
from ..yaml_files import read_yaml
from .arg_types import positive_number


def _heights(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected heights like 0.5,2.5, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("give at least one height")
    return values


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``plan`` subcommand."""
    p = subparsers.add_parser(
        "plan",
        help="DOP maps of a reader constellation; reader placement",
        description="Draw the expected position sigma (range sigma x DOP) of a constellation "
        "over its capture area and print median, 95th percentile, max and the fraction under "
        "5 cm; with --optimize N, choose N reader positions that minimise the 95th percentile, "
        "starting from the file's readers when it has N of them (else from N readers evenly "
        "spaced on the area border); the result is never worse than that start.",
    )
    p.add_argument("constellation", metavar="CONSTELLATION.yaml", help="constellation YAML")
    p.add_argument("--height", type=float, default=1.5, metavar="M", help="tag height [m]")
    p.add_argument(
        "--mode",
        choices=("3d", "2d"),
        default="3d",
        help="3d: x, y, z unknown; 2d: tag height known (default %(default)s)",
    )
    p.add_argument(
        "--clock",
        choices=("free", "zero"),
        default="free",
        help="free: transmit time unknown (TOA, default); zero: two-way ranges",
    )
    p.add_argument("--step", type=positive_number, metavar="M", help="map grid spacing [m]")
    p.add_argument("--out", metavar="FILE.png", help="figure to write (default <name>_dop.png)")
    p.add_argument("--no-plot", action="store_true", help="print the numbers only")
    p.add_argument("--json", action="store_true", help="print the numbers as JSON")
    p.add_argument(
        "--no-reader-covariance",
        action="store_true",
        help="ignore the readers' position_covariance entries",
    )
    opt = p.add_argument_group("placement (--optimize)")
    opt.add_argument("--optimize", type=int, metavar="N", help="choose N reader positions")
    opt.add_argument(
        "--candidates",
        metavar="FILE",
        help="candidate mounting points: YAML 'candidates: [[x, y, z], ...]' or a "
        "constellation file (its readers); default: the area border",
    )
    opt.add_argument(
        "--mount-heights",
        type=_heights,
        default=[0.5, 2.5],
        metavar="Z1,Z2",
        help="heights of the default candidates and of the naive layout [m] (default 0.5,2.5)",
    )
    opt.add_argument(
        "--spacing",
        type=positive_number,
        default=1.0,
        metavar="M",
        help="spacing of the default candidates along the border [m] (default %(default)s)",
    )
    opt.add_argument(
        "--out-constellation", metavar="FILE.yaml", help="write the chosen constellation here"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion plan``."""
    if args.optimize is not None:
        return _run_optimize(args)
    constellation = load_constellation(args.constellation)
    m = _map(constellation, args)
    summary = m.summary()
    png = None
    if not args.no_plot:
        from ..uwb.plot import plot_dop_map

        png = plot_dop_map(
            m,
            constellation.positions,
            constellation.ids,
            args.out or f"{_stem(args.constellation)}_dop.png",
            name=constellation.name or _stem(args.constellation),
        )
    report = {
        "constellation": constellation.name,
        "file": str(args.constellation),
        "readers": len(constellation.readers),
        **_settings(constellation, args, m),
        "summary": summary.as_dict("cm"),
        "png": None if png is None else str(png),
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(_describe(f"{constellation.name} ({len(constellation.readers)} readers)", m, args))
        if png is not None:
            print(f"wrote {png}")
    return 0


def _run_optimize(args: argparse.Namespace) -> int:
    template = load_constellation(args.constellation, allow_empty=True)
    if template.area is None and len(template.readers) < 3:
        raise ConfigError(
            "placement needs a capture area: add 'area: [[x, y], ...]'",
            path=args.constellation,
            field="area",
        )
    area = capture_area(template)
    own = template.positions if template.readers else None
    from_own = own is not None and len(own) == args.optimize
    candidates = None if args.candidates is None else _load_candidates(Path(args.candidates))
    result = optimize_placement(
        area,
        args.optimize,
        start=own if from_own else None,
        candidates=candidates,
        mount_heights=args.mount_heights,
        spacing=args.spacing,
        height=args.height,
        mode=args.mode,
        clock=args.clock == "free",
        sigma=template.sigma,
        coverage=template.range,
        eval_step=args.step,
    )
    start_name = "your layout" if from_own else "naive perimeter layout"
    start_c = _layout(result.start, template, area, "start")
    chosen_c = _layout(result.chosen, template, area, f"{template.name or 'area'}_optimized")
    start_map, chosen_map = _map(start_c, args), _map(chosen_c, args)
    start_s, chosen_s = start_map.summary(), chosen_map.summary()
    naive_s = (
        start_s
        if not from_own
        else _map(_layout(result.naive, template, area, "naive"), args).summary()
    )
    own_s = None if own is None else _map(_layout(own, template, area, "own"), args).summary()
    written = None
    if args.out_constellation:
        written = save_constellation(chosen_c, args.out_constellation)
    png = None
    if not args.no_plot:
        from ..uwb.plot import plot_placement

        png = plot_placement(
            start_map,
            chosen_map,
            result.start,
            result.chosen,
            args.out or f"{_stem(args.constellation)}_placement.png",
            start_label=start_name,
        )
    gain = (
        100.0 * (1.0 - chosen_s.p95 / start_s.p95)
        if np.isfinite(start_s.p95) and np.isfinite(chosen_s.p95)
        else None
    )
    report: dict[str, Any] = {
        "file": str(args.constellation),
        "n": args.optimize,
        **_settings(template, args, chosen_map),
        "candidates": len(result.candidates),
        "layouts_scored": result.evaluations,
        "start": {
            "layout": "yours" if from_own else "naive",
            "readers": _rows(result.start),
            "summary": start_s.as_dict("cm"),
        },
        "yours": None
        if own is None
        else {"readers": _rows(own), "summary": None if own_s is None else own_s.as_dict("cm")},
        "naive": {"readers": _rows(result.naive), "summary": naive_s.as_dict("cm")},
        "optimized": {"readers": _rows(result.chosen), "summary": chosen_s.as_dict("cm")},
        "kept_start": result.kept_start,
        "p95_improvement_percent": None if gain is None else round(gain, 2),
        "png": None if png is None else str(png),
        "constellation_out": None if written is None else str(written),
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    if own is not None and not from_own and own_s is not None:
        print(
            f"your file has {len(own)} readers (p95 {_cm(own_s.p95)}); --optimize "
            f"{args.optimize} starts from a naive layout of {args.optimize} readers evenly "
            "spaced on the area border"
        )
    print(_describe(start_name, start_map, args))
    print(_describe(f"optimised ({len(result.candidates)} candidates)", chosen_map, args))
    change = "n/a" if gain is None else f"{gain:.1f} % lower"
    print(
        f"p95 expected sigma: {start_name} {_cm(start_s.p95)} -> optimised "
        f"{_cm(chosen_s.p95)} ({change})"
    )
    if result.kept_start:
        print(f"  no layout searched beats {start_name}; it is kept")
    for i, (x, y, z) in enumerate(result.chosen):
        print(f"  R{i + 1}: [{x:.2f}, {y:.2f}, {z:.2f}]")
    if written is not None:
        print(f"wrote {written}")
    if png is not None:
        print(f"wrote {png}")
    return 0


def _map(constellation: Constellation, args: argparse.Namespace) -> DopMap:
    return dop_map(
        constellation,
        height=args.height,
        mode=args.mode,
        clock=args.clock == "free",
        step=args.step,
        use_reader_covariance=not args.no_reader_covariance,
    )


def _layout(
    positions: np.ndarray, template: Constellation, area: np.ndarray, name: str
) -> Constellation:
    return make_constellation(
        positions, coverage=template.range, sigma=template.sigma, area=area, name=name
    )


def _settings(c: Constellation, args: argparse.Namespace, m: DopMap) -> dict[str, Any]:
    return {
        "mode": args.mode,
        "clock": args.clock,
        "height_m": args.height,
        "sigma_range_m": c.sigma,
        "range_m": c.range,
        "grid_step_m": round(float(m.x[1] - m.x[0]), 6) if m.x.size > 1 else None,
    }


def _describe(title: str, m: DopMap, args: argparse.Namespace) -> str:
    s = m.summary()
    mode = "3-D" if args.mode == "3d" else "2-D (known height)"
    clock = "unknown transmit time" if args.clock == "free" else "two-way ranges"
    return (
        f"{title}: {mode}, {clock}, tag at {args.height:.2f} m, "
        f"{s.points} area points\n"
        f"  expected position sigma: median {_cm(s.median)}, p95 {_cm(s.p95)}, "
        f"max {_cm(s.max)}; {100 * s.fraction_under_5cm:.1f} % of the area under 5 cm; "
        f"{100 * s.covered_fraction:.1f} % covered"
    )


def _cm(v: float) -> str:
    return f"{100 * v:.2f} cm" if np.isfinite(v) else "no fix"


def _rows(p: np.ndarray) -> list[list[float]]:
    return [[round(float(v), 4) for v in row] for row in p]


def _stem(path: str) -> str:
    return Path(path).stem


def _load_candidates(path: Path) -> np.ndarray:
    """Candidate mounting points from ``candidates: [[x, y, z], ...]`` or a constellation."""
    data = read_yaml(path, "candidates file")
    if isinstance(data, dict) and "candidates" in data:
        rows = data["candidates"]
        if not isinstance(rows, list) or not rows:
            raise ConfigError("expected a list of [x, y, z]", path=path, field="candidates")
        out = []
        for i, row in enumerate(rows):
            ok = isinstance(row, list) and len(row) == 3
            if ok:
                try:
                    vals = [float(v) for v in row]
                except (TypeError, ValueError):
                    ok = False
            if not ok or not np.all(np.isfinite(vals)):
                raise ConfigError(
                    f"expected [x, y, z] in metres, found {row!r}",
                    path=path,
                    field=f"candidates[{i}]",
                )
            out.append(vals)
        return np.array(out)
    return load_constellation(path).positions
