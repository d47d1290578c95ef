"""Where an IMU-only solve loses distance: the pelvis's along-track error, step by step.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_drift_steps.py CAPTURE RESULT``

``CAPTURE`` is a simulated capture folder (its ``truth.npz``), ``RESULT`` the ``solve`` result of
it, e.g. ``DIR/perfect/cmu-02-02-walk/capture`` and ``.../imu-only`` of ``bench_motions.py
--acceptance --out DIR``. The solve is shifted to the true start (as ``evaluate`` does IMU only).
With perfect joint angles the pelvis can only fall behind the truth through the points the
solver holds: a held point whose true counterpart moves shifts the body by as much. Two tables:

* per set of points the solver holds (heel/toe of each foot; ``truth:`` their true contact
  states, ``1`` planted): frames, the pelvis's along-track error gained [mm] and the true
  held points' own motion along the track meanwhile [mm] (mean over the held points);
* per step (from one foot strike of the truth to the next, ``ikfusion.app.stride_loss``): the
  true and solved pelvis travel [mm], their difference, and per held point the true point's
  motion while held (``*``: the truth no longer labels it planted); then the sums over all steps
  and the share the solve falls short (``% short``: ``evaluate``'s ``stride_loss_percent``). On
  the generator's circles that share is the walk's loss: the end error (``drift_percent``)
  closes with the solved circle, a little smaller than the true.

The pelvis's error gained while points are held splits in two (mean over the held points): the
held point's solved motion against the true point's (``point mm``: an anchor held or carried
wrongly) and the change of the pelvis's offset from that point against the truth's (``shape
mm``: the body between the point and the pelvis posed otherwise than the truth, e.g. an unsensed
toe bent less than the true one while the body rides on it). ``--frames T0 T1`` prints every
frame of that time span [s]: the true and held contact states (heel and toe, left then right;
``1`` planted), the pelvis's along-track error gained and its sum [mm], both parts, the true
points' heights [mm] and the solved ones.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ikfusion.app.stride_loss import foot_strikes, steps, stride_loss_percent

FEET = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
LINKS = ["toe", "foot", "shank", "thigh", "pelvis"]


def _rows(path: Path, key: str, name: str, columns: list[str]) -> np.ndarray:
    """The rows of one segment or site (N, len(columns)) of a result CSV."""
    with path.open() as f:
        return np.array([[float(r[c]) for c in columns] for r in csv.DictReader(f)
                         if r[key] == name])


def main(argv: Sequence[str] | None = None) -> int:
    """Print both tables; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("capture", type=Path, help="capture folder (truth.npz)")
    parser.add_argument("result", type=Path, help="IMU-only solve result folder")
    parser.add_argument("--frames", type=float, nargs=2, metavar=("T0", "T1"),
                        help="also print every frame from T0 to T1 [s]")
    args = parser.parse_args(argv)
    truth = np.load(args.capture / "truth.npz", allow_pickle=True)
    t = truth["time"]
    segments, sites = list(truth["segment_names"]), list(truth["site_names"])
    contact_names = list(truth["contact_names"])
    p_true = truth["p_world_segment"][:, segments.index("Pelvis"), :2]
    p_est = _rows(args.result / "segments.csv", "segment", "Pelvis", ["px", "py"])
    p_est = p_est + (p_true[0] - p_est[0])
    err = p_est - p_true
    planted_true = truth["contacts"][:, [contact_names.index(n) for n in FEET]].astype(bool)
    with (args.result / "contacts.csv").open() as f:
        held = np.array([[float(r[n]) > 0.5 for n in FEET] for r in csv.DictReader(f)])
    points_3d = np.stack([truth["p_world_site"][:, sites.index(n)] for n in FEET], axis=1)
    points = points_3d[:, :, :2]
    sites_solved = np.stack([_rows(args.result / "sites.csv", "site", n, ["x", "y", "z"])
                       for n in FEET], axis=1)
    # per frame: the pelvis's along-track error gained, and its point and shape parts [m]
    frames = len(t)
    gained, point_part, shape_part = np.zeros(frames), np.zeros(frames), np.zeros(frames)
    for k in range(frames - 1):
        step = p_true[k + 1] - p_true[k]
        if np.linalg.norm(step) < 1e-6:
            continue
        u = step / np.linalg.norm(step)
        gained[k + 1] = float((err[k + 1] - err[k]) @ u)
        both = held[k] & held[k + 1]
        if both.any():
            point_err = sites_solved[:, both, :2] - points[:, both]
            point_part[k + 1] = float(((point_err[k + 1] - point_err[k]) @ u).mean())
            shape_part[k + 1] = gained[k + 1] - point_part[k + 1]

    by_set: dict[str, list[float]] = {}
    for k in range(frames - 1):
        step = p_true[k + 1] - p_true[k]
        if np.linalg.norm(step) < 1e-6:
            continue
        u = step / np.linalg.norm(step)
        both = held[k] & held[k + 1]
        moved = float(((points[k + 1] - points[k]) @ u)[both].mean()) if both.any() else 0.0
        key = ("+".join(n for n, h in zip(FEET, both, strict=True) if h) or "none") + (
            " (truth:" + "".join("1" if planted_true[k, i] else "0"
                                 for i in np.flatnonzero(both)) + ")")
        entry = by_set.setdefault(key, [0.0, 0.0, 0.0, 0.0, 0.0])
        entry[0] += 1
        entry[1] += gained[k + 1]
        entry[2] += moved
        entry[3] += point_part[k + 1]
        entry[4] += shape_part[k + 1]
    travelled = float(np.linalg.norm(np.diff(p_true, axis=0), axis=1).sum())
    print(f"end error {1000 * np.linalg.norm(err[-1]):.1f} mm over {travelled:.2f} m")
    print(f"{'held points':<42s} {'frames':>6s} {'pelvis mm':>9s} {'true held mm':>12s} "
          f"{'point mm':>8s} {'shape mm':>8s}")
    for key, (count, gain, moved, part, shape) in sorted(by_set.items(),
                                                         key=lambda kv: kv[1][1]):
        print(f"{key:<42s} {int(count):6d} {1000 * gain:9.1f} {1000 * moved:12.1f} "
              f"{1000 * part:8.1f} {1000 * shape:8.1f}")

    links = _link_parts(truth, args.result, held, p_true)
    if links is not None:
        print("shape by link of the held leg [mm]: "
              + " ".join(f"{n} {1000 * v:.1f}" for n, v in zip(LINKS, links, strict=True)))

    strikes = foot_strikes(t, truth["contacts"], contact_names)
    step_list = steps(p_est, p_true, strikes)
    print(f"\n{'step [s]':<13s} {'true mm':>8s} {'solved mm':>9s} {'diff mm':>8s}  held points")
    for s in step_list:
        a, b, u = s.start, s.end, s.direction
        moved: dict[str, float] = {}
        for k in range(a, b):
            both = held[k] & held[k + 1]
            for i in np.flatnonzero(both):
                name = FEET[i] + ("" if planted_true[k, i] else "*")
                moved[name] = moved.get(name, 0.0) + float(
                    (points[k + 1, i] - points[k, i]) @ u) / both.sum()
        print(f"{t[a]:5.2f}-{t[b]:5.2f} {1000 * s.true_m:8.1f} {1000 * s.solved_m:9.1f} "
              f"{1000 * (s.solved_m - s.true_m):8.1f}  "
              + " ".join(f"{n}:{1000 * v:.1f}" for n, v in moved.items()))
    total_true = sum(s.true_m for s in step_list)
    if total_true > 0:
        loss = stride_loss_percent(step_list, min_steps=1, min_distance_m=0.0)
        print(f"steps: the pelvis went {sum(s.solved_m for s in step_list):.3f} m of the true "
              f"{total_true:.3f} m ({loss:.2f} % short, evaluate's stride_loss_percent; on a "
              "closed path the end error hides a short stride)")
    if args.frames is not None:
        _print_frames(t, args.frames, planted_true, held, gained, point_part, shape_part,
                      points_3d[:, :, 2], sites_solved[:, :, 2])
    return 0


def _chain(point: str) -> list[tuple[str, str]]:
    """The held leg from ``point`` up to the pelvis: (``site``/``segment``, name) nodes."""
    side = "Left" if point.startswith("Left") else "Right"
    toe = [("segment", f"{side}Toe")] if point.endswith("Toe") else []
    return [("site", point), *toe, *(("segment", f"{side}{s}")
                                     for s in ("Foot", "LowerLeg", "UpperLeg")),
            ("segment", "Pelvis")]


def _link_parts(truth: Mapping[str, np.ndarray], result: Path, held: np.ndarray,
                p_true: np.ndarray) -> np.ndarray | None:
    """(5,) the ``shape`` part per link of the held leg (:data:`LINKS`) [m]; None: no legs.

    Per frame with held points, each link's along-track change (solved less true) of the
    vector from its lower end to its upper end, the mean over the held points.
    """
    segments, sites = list(truth["segment_names"]), list(truth["site_names"])
    nodes = {n for p in FEET for n in _chain(p)}
    if any(name not in (segments if kind == "segment" else sites) for kind, name in nodes):
        return None
    solved: dict[tuple[str, str], np.ndarray] = {}
    true: dict[tuple[str, str], np.ndarray] = {}
    for kind, name in nodes:
        file, key, cols = (("segments.csv", "segment", ["px", "py"]) if kind == "segment"
                           else ("sites.csv", "site", ["x", "y"]))
        solved[(kind, name)] = _rows(result / file, key, name, cols)
        true[(kind, name)] = (truth["p_world_segment"][:, segments.index(name), :2]
                              if kind == "segment" else
                              truth["p_world_site"][:, sites.index(name), :2])
    if any(len(v) != len(p_true) for v in solved.values()):
        return None
    parts = np.zeros(len(LINKS))
    for k in range(len(p_true) - 1):
        step = p_true[k + 1] - p_true[k]
        both = np.flatnonzero(held[k] & held[k + 1])
        if np.linalg.norm(step) < 1e-6 or not len(both):
            continue
        u = step / np.linalg.norm(step)
        for i in both:
            chain = _chain(FEET[i])
            names = LINKS[len(LINKS) + 1 - len(chain):]
            for lower, upper, link in zip(chain[:-1], chain[1:], names, strict=True):
                d_solved = solved[upper] - solved[lower]
                d_true = true[upper] - true[lower]
                change = (d_solved[k + 1] - d_solved[k]) - (d_true[k + 1] - d_true[k])
                parts[LINKS.index(link)] += float(change @ u) / len(both)
    return parts


def _states(row: np.ndarray) -> str:
    """Contact states as ``1`` (planted) and ``.``."""
    return "".join("1" if x else "." for x in row)


def _print_frames(t: np.ndarray, span: Sequence[float], planted_true: np.ndarray,
                  held: np.ndarray, gained: np.ndarray, point_part: np.ndarray,
                  shape_part: np.ndarray, z_true: np.ndarray, z_solved: np.ndarray) -> None:
    """The per-frame table of ``--frames`` (see the module docstring); lengths in [m]."""
    print(f"\n{'t [s]':>6s} {'truth':>5s} {'held':>4s} {'gain mm':>7s} {'sum mm':>7s} "
          f"{'point':>6s} {'shape':>6s}  true z mm {'':10s} solved z mm")
    total = float(gained[t < span[0]].sum())
    for k in np.flatnonzero((t >= span[0]) & (t <= span[1])):
        total += float(gained[k])
        print(f"{t[k]:6.2f} {_states(planted_true[k]):>5s} {_states(held[k]):>4s} "
              f"{1000 * gained[k]:7.1f} {1000 * total:7.1f} {1000 * point_part[k]:6.1f} "
              f"{1000 * shape_part[k]:6.1f}  "
              + " ".join(f"{1000 * z:4.0f}" for z in z_true[k]) + "   "
              + " ".join(f"{1000 * z:4.0f}" for z in z_solved[k]))


if __name__ == "__main__":
    sys.exit(main())
