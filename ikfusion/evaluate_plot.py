"""Plots of an evaluation: top-view trajectories (truth vs estimate) and joint angles.

Matplotlib is an optional extra (``pip install ikfusion[plot]``); it is imported only here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError
from .evaluate import _floats, _interp, _long_table, _read_table


def _pyplot():  # type: ignore[no-untyped-def]
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as err:
        raise InputError("plots need matplotlib: pip install 'ikfusion[plot]'",
                         field="plot") from err
    return plt


def plot_evaluation(result_dir: str | Path, truth_path: str | Path, out_dir: str | Path,
                    joints: tuple[str, ...] = ("jRightHip_flex", "jRightKnee_flex",
                                               "jRightAnkle_flex", "jRightShoulder_flex"),
                    ) -> list[Path]:
    """Write ``trajectory.png`` (top view of HeadTop and the pelvis) and ``joint_angles.png``.

    Returns:
        The files written.
    """
    plt = _pyplot()
    folder, out = Path(result_dir), Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    truth = np.load(truth_path, allow_pickle=False)
    t_true = truth["time"]
    t_site, sites = _long_table(folder / "sites.csv", "site", ["x", "y", "z"])
    true_sites = [str(s) for s in truth["site_names"]]
    head = _interp(t_true, t_site, sites["HeadTop"])
    head_true = truth["p_world_site"][:, true_sites.index("HeadTop")]
    shift = np.zeros(3)
    shift[:2] = head_true[0, :2] - head[0, :2]
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(head_true[:, 0], head_true[:, 1], label="truth", lw=2)
    ax.plot(head[:, 0] + shift[0], head[:, 1] + shift[1], label="estimate (start aligned)",
            lw=1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("HeadTop, top view")
    ax.legend()
    files = [out / "trajectory.png"]
    fig.savefig(files[0], dpi=100, bbox_inches="tight")
    plt.close(fig)
    header, rows = _read_table(folder / "joint_angles.csv")
    names = [str(n) for n in truth["joint_angle_names"]]
    chosen = [j for j in joints if j in header and j in names]
    t_est = _floats(folder / "joint_angles.csv", header, rows, ["time"])[:, 0]
    est = _floats(folder / "joint_angles.csv", header, rows, chosen)
    fig, axes = plt.subplots(len(chosen), 1, figsize=(8, 2.2 * len(chosen)), sharex=True,
                             squeeze=False)
    for k, joint in enumerate(chosen):
        axis = axes[k, 0]
        axis.plot(t_true, truth["joint_angles"][:, names.index(joint)], label="truth", lw=2)
        axis.plot(t_est, est[:, k], label="estimate", lw=1)
        axis.set_ylabel(f"{joint} [deg]")
    axes[0, 0].legend()
    axes[-1, 0].set_xlabel("time [s]")
    files.append(out / "joint_angles.png")
    fig.savefig(files[1], dpi=100, bbox_inches="tight")
    plt.close(fig)
    return files
