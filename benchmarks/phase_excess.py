"""Which contact phases make ``beyond mm`` (``foot_slide_excess_mm``): one line per phase.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/phase_excess.py RESULT_DIR TRUTH.npz
[--min-mm 3]`` on a result folder of ``bench_motions.py --out DIR`` (e.g.
``DIR/perfect/<clip>/imu-only`` and ``DIR/perfect/<clip>/capture/truth.npz``).

Per contact phase of the truth and contact point (as :func:`ikfusion.app.evaluate.evaluate`
scores them, after its start alignment): the phase's time span [s], the largest horizontal
slide of the solved point and of the true one from where they were when the phase began [mm],
the excess (solved minus true, at least 0) [mm], and the share of the phase's frames in which
the solver held the point (``contacts.csv``). Phases whose excess is below ``--min-mm`` are
left out of the listing but counted in the mean printed last (the ``beyond mm`` column).

Each listed phase's excess is then split by cause (:func:`step_causes`): the solved point's
motion relative to the true one, frame by frame, goes to what the solver's held points did in
that step; the excess is shared out in proportion to those path lengths [mm]:

* ``sunk``: the solver held a trunk point the truth has sunk deeper than the floor scatter
  (:data:`ikfusion.app.slide_excess.SUNK_DEPTH`): the floor holds the solved point where the true
  one slides through the floor, a motion no solve on the floor can follow (the steps
  ``foot_slide_excess_on_floor_mm``, the ``floor mm`` column, leaves out);
* ``under``: the same within the scatter (z < 0): the truth's own floor, counted;
* ``held``: the solver held points the truth has on or above the floor, and they moved in the
  truth (a loose stance of the truth, a lift-off the solver held on to, a roll);
* ``switch``: the set of held points changed (a plant, a release, a hand-over);
* ``free``: nothing held.

The last lines give each cause's share of ``beyond mm`` over all phases.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import _long_table, _read_table, read_truth
from ikfusion.app.slide_excess import sunk_steps

#: The causes of :func:`step_causes`, in their column order.
CAUSES = ("sunk", "under", "held", "switch", "free")


def phase_spans(contacts: np.ndarray) -> list[tuple[int, int]]:
    """The ``[start, end)`` sample spans of the True runs of ``contacts`` (N,)."""
    edges = np.diff(np.r_[0, contacts.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(),
                    strict=True))


def step_causes(held: np.ndarray, z_true: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """The cause (index into :data:`CAUSES`) of each step ``k -> k + 1`` (N - 1,).

    Args:
        held: (N, k) the points the solver holds in each frame.
        z_true: (N, k) the true points' heights [m] (floor at 0).
        names: (k,) the points' names (:func:`~ikfusion.app.slide_excess.sunk_steps`).
    """
    now, before = held[1:], held[:-1]
    under = np.any(now & (z_true[1:] < 0.0), axis=1)
    cause = np.where(sunk_steps(held, z_true, names), 0, np.where(under, 1, 2))
    cause = np.where(np.any(now != before, axis=1), 3, cause)
    return np.where(~now.any(axis=1), 4, cause)


def cause_split(excess: float, relative: np.ndarray, causes: np.ndarray) -> np.ndarray:
    """``excess`` shared out over :data:`CAUSES` (len(CAUSES),) by path length.

    Args:
        excess: The phase's excess [m].
        relative: (n, 2) the solved point's horizontal position minus the true one's over the
            phase's n frames [m].
        causes: (n - 1,) the cause of each step (:func:`step_causes`).
    """
    steps = np.linalg.norm(np.diff(relative, axis=0), axis=1)
    path = np.bincount(causes, weights=steps, minlength=len(CAUSES))
    total = float(path.sum())
    return excess * path / total if total > 0.0 else np.zeros(len(CAUSES))


def main(argv: Sequence[str] | None = None) -> int:
    """List the phases; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("result", type=Path, help="result folder of ikfusion solve")
    parser.add_argument("truth", type=Path, help="truth.npz of the capture")
    parser.add_argument("--min-mm", type=float, default=3.0,
                        help="list only phases with a larger excess [mm]")
    args = parser.parse_args(argv)
    truth = read_truth(args.truth)
    t = truth["time"]
    site_names = [str(s) for s in truth["site_names"]]
    segment_names = [str(s) for s in truth["segment_names"]]
    t_site, sites = _long_table(args.result / "sites.csv", "site", ["x", "y", "z"])
    t_seg, segments = _long_table(args.result / "segments.csv", "segment", ["px", "py", "pz"])
    shift = truth["p_world_segment"][0, segment_names.index("Pelvis")] - segments["Pelvis"][0]
    shift[2] = 0.0  # evaluate's start alignment (an IMU-only result)
    header, rows = _read_table(args.result / "contacts.csv")
    held_table = np.array([[float(v) for v in row] for row in rows])
    held_rows = np.clip(np.searchsorted(held_table[:, 0], t - 1e-6), 0, len(held_table) - 1)
    names = [str(c) for c in truth["contact_names"]]
    solver_names = [n for n in names if n in header and n in site_names]
    held_all = held_table[held_rows][:, [header.index(n) for n in solver_names]] > 0.5
    z_true = truth["p_world_site"][:, [site_names.index(n) for n in solver_names], 2]
    causes = step_causes(held_all, z_true, solver_names)
    contacts = np.asarray(truth["contacts"], dtype=bool)
    excess = []
    split = np.zeros(len(CAUSES))
    print(f"{'point':<20s} {'phase [s]':>17s}  {'solved':>6s} {'true':>6s} {'excess':>6s} mm "
          f"{'held':>4s}  " + " ".join(f"{c:>6s}" for c in CAUSES))
    for i, name in enumerate(names):
        if name not in site_names or name not in sites:
            continue
        p_est = np.stack([np.interp(t, t_site, sites[name][:, k]) for k in range(2)], axis=1)
        p_est += shift[:2]
        p_true = truth["p_world_site"][:, site_names.index(name), :2]
        held = held_table[held_rows, header.index(name)] if name in header else None
        for start, end in phase_spans(contacts[:, i]):
            est = float(np.max(np.linalg.norm(p_est[start:end] - p_est[start], axis=1)))
            tru = float(np.max(np.linalg.norm(p_true[start:end] - p_true[start], axis=1)))
            excess.append(max(0.0, est - tru))
            parts = cause_split(excess[-1], p_est[start:end] - p_true[start:end],
                                causes[start:end - 1])
            split += parts
            if 1e3 * excess[-1] >= args.min_mm:
                share = "-" if held is None else f"{np.mean(held[start:end]):.2f}"
                print(f"{name:<20s} {t[start]:7.2f}-{t[end - 1]:7.2f} s  {1e3 * est:6.1f} "
                      f"{1e3 * tru:6.1f} {1e3 * excess[-1]:6.1f} mm {share:>4s}  "
                      + " ".join(f"{1e3 * v:6.1f}" for v in parts))
    mean = 1e3 * float(np.mean(excess)) if excess else float("nan")
    print(f"{len(excess)} phases, mean excess {mean:.1f} mm (beyond mm)")
    if excess:
        print("by cause [mm of beyond mm]: " + ", ".join(
            f"{c} {1e3 * v / len(excess):.2f}" for c, v in zip(CAUSES, split, strict=True)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
