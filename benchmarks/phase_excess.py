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
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import _long_table, _read_table, read_truth


def phase_spans(contacts: np.ndarray) -> list[tuple[int, int]]:
    """The ``[start, end)`` sample spans of the True runs of ``contacts`` (N,)."""
    edges = np.diff(np.r_[0, contacts.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(),
                    strict=True))


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
    contacts = np.asarray(truth["contacts"], dtype=bool)
    excess = []
    for i, name in enumerate(str(c) for c in truth["contact_names"]):
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
            if 1e3 * excess[-1] >= args.min_mm:
                share = "-" if held is None else f"{np.mean(held[start:end]):.2f}"
                print(f"{name:<20s} {t[start]:7.2f}-{t[end - 1]:7.2f} s  solved {1e3 * est:6.1f}"
                      f"  true {1e3 * tru:6.1f}  excess {1e3 * excess[-1]:6.1f} mm  held {share}")
    mean = 1e3 * float(np.mean(excess)) if excess else float("nan")
    print(f"{len(excess)} phases, mean excess {mean:.1f} mm (beyond mm)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
