"""Figures of DOP maps and reader layouts (matplotlib, imported only when drawing)."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_write_bytes
from ..errors import InputError
from .dop import GOOD_SIGMA, DopMap

#: Colour-scale limits of expected-sigma maps [cm].
_VMAX_RANGE_CM = (5.0, 50.0)


def matplotlib_classes(
    purpose: str = "drawing DOP maps", instead: str = "pass --no-plot to print the numbers only"
) -> tuple[Any, Any]:
    """Figure and Agg canvas classes, with a clear error when matplotlib is missing.

    Args:
        purpose: What needs the plot, for the message (e.g. ``"drawing DOP maps"``).
        instead: What the user can do without matplotlib.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise InputError(
            f"{purpose} needs matplotlib: pip install 'ikfusion[plot]' (or {instead})"
        ) from err
    return Figure, FigureCanvasAgg


def colour_limit_cm(maps: Sequence[DopMap]) -> float:
    """Upper end of a shared colour scale: twice the worst 95th percentile, within 5-50 cm."""
    p95 = [m.summary().p95 * 100.0 for m in maps]
    finite = [v for v in p95 if np.isfinite(v)]
    top = 2.0 * max(finite) if finite else _VMAX_RANGE_CM[1]
    return float(np.clip(np.ceil(top), *_VMAX_RANGE_CM))


def _draw(ax: Any, dop_map: DopMap, readers: np.ndarray, ids: Sequence[str], vmax: float) -> Any:
    import matplotlib as mpl

    cmap = mpl.colormaps["viridis"].with_extremes(bad="0.82", over="#7f0000")
    sigma_cm = np.ma.masked_invalid(dop_map.expected_sigma * 100.0)
    mesh = ax.pcolormesh(
        dop_map.x, dop_map.y, sigma_cm, cmap=cmap, vmin=0.0, vmax=vmax, shading="nearest"
    )
    if np.any(np.isfinite(sigma_cm)) and np.nanmin(sigma_cm) < GOOD_SIGMA * 100 < vmax:
        ax.contour(
            dop_map.x,
            dop_map.y,
            sigma_cm.filled(np.inf),
            levels=[GOOD_SIGMA * 100],
            colors="black",
            linewidths=0.9,
            linestyles=":",
        )
    area = np.vstack([dop_map.area, dop_map.area[:1]])
    ax.plot(area[:, 0], area[:, 1], color="black", linewidth=1.6)
    ax.scatter(
        readers[:, 0],
        readers[:, 1],
        c=readers[:, 2],
        cmap="autumn",
        marker="^",
        s=70,
        edgecolors="black",
        linewidths=0.8,
        zorder=5,
    )
    for (x, y, z), rid in zip(readers, ids):
        ax.annotate(
            f"{rid} ({z:.1f} m)",
            (x, y),
            textcoords="offset points",
            xytext=(4, 4),
            fontsize=7,
            zorder=6,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return mesh


def _legend(fig: Any) -> None:
    """One legend for the figure, below the maps."""
    from matplotlib.lines import Line2D

    reader: dict[str, Any] = {
        "marker": "^",
        "color": "none",
        "markeredgecolor": "black",
        "markersize": 8,
    }
    handles = [
        Line2D([], [], color="black", linewidth=1.6, label="capture area"),
        Line2D([], [], color="black", linestyle=":", label="5 cm contour"),
        Line2D([], [], markerfacecolor="red", label="reader, low", **reader),
        Line2D([], [], markerfacecolor="yellow", label="reader, high", **reader),
        Line2D(
            [], [], marker="s", color="none", markerfacecolor="0.82", markersize=8, label="no fix"
        ),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=5, fontsize=8, frameon=False)


def _layout(width: float, height: float, panels: int) -> tuple[tuple[float, float], bool]:
    """Figure size and whether the colour bar goes below (wide maps) or beside."""
    aspect = height / max(width, 1e-9)
    wide = aspect < 0.45
    if wide:
        return (min(16.0, 7.0 * panels + 2.0), 2.6 + 6.5 * panels * max(aspect, 0.05)), wide
    return (7.5 * panels + 1.5, 2.4 + 6.0 * min(aspect, 2.0)), wide


def _title(dop_map: DopMap, name: str) -> str:
    s = dop_map.summary().as_dict("cm")
    mode = "3-D" if dop_map.mode == "3d" else "2-D, known height"
    clock = "unknown transmit time" if dop_map.clock else "two-way ranges"
    p95 = "no fix" if s["p95_cm"] is None else f"{s['p95_cm']:.1f} cm"
    return (
        f"{name}: expected position sigma, {mode}, {clock}, tag at {dop_map.height:.2f} m\n"
        f"area median {_cm(s['median_cm'])}, p95 {p95}, max {_cm(s['max_cm'])}, "
        f"{100 * float(s['fraction_under_5cm'] or 0):.0f} % under 5 cm"
    )


def _cm(v: object) -> str:
    return "no fix" if v is None else f"{float(v):.1f} cm"  # type: ignore[arg-type]


def _save(fig: Any, canvas_cls: Any, path: Path) -> Path:
    canvas_cls(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    return atomic_write_bytes(Path(path), buf.getvalue())


def plot_dop_map(
    dop_map: DopMap,
    p_world_readers: np.ndarray,
    reader_ids: Sequence[str],
    path: str | Path,
    *,
    name: str = "constellation",
) -> Path:
    """Heatmap PNG of the expected position sigma [cm], readers and capture area drawn.

    Grey cells have no fix (too few readers in coverage); dark red cells exceed the colour
    scale; the dotted black line is the 5 cm contour. Reader markers are coloured by height.

    Returns:
        The PNG path.
    """
    figure_cls, canvas_cls = matplotlib_classes()
    size, wide = _layout(dop_map.x[-1] - dop_map.x[0], dop_map.y[-1] - dop_map.y[0], 1)
    fig = figure_cls(figsize=size, layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    mesh = _draw(ax, dop_map, p_world_readers, reader_ids, colour_limit_cm([dop_map]))
    fig.colorbar(
        mesh,
        ax=ax,
        label="expected position sigma [cm]",
        extend="max",
        shrink=0.9,
        location="bottom" if wide else "right",
    )
    ax.set_title(_title(dop_map, name), fontsize=9)
    _legend(fig)
    return _save(fig, canvas_cls, Path(path))


def plot_placement(
    naive: DopMap,
    chosen: DopMap,
    naive_readers: np.ndarray,
    chosen_readers: np.ndarray,
    path: str | Path,
    start_label: str = "naive perimeter layout",
) -> Path:
    """Side-by-side maps of the start (by default naive) and the optimised layout.

    Both maps share one colour scale; ``start_label`` titles the first panel.

    Returns:
        The PNG path.
    """
    figure_cls, canvas_cls = matplotlib_classes()
    size, wide = _layout(naive.x[-1] - naive.x[0], naive.y[-1] - naive.y[0], 2)
    fig = figure_cls(figsize=size, layout="constrained")
    vmax = colour_limit_cm([naive, chosen])
    mesh = None
    panels = [
        (naive, naive_readers, start_label),
        (chosen, chosen_readers, "optimised"),
    ]
    for i, (m, readers, label) in enumerate(panels):
        ax = fig.add_subplot(2, 1, i + 1) if wide else fig.add_subplot(1, 2, i + 1)
        ids = [f"R{j + 1}" for j in range(len(readers))]
        mesh = _draw(ax, m, readers, ids, vmax)
        ax.set_title(_title(m, label), fontsize=8)
    fig.colorbar(
        mesh,
        ax=fig.axes,
        label="expected position sigma [cm]",
        extend="max",
        shrink=0.9,
        location="bottom" if wide else "right",
    )
    _legend(fig)
    return _save(fig, canvas_cls, Path(path))
