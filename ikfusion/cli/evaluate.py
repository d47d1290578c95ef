"""``ikfusion evaluate``: accuracy of a solve against the truth of a simulated capture."""

from __future__ import annotations

import argparse
import json
import sys

from ..app.evaluate import evaluate
from ..uwb.constellation import load_constellation


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``evaluate`` subcommand."""
    p = subparsers.add_parser(
        "evaluate",
        help="accuracy metrics of a result folder against truth.npz",
        description="Compare a `solve` result folder with the truth.npz of `simulate`: joint "
        "angles, segment orientations, head position, foot slide, held-contact slide and contact "
        "agreement, the largest frame-to-frame "
        "joint-angle jump (SPEC section 6).",
    )
    p.add_argument("result", metavar="RESULT_DIR", help="result folder of `ikfusion solve`")
    p.add_argument("truth", metavar="TRUTH.npz", help="truth file of `ikfusion simulate`")
    p.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    p.add_argument("--align", choices=["auto", "start", "none"], default="auto",
                   help="shift the estimate to the true start position (auto: only without UWB)")
    p.add_argument("--plot", metavar="DIR", nargs="?", const="", default=None,
                   help="write trajectory.png (HeadTop top view as scored, i.e. with the "
                   "same start alignment, readers and capture area when known) and "
                   "joint_angles.png (hip, knee, ankle, shoulder flexion, both sides) into DIR, "
                   "default the result folder; needs matplotlib")
    p.add_argument("--readers", metavar="FILE",
                   help="constellation drawn on the plot (default: the one summary.json names)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion evaluate``."""
    result = evaluate(args.result, args.truth, align=args.align)
    metrics = result.as_dict()
    if args.plot is not None:
        from ..app.evaluate_plot import plot_evaluation

        readers = load_constellation(args.readers) if args.readers else None
        for path in plot_evaluation(args.result, args.truth, args.plot or args.result,
                                    evaluation=result, readers=readers):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        print(json.dumps(metrics, indent=2))
        return 0
    rows = [
        ("frames", f"{result.frames}"),
        ("joint angle RMS", f"{result.joint_angle_rms_deg:.2f} deg"),
        ("segment orientation RMS", f"{result.segment_orientation_rms_deg:.2f} deg"),
        ("head position RMS (3-D)", f"{100 * result.head_position_rms_m:.1f} cm"),
        ("head position RMS (horizontal)", f"{100 * result.head_position_rms_xy_m:.1f} cm"),
        ("foot slide per contact (mean / max)",
         f"{result.foot_slide_mm:.1f} / {result.foot_slide_max_mm:.1f} mm (the truth's own "
         f"{result.truth_slide_mm:.1f} mean; beyond the truth's "
         + ("-" if result.foot_slide_excess_mm is None
            else f"{result.foot_slide_excess_mm:.1f}") + " mean, "
         + ("-" if result.foot_slide_excess_on_floor_mm is None
            else f"{result.foot_slide_excess_on_floor_mm:.1f}")
         + " where the truth lies on the floor)"),
        ("slide of held contacts (mean / max)",
         f"{result.held_slide_mm:.1f} / {result.held_slide_max_mm:.1f} mm (the true points "
         f"{result.held_truth_slide_mm:.1f} mean)"),
        ("contact agreement with truth",
         f"{result.contact_agreement_pct:.1f} % ({result.contact_missed_pct:.1f} % of planted "
         "samples missed)"),
        ("largest joint-angle jump vs truth",
         f"{result.joint_angle_jump_max_deg:.2f} deg/frame ({result.joint_angle_jump_at})"),
        ("largest joint turn in one frame", f"{result.joint_angle_step_max_deg:.2f} deg"),
        ("drift (pelvis, % of distance)", "-" if result.drift_percent is None
         else f"{result.drift_percent:.2f} %"),
        ("stride loss (pelvis, % short per step)", "-" if result.stride_loss_percent is None
         else f"{result.stride_loss_percent:.2f} %"),
        ("start aligned to truth", "yes" if result.aligned_start else "no"),
    ]
    width = max(len(r[0]) for r in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    return 0
