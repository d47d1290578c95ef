"""Plots of an evaluation: top-view trajectories (truth vs estimate) and joint angles.

The plots show what :func:`ikfusion.app.evaluate.evaluate` scored: the estimate carries the same
start shift as the metrics (none when the result was not aligned, e.g. UWB results in the
readers' frame) and the legend says which. The top view draws the readers and the capture area
when they are known (``summary.json``'s ``uwb.readers`` file, or ``readers=``), on equal axes
whose limits cover truth, estimate, readers and area with a margin; the figure takes the shape
of that box within 1:3 and 3:1, so a straight walk is not a thin strip. ``joint_angles.png``
shows hip, knee, ankle and shoulder flexion of both sides.

Matplotlib is an optional extra (``pip install ikfusion[plot]``); it is imported only here.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.truth_npz import read_truth
from ..uwb.constellation import Constellation, load_constellation
from ..uwb.dop import capture_area
from .evaluate import Evaluation, _floats, _interp, _long_table, _read_table, evaluate

#: Flexion angles drawn per side, top to bottom.
JOINT_FLEXIONS = ("Hip_flex", "Knee_flex", "Ankle_flex", "Shoulder_flex")
#: Widest and tallest figure shape (width / height) of the top view.
_MAX_SHAPE = 3.0


@dataclass(frozen=True)
class TrajectoryView:
    """What ``trajectory.png`` draws (world frame, top view, metres).

    Attributes:
        time: Scored sample times, shape (N,) [s].
        truth_xy: True HeadTop x, y, shape (N, 2) [m].
        estimate_xy: Estimated HeadTop x, y as scored (with ``shift_xy``), shape (N, 2) [m].
        shift_xy: Start shift applied to the estimate, shape (2,) [m] (zero: not aligned).
        label: Legend text of the estimate (says whether and how it was aligned).
        readers_xy: Reader positions, shape (M, 2) [m], or None.
        reader_ids: Their ids.
        area: Capture-area polygon, shape (K, 2) [m], or None.
        xlim: Axis limits in x [m].
        ylim: Axis limits in y [m] (same scale as x).
    """

    time: np.ndarray
    truth_xy: np.ndarray
    estimate_xy: np.ndarray
    shift_xy: np.ndarray
    label: str
    readers_xy: np.ndarray | None
    reader_ids: list[str]
    area: np.ndarray | None
    xlim: tuple[float, float]
    ylim: tuple[float, float]

    @property
    def shape(self) -> float:
        """Width over height of the drawn box."""
        return (self.xlim[1] - self.xlim[0]) / (self.ylim[1] - self.ylim[0])


def _pyplot():  # type: ignore[no-untyped-def]
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as err:
        raise InputError("plots need matplotlib: pip install 'ikfusion[plot]'",
                         field="plot") from err
    return plt


def summary_readers(result_dir: str | Path) -> Constellation | None:
    """The constellation named in ``summary.json`` (``uwb.readers_file``), if readable."""
    path = Path(result_dir) / "summary.json"
    try:
        summary = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    uwb = summary.get("uwb") if isinstance(summary, dict) else None
    name = uwb.get("readers_file") if isinstance(uwb, dict) else None
    if not isinstance(name, str) or not Path(name).is_file():
        return None
    return load_constellation(name)


def trajectory_view(result_dir: str | Path, truth_path: str | Path, evaluation: Evaluation,
                    readers: Constellation | None = None) -> TrajectoryView:
    """The top view of HeadTop as ``evaluation`` scored it, with readers and area.

    Args:
        result_dir: The ``solve`` result folder.
        truth_path: The truth file.
        evaluation: The metrics of this result (their ``start_shift_m`` is applied).
        readers: The constellation to draw; by default the one ``summary.json`` names.
    """
    folder = Path(result_dir)
    truth = read_truth(truth_path)
    t_true = truth["time"]
    t_site, sites = _long_table(folder / "sites.csv", "site", ["x", "y", "z"])
    span = (t_true >= t_site[0] - 1e-6) & (t_true <= t_site[-1] + 1e-6)
    t = t_true[span]
    true_sites = [str(s) for s in truth["site_names"]]
    truth_xy = truth["p_world_site"][span][:, true_sites.index("HeadTop"), :2]
    shift = np.asarray(evaluation.start_shift_m, dtype=float)[:2]
    estimate_xy = _interp(t, t_site, sites["HeadTop"])[:, :2] + shift
    if evaluation.aligned_start:
        label = (f"estimate, start aligned as scored (shifted by [{shift[0]:.2f}, "
                 f"{shift[1]:.2f}] m)")
    else:
        label = "estimate as solved (not aligned)"
    constellation = readers if readers is not None else summary_readers(folder)
    readers_xy = None if constellation is None else constellation.positions[:, :2]
    area = None if constellation is None else capture_area(constellation)
    boxes = [truth_xy, estimate_xy] + [p for p in (readers_xy, area) if p is not None]
    xlim, ylim = _equal_limits(np.concatenate(boxes))
    return TrajectoryView(
        time=t, truth_xy=truth_xy, estimate_xy=estimate_xy, shift_xy=shift, label=label,
        readers_xy=readers_xy,
        reader_ids=[] if constellation is None else list(constellation.ids),
        area=area, xlim=xlim, ylim=ylim)


def _equal_limits(points: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
    """Limits around points with a margin, one scale on both axes, shape within 1:3 .. 3:1.

    The larger side gets a 5 % margin (at least 0.25 m); the smaller side is widened about
    its middle until the box is no flatter than 3:1.
    """
    finite = points[np.all(np.isfinite(points), axis=1)]
    if finite.size == 0:
        return (-1.0, 1.0), (-1.0, 1.0)
    lo, hi = finite.min(axis=0), finite.max(axis=0)
    middle = 0.5 * (lo + hi)
    pad = max(0.05 * float(np.max(hi - lo)), 0.25)
    half = 0.5 * (hi - lo) + pad
    big = float(np.max(half))
    half = np.maximum(half, big / _MAX_SHAPE)
    return ((float(middle[0] - half[0]), float(middle[0] + half[0])),
            (float(middle[1] - half[1]), float(middle[1] + half[1])))


def draw_trajectory(view: TrajectoryView) -> Any:
    """The top-view figure (a matplotlib ``Figure``; lines: truth, then the estimate)."""
    plt = _pyplot()
    width = 7.0
    fig, ax = plt.subplots(figsize=(width, max(width / view.shape, 2.6) + 0.8))
    ax.plot(view.truth_xy[:, 0], view.truth_xy[:, 1], label="truth", lw=2)
    ax.plot(view.estimate_xy[:, 0], view.estimate_xy[:, 1], label=view.label, lw=1)
    if view.area is not None:
        ring = np.vstack([view.area, view.area[:1]])
        ax.fill(ring[:, 0], ring[:, 1], color="0.9", zorder=0, label="capture area")
    if view.readers_xy is not None:
        ax.scatter(view.readers_xy[:, 0], view.readers_xy[:, 1], marker="^", color="k",
                   zorder=3, label="readers")
        for name, (x, y) in zip(view.reader_ids, view.readers_xy):
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7)
    ax.set_xlim(*view.xlim)
    ax.set_ylim(*view.ylim)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("HeadTop, top view")
    ax.legend(fontsize=8, loc="best")
    return fig


def draw_joint_angles(result_dir: str | Path, truth_path: str | Path,
                      flexions: tuple[str, ...] = JOINT_FLEXIONS) -> Any:
    """Figure of flexion angles, one row per joint, left side then right side [deg]."""
    plt = _pyplot()
    folder = Path(result_dir)
    truth = read_truth(truth_path)
    header, rows = _read_table(folder / "joint_angles.csv")
    names = [str(n) for n in truth["joint_angle_names"]]
    t_est = _floats(folder / "joint_angles.csv", header, rows, ["time"])[:, 0]
    fig, axes = plt.subplots(len(flexions), 2, figsize=(11, 2.2 * len(flexions)), sharex=True,
                             squeeze=False)
    for k, flexion in enumerate(flexions):
        for col, side in enumerate(("Left", "Right")):
            axis, joint = axes[k, col], f"j{side}{flexion}"
            axis.set_ylabel(f"{joint} [deg]", fontsize=8)
            if joint not in header or joint not in names:
                axis.set_title(f"{joint}: not in the result", fontsize=8)
                continue
            est = _floats(folder / "joint_angles.csv", header, rows, [joint])[:, 0]
            axis.plot(truth["time"], truth["joint_angles"][:, names.index(joint)],
                      label="truth", lw=2)
            axis.plot(t_est, est, label="estimate", lw=1)
    axes[0, 0].legend(fontsize=8)
    for col in range(2):
        axes[-1, col].set_xlabel("time [s]")
    return fig


def plot_evaluation(result_dir: str | Path, truth_path: str | Path, out_dir: str | Path,
                    evaluation: Evaluation | None = None,
                    readers: Constellation | None = None) -> list[Path]:
    """Write ``trajectory.png`` (top view of HeadTop) and ``joint_angles.png``.

    Args:
        result_dir: The ``solve`` result folder.
        truth_path: The truth file.
        out_dir: Folder for the figures.
        evaluation: The metrics whose alignment is drawn; by default ``evaluate(...)``'s.
        readers: Constellation to draw; by default the one ``summary.json`` names.

    Returns:
        The files written.
    """
    plt = _pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scored = evaluation if evaluation is not None else evaluate(result_dir, truth_path)
    files = [out / "trajectory.png", out / "joint_angles.png"]
    figures = [draw_trajectory(trajectory_view(result_dir, truth_path, scored, readers)),
               draw_joint_angles(result_dir, truth_path)]
    for fig, path in zip(figures, files):
        fig.savefig(path, dpi=100, bbox_inches="tight")
        plt.close(fig)
    return files
