"""Accuracy of a solve against ground truth (SPEC section 6, ``ikfusion evaluate``).

The result folder's CSV files are compared with ``truth.npz`` at the truth's sample times
(the estimate is interpolated linearly, quaternions by normalised linear blending of the
nearest samples). Without UWB the absolute position of the body is unobservable, so by default
(``align="auto"``) an IMU-only result is shifted horizontally so that its first pelvis position
equals the truth's; a result that used UWB is compared as it is. The shift applied is reported
as ``start_shift_m`` ([x, y, z] [m], zero when not aligned).

Joint angles of both sides are made continuous in time (no +-360 deg wraps, no jumps between
the two Euler triples of a rotation, :mod:`ikfusion.model.angle_continuity`), then each frame of
the estimate takes the triple of its rotation closest to the truth's, so an arm overhead or a
spin compares like with like.

Metrics (all over the common time span):

* ``joint_angle_rms_deg``: RMS over every anatomical angle and frame [deg];
* ``segment_orientation_rms_deg``: RMS geodesic angle between estimated and true segment
  orientations [deg];
* ``head_position_rms_m`` and ``head_position_rms_xy_m``: RMS distance of site ``HeadTop``, 3-D
  and horizontal [m];
* ``foot_slide_mm`` and ``foot_slide_max_mm``: per contact phase of the truth, the largest
  horizontal distance of the estimated contact point from where it was when the phase began;
  mean and maximum over phases [mm]. It mixes two faults: a point the solver let slide and a
  planted point of the truth the solver released (a detection miss); and the truth's phases
  (a point below 3 cm slower than 0.3 m/s) let the true point itself move:
  ``truth_slide_mm`` is the same measure of the truth's own points (its floor) [mm];
* ``foot_slide_excess_mm``: per contact phase of the truth, how much further the estimated point
  slid than the true one did (``max(0, slide_estimated - slide_true)``), mean over phases [mm]
  (None when the truth has no contact phase): the skating a solve adds, free of the truth's
  loose phases (a point the solver holds still while the true one rolls counts 0);
  ``foot_slide_excess_on_floor_mm`` the same where the truth is a body on the floor: the steps
  in which the solver holds a trunk point the truth has sunk more than 2 cm under the floor (a
  lying body's back, :mod:`.slide_excess`) are left out, the solved points moving there as the
  true ones do [mm];
* ``held_slide_mm`` and ``held_slide_max_mm``: the same per contact phase of the *solver*
  (``contacts.csv``): how far a point the solver holds planted moves, mean and maximum [mm];
  ``held_truth_slide_mm`` the same of the *true* point over those phases, mean [mm]: a point the
  solver holds while the true one moves (held too early or too long, a rolling knee or palm, a
  skating mocap clip) shifts the whole body by that much;
* ``contact_agreement_pct``: share of frames and contact points (those of both the truth and
  ``contacts.csv``) where the solver's contact state equals the truth's [%]; ``contact_missed_pct``
  the share of the truth's planted samples the solver released [%];
* ``joint_angle_jump_max_deg``: the largest frame-to-frame change of a joint's error against
  the truth (the geodesic angle between the error rotations ``R_true^T R_est`` of its angles in
  two consecutive frames) [deg]: the pops of a solve (a contact that lets go, a correction applied
  at once). Free of Euler artefacts near ``|middle| = 90`` deg; for a pop about one axis it is
  that angle's change. The toe joints, which no sensor of a suit observes, are left out.
  ``joint_angle_jump_at`` says which angle (of the joint, the one whose error changed most),
  when;
* ``joint_angle_step_max_deg``: the largest frame-to-frame turn of a joint in the estimate itself
  (the geodesic angle between its rotations in two consecutive frames, toes left out) [deg]: a
  flip (a joint turning over to another solution) shows here whatever the truth does;
* ``drift_percent``: the pelvis's horizontal error over the last second, as a percentage of the
  horizontal distance the true pelvis travelled (its track sampled once a second, so sway does
  not count as distance); None when it travelled less than 2 m (standing, turning on the spot).
  On a closed path (a circle) it is blind to a stride the solve shortens: the solved path is a
  smaller copy that closes on itself;
* ``stride_loss_percent``: step by step (from one foot strike of the truth's contacts to the
  next), the solved pelvis's horizontal travel along the true pelvis's against the true travel,
  summed over the steps, as a percentage short: ``100 (1 - solved / true)``, negative when the
  solve overshoots (:mod:`.stride_loss`: a foot strike is a foot's heel or toe planted after
  0.1 s or more with neither); None with fewer than 4 steps or under 1 m of true travel.
"""

from __future__ import annotations

import csv
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.truth_npz import read_truth
from ..model.angle_continuity import (
    continuous_columns_deg,
    nearest_columns_deg,
    sequence_columns,
)
from ..model.joints import load_joint_specs
from ..rotations import angle_between, continuous_quaternions, quat_wxyz_to_matrix
from .slide_excess import excess_slides, sunk_steps
from .stride_loss import foot_strikes, steps, stride_loss_percent


@dataclass
class Evaluation:
    """Accuracy metrics of one result (see the module docstring for definitions)."""

    frames: int
    joint_angle_rms_deg: float
    segment_orientation_rms_deg: float
    head_position_rms_m: float
    head_position_rms_xy_m: float
    foot_slide_mm: float
    foot_slide_max_mm: float
    aligned_start: bool
    per_joint_rms_deg: dict[str, float] = field(default_factory=dict)
    joint_angle_jump_max_deg: float = 0.0
    joint_angle_jump_at: str = ""
    start_shift_m: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    drift_percent: float | None = None
    held_slide_mm: float = 0.0
    held_slide_max_mm: float = 0.0
    contact_agreement_pct: float = 100.0
    contact_missed_pct: float = 0.0
    truth_slide_mm: float = 0.0
    held_truth_slide_mm: float = 0.0
    foot_slide_excess_mm: float | None = None
    foot_slide_excess_on_floor_mm: float | None = None
    joint_angle_step_max_deg: float = 0.0
    stride_loss_percent: float | None = None

    def as_dict(self) -> dict[str, object]:
        """Plain dictionary (for JSON)."""
        return asdict(self)


def _read_table(path: Path) -> tuple[list[str], list[list[str]]]:
    if not path.is_file():
        raise InputError("missing from the result folder (is it a `solve` output?)", path=path)
    with path.open() as f:
        rows = list(csv.reader(f))
    if not rows:
        raise InputError("empty file", path=path, line=1)
    return rows[0], rows[1:]


def _floats(path: Path, header: list[str], rows: list[list[str]], columns: list[str]) -> np.ndarray:
    missing = [c for c in columns if c not in header]
    if missing:
        raise InputError(f"columns missing: {', '.join(missing)}", path=path, line=1,
                         field=missing[0])
    index = [header.index(c) for c in columns]
    out = np.empty((len(rows), len(columns)))
    for r, row in enumerate(rows):
        for k, i in enumerate(index):
            try:
                out[r, k] = float(row[i])
            except (ValueError, IndexError):
                raise InputError("not a number", path=path, line=r + 2,
                                 field=columns[k]) from None
    return out


def _long_table(path: Path, key: str,
                columns: list[str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A ``time,<key>,...`` table as times (N,) and name -> values (N, len(columns))."""
    header, rows = _read_table(path)
    if key not in header:
        raise InputError(f"column {key!r} missing", path=path, line=1, field=key)
    k = header.index(key)
    names = list(dict.fromkeys(r[k] for r in rows))
    values = _floats(path, header, rows, ["time", *columns])
    per_name = {}
    time = None
    for name in names:
        sel = np.array([r[k] == name for r in rows])
        per_name[name] = values[sel, 1:]
        time = values[sel, 0] if time is None else time
    return (time if time is not None else np.zeros(0)), per_name


def _interp(t_out: np.ndarray, t_in: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t_out, t_in, values[:, k]) for k in range(values.shape[1])],
                    axis=1)


def _interp_quat(t_out: np.ndarray, t_in: np.ndarray, quat: np.ndarray) -> np.ndarray:
    out = _interp(t_out, t_in, continuous_quaternions(quat))
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def phase_slides(P: np.ndarray, contacts: np.ndarray) -> list[float]:
    """Per contact phase, the largest horizontal slide [m] of a contact point.

    ``P`` (N, k, 3) are the points' positions, ``contacts`` (N, k) their phases; the slide is
    the distance from where the point was when its phase began.
    """
    slides = []
    for i in range(contacts.shape[1]):
        start = None
        for k in range(len(contacts) + 1):
            on = k < len(contacts) and bool(contacts[k, i])
            if on and start is None:
                start = k
            elif not on and start is not None:
                seg = P[start:k, i, :2]
                slides.append(float(np.max(np.linalg.norm(seg - seg[0], axis=1))))
                start = None
    return slides


def drift_percent(time: np.ndarray, p_est: np.ndarray, p_true: np.ndarray,
                  min_distance_m: float = 2.0) -> float | None:
    """Horizontal drift at the end as a percentage of the distance travelled.

    Args:
        time: Sample times [s], shape (N,).
        p_est: Estimated pelvis positions (world) [m], shape (N, 3).
        p_true: True pelvis positions (world) [m], shape (N, 3).
        min_distance_m: Below this horizontal distance travelled the ratio is meaningless
            (None) [m].

    Returns:
        The mean horizontal error over the last second [m], over the true track's length
        sampled once a second [m], in percent; None below ``min_distance_m``.
    """
    ticks = np.append(np.arange(time[0], time[-1], 1.0), time[-1])
    track = np.stack([np.interp(ticks, time, p_true[:, k]) for k in range(2)], axis=1)
    distance = float(np.sum(np.linalg.norm(np.diff(track, axis=0), axis=1)))
    if distance < min_distance_m:
        return None
    last = time >= time[-1] - 1.0
    error = float(np.mean(np.linalg.norm(p_est[last, :2] - p_true[last, :2], axis=1)))
    return 100.0 * error / distance
def _solver_contacts(path: Path, t: np.ndarray,
                     names: list[str]) -> tuple[list[str], np.ndarray]:
    """The solver's contact states of ``contacts.csv`` at times ``t`` [s] (nearest sample).

    Returns the names among ``names`` the file has and their states (len(t), k) as booleans;
    no names when the file is absent (older results).
    """
    if not path.is_file():
        return [], np.zeros((len(t), 0), dtype=bool)
    header, rows = _read_table(path)
    have = [n for n in names if n in header]
    values = _floats(path, header, rows, ["time", *have])
    if len(values) == 0:
        return [], np.zeros((len(t), 0), dtype=bool)
    nearest = np.clip(np.searchsorted(values[:, 0], t), 0, len(values) - 1)
    before = np.clip(nearest - 1, 0, len(values) - 1)
    closer = np.abs(values[before, 0] - t) < np.abs(values[nearest, 0] - t)
    pick = np.where(closer, before, nearest)
    return have, values[pick, 1:] > 0.5


def joint_angle_jump(time: np.ndarray, estimated: np.ndarray, true: np.ndarray,
                     names: list[str]) -> tuple[float, str]:
    """The largest frame-to-frame change of a joint's error against the truth, and where.

    Per joint, the error is the rotation ``R_true^T R_estimated`` of its three angles; its change
    over one frame is a geodesic angle, so the measure is the same whichever Euler triple either
    side holds and stays meaningful where Euler angles are not (at ``|middle| = 90`` deg a tiny
    turn moves the first and third angles by tens of degrees on both sides alike). For a pop about
    one anatomical axis it equals the change of that angle's error. Angles of incomplete joints
    are compared one by one.

    Args:
        time: (N,) [s].
        estimated: (N, J) joint angles of the solve [deg].
        true: (N, J) the truth's at the same times [deg].
        names: (J,) angle names; the toes (``...BallFoot...``) are left out.

    Returns:
        The largest change [deg] (0 for fewer than two frames), and ``"<angle> at <t> s"`` (the
        frame the change ends on; of the joint's angles the one whose error changed most).
    """
    specs = load_joint_specs()
    triples = [list(row) for row in sequence_columns(names, specs)
               if "BallFoot" not in names[row[0]]]
    in_triples = {k for row in triples for k in row}
    singles = [k for k, n in enumerate(names) if "BallFoot" not in n and k not in in_triples]
    if len(time) < 2 or not (triples or singles):
        return 0.0, ""
    jumps = []  # per joint or single angle: (N - 1,) [deg]
    for row in triples:
        spec = specs[names[row[0]].rsplit("_", 1)[0]]
        order = [spec.column(a.name) for a in spec.angles]
        cols = [next(k for k in row if names[k] == c) for c in order]
        R_est = spec.rotation(np.radians(estimated[:, cols]))
        R_true = spec.rotation(np.radians(true[:, cols]))
        error = np.swapaxes(R_true, -1, -2) @ R_est
        jumps.append(np.degrees(angle_between(error[:-1], error[1:])))
    for single in singles:
        error = (estimated[:, single] - true[:, single] + 180.0) % 360.0 - 180.0
        jumps.append(np.abs((np.diff(error) + 180.0) % 360.0 - 180.0))
    table = np.stack(jumps, axis=1)
    k, j = (int(i) for i in np.unravel_index(int(np.argmax(table)), table.shape))
    columns = triples[j] if j < len(triples) else [singles[j - len(triples)]]
    change = np.abs(np.diff(estimated[k:k + 2, columns] - true[k:k + 2, columns], axis=0))[0]
    angle = names[columns[int(np.argmax((change + 180.0) % 360.0 - 180.0))]]
    return float(table[k, j]), f"{angle} at {time[k + 1]:.2f} s"


def evaluate(result_dir: str | Path, truth_path: str | Path, align: str = "auto") -> Evaluation:
    """Compare a ``solve`` result folder with a ``truth.npz``.

    Args:
        result_dir: The result folder.
        truth_path: The truth file of ``simulate``.
        align: ``"auto"`` (shift IMU-only results to the true start), ``"start"`` or
            ``"none"``.

    Raises:
        InputError: Missing files or columns, no overlapping time span.
    """
    folder = Path(result_dir)
    truth_file = Path(truth_path)
    truth = read_truth(truth_file)
    t_true = truth["time"]
    header, rows = _read_table(folder / "joint_angles.csv")
    t_est = _floats(folder / "joint_angles.csv", header, rows, ["time"])[:, 0]
    span = (t_true >= t_est[0] - 1e-6) & (t_true <= t_est[-1] + 1e-6)  # CSV: 6 decimals
    if span.sum() < 2:
        raise InputError("no common time span with the truth", path=folder / "joint_angles.csv")
    t = t_true[span]
    names = [str(n) for n in truth["joint_angle_names"]]
    common = [n for n in names if n in header]
    specs = load_joint_specs()
    est_angles = _interp(t, t_est, continuous_columns_deg(
        _floats(folder / "joint_angles.csv", header, rows, common), common, specs))
    true_angles = continuous_columns_deg(
        truth["joint_angles"][:, [names.index(n) for n in common]], common, specs)[span]
    est_angles = nearest_columns_deg(est_angles, true_angles, common, specs)
    diff = (est_angles - true_angles + 180.0) % 360.0 - 180.0
    per_joint = {n: float(np.sqrt(np.mean(diff[:, k] ** 2))) for k, n in enumerate(common)}

    t_seg, segments = _long_table(folder / "segments.csv", "segment",
                                  ["px", "py", "pz", "qw", "qx", "qy", "qz"])
    true_seg = [str(s) for s in truth["segment_names"]]
    errors = []
    for name, values in segments.items():
        if name not in true_seg:
            continue
        R_est = quat_wxyz_to_matrix(_interp_quat(t, t_seg, values[:, 3:]))
        R_true = quat_wxyz_to_matrix(truth["quat_wxyz_world_segment"][span, true_seg.index(name)])
        errors.append(np.degrees(angle_between(R_est, R_true)))

    t_site, sites = _long_table(folder / "sites.csv", "site", ["x", "y", "z"])
    true_sites = [str(s) for s in truth["site_names"]]
    summary_path = folder / "summary.json"
    used_uwb = bool(summary_path.is_file()
                    and json.loads(summary_path.read_text()).get("uwb", {}).get("used", False))
    shift = np.zeros(3)
    aligned = align == "start" or (align == "auto" and not used_uwb)
    if aligned and "Pelvis" in segments:
        p0 = _interp(t[:1], t_seg, segments["Pelvis"][:, :3])[0]
        shift[:2] = (truth["p_world_segment"][span][0, true_seg.index("Pelvis")] - p0)[:2]
    head = _interp(t, t_site, sites["HeadTop"]) + shift
    head_true = truth["p_world_site"][span][:, true_sites.index("HeadTop")]
    head_err = head - head_true
    contact_names = [str(c) for c in truth["contact_names"]]
    P = np.stack([_interp(t, t_site, sites[c]) for c in contact_names], axis=1)
    true_contacts = np.asarray(truth["contacts"][span], dtype=bool)
    slides = phase_slides(P, true_contacts)
    own = [n for n in contact_names if n in true_sites]
    P_true = truth["p_world_site"][span][:, [true_sites.index(n) for n in own]]
    own_cols = [contact_names.index(n) for n in own]
    own_slides = phase_slides(P_true, true_contacts[:, own_cols])
    held_names, held = _solver_contacts(folder / "contacts.csv", t, contact_names)
    held_true = [i for i, n in enumerate(held_names) if n in own]
    excess = excess_slides(P[:, own_cols], P_true, true_contacts[:, own_cols])
    sunk = sunk_steps(held[:, held_true],
                      P_true[:, [own.index(held_names[i]) for i in held_true], 2],
                      [held_names[i] for i in held_true])
    excess_on_floor = excess_slides(P[:, own_cols], P_true, true_contacts[:, own_cols], sunk)
    held_truth_slides = phase_slides(P_true[:, [own.index(held_names[i]) for i in held_true]],
                                     held[:, held_true])
    held_cols = [contact_names.index(n) for n in held_names]
    held_slides = phase_slides(P[:, held_cols], held)
    truth_held = true_contacts[:, held_cols]
    agreement = 100.0 * float(np.mean(held == truth_held)) if held.size else float("nan")
    planted = int(truth_held.sum())
    missed = 100.0 * float(np.sum(truth_held & ~held)) / planted if planted else 0.0
    jump, jump_at = joint_angle_jump(t, est_angles, true_angles, common)
    # against a zero truth the "error" is the estimate's own rotation: its turn per frame
    step, _ = joint_angle_jump(t, est_angles, np.zeros_like(est_angles), common)
    drift = stride = None
    if "Pelvis" in segments:
        pelvis = _interp(t, t_seg, segments["Pelvis"][:, :3]) + shift
        pelvis_true = truth["p_world_segment"][span][:, true_seg.index("Pelvis")]
        drift = drift_percent(t, pelvis, pelvis_true)
        stride = stride_loss_percent(steps(pelvis, pelvis_true,
                                           foot_strikes(t, true_contacts, contact_names)))
    return Evaluation(
        frames=int(span.sum()),
        joint_angle_rms_deg=float(np.sqrt(np.mean(diff**2))),
        segment_orientation_rms_deg=float(np.sqrt(np.mean(np.concatenate(errors) ** 2))),
        head_position_rms_m=float(np.sqrt(np.mean(np.sum(head_err**2, axis=1)))),
        head_position_rms_xy_m=float(np.sqrt(np.mean(np.sum(head_err[:, :2] ** 2, axis=1)))),
        foot_slide_mm=1e3 * float(np.mean(slides)) if slides else 0.0,
        foot_slide_max_mm=1e3 * float(np.max(slides)) if slides else 0.0,
        aligned_start=aligned,
        per_joint_rms_deg=per_joint,
        joint_angle_jump_max_deg=jump,
        joint_angle_jump_at=jump_at,
        start_shift_m=[float(v) for v in shift],
        drift_percent=drift,
        held_slide_mm=1e3 * float(np.mean(held_slides)) if held_slides else 0.0,
        held_slide_max_mm=1e3 * float(np.max(held_slides)) if held_slides else 0.0,
        contact_agreement_pct=agreement,
        contact_missed_pct=missed,
        truth_slide_mm=1e3 * float(np.mean(own_slides)) if own_slides else 0.0,
        held_truth_slide_mm=(1e3 * float(np.mean(held_truth_slides)) if held_truth_slides
                             else 0.0),
        foot_slide_excess_mm=1e3 * float(np.mean(excess)) if excess else None,
        foot_slide_excess_on_floor_mm=(1e3 * float(np.mean(excess_on_floor))
                                       if excess_on_floor else None),
        joint_angle_step_max_deg=step,
        stride_loss_percent=stride,
    )
