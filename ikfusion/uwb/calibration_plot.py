"""Figure of a calibration: readers with their 2-sigma ellipses and the wand path (matplotlib).

matplotlib is in the ``plot`` extra and imported only when drawing.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_write_bytes
from .calibration_result import UwbCalibration
from .plot import matplotlib_classes

#: Ellipses are drawn at this many sigmas, magnified by :data:`_ELLIPSE_SCALE` to be visible.
_ELLIPSE_SIGMAS = 2.0
_ELLIPSE_SCALE = 20.0


def _figure() -> tuple[Any, Any]:
    """A new figure and its Agg canvas class."""
    figure_cls, canvas_cls = matplotlib_classes("drawing the calibration", "leave out --plot")
    return figure_cls(figsize=(8.0, 7.0), layout="constrained"), canvas_cls


def plot_calibration(calibration: UwbCalibration, path: str | Path) -> Path:
    """PNG of the calibrated readers (x, y [m]), the first estimate and the wand path.

    Each reader carries its horizontal 2-sigma ellipse magnified 20 times.

    Returns:
        The PNG path.
    """
    fig, canvas_cls = _figure()
    ax = fig.add_subplot(1, 1, 1)
    wand = calibration.p_world_wand
    ax.plot(wand[:, 0], wand[:, 1], color="0.6", linewidth=0.6, label="wand path")
    first = calibration.initial.positions
    ax.scatter(first[:, 0], first[:, 1], marker="x", color="tab:blue", label="first estimate")
    readers = calibration.constellation.positions
    ax.scatter(readers[:, 0], readers[:, 1], marker="^", s=70, color="tab:red",
               edgecolors="black", label="calibrated reader", zorder=5)  # fmt: skip
    angle = np.linspace(0.0, 2.0 * np.pi, 60)
    circle = np.column_stack([np.cos(angle), np.sin(angle)])
    for j, (rid, p) in enumerate(zip(calibration.ids, readers)):
        cov = calibration.position_covariance[2 * j : 2 * j + 2, 2 * j : 2 * j + 2]
        values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
        axes = vectors * np.sqrt(np.maximum(values, 0.0))
        ring = p[:2] + _ELLIPSE_SIGMAS * _ELLIPSE_SCALE * circle @ axes.T
        ax.plot(ring[:, 0], ring[:, 1], color="tab:red", linewidth=0.8)
        sigma_cm = 100.0 * calibration.horizontal_sigma[j]
        ax.annotate(f"{rid} ({sigma_cm:.1f} cm)", (p[0], p[1]), textcoords="offset points",
                    xytext=(5, 5), fontsize=7)  # fmt: skip
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(
        f"UWB calibration: residual RMS {100 * calibration.residual_rms:.1f} cm, outliers "
        f"{100 * calibration.outliers.fraction:.1f} %, predicted reader RMS "
        f"{100 * calibration.predicted_rms:.1f} cm (ellipses: 2 sigma x 20)",
        fontsize=9,
    )
    fig.legend(loc="outside lower center", ncol=3, fontsize=8, frameon=False)
    canvas_cls(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    return atomic_write_bytes(Path(path), buffer.getvalue())
