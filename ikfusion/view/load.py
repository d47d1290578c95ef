"""Load what ``ikfusion view`` shows into a neutral :class:`~ikfusion.view.scene.Scene`.

PATH can be:

- a ``solve`` result folder (``segments.csv``, ``sites.csv``, ``contacts.csv``,
  ``joint_angles.csv``, ``summary.json``; SPEC section 6), optionally with ``readers.yaml`` and
  ``solve_time.csv`` (``time,solve_time_ms``, per-frame solve time, drawn when present);
- a folder whose sub-folders are result folders: one actor per sub-folder, drawn together;
- a ``simulate`` capture folder (``truth.npz``, optionally ``readers.yaml``);
- a ``retarget`` output folder (``robot_motion.npz``, ``summary.json``): the robot from its
  URDF (or the resized human model) with its planted soles lit;
- a BVH file: its own skeleton, scaled to metres and turned Z-up.

All positions are in the world frame (Z up) in metres, times in seconds.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.bvh import BvhMotion, read_bvh
from ..io.truth_npz import read_truth
from ..mocap.skeleton_map import SEGMENT_PARENTS
from ..model.layout import CONTACT_SITES, TAG_SITES
from .robot import is_retarget_folder, load_retarget_actor
from .scene import Actor, Readers, Scene

#: Parent of each segment of the 23-segment model (the Pelvis is the root).
MODEL_SEGMENT_PARENTS = SEGMENT_PARENTS

#: Leaf segments whose bone ends at a site (the toe tip is the ``*Toe`` contact point).
MODEL_SEGMENT_TIPS: dict[str, str] = {
    "Head": "HeadTop", "LeftToe": "LeftToe", "RightToe": "RightToe",
}


def load_scene(path: str | Path, truth: str | Path | None = None,
               readers: str | Path | None = None) -> Scene:
    """Load a result folder, a capture folder or a BVH file, plus an optional truth ghost.

    Args:
        path: What to show (see the module notes).
        truth: A ``truth.npz`` drawn as a faint ghost on the same timeline.
        readers: A constellation YAML; by default ``readers.yaml`` next to the data is used.

    Returns:
        The scene.

    Raises:
        InputError: PATH is none of the accepted kinds, or a file in it is malformed.
    """
    source = Path(path)
    if not source.exists():
        raise InputError("no such file or folder", path=source)
    notes: list[str] = []
    if source.is_file() and source.suffix.lower() == ".bvh":
        motion = read_bvh(source)
        actors = [load_bvh_actor(source, motion)]
        notes = [f"warning: {w}" for w in motion.warnings]
        folder = source.parent
    elif source.is_file() and source.suffix.lower() == ".npz":
        actors = [load_truth_actor(source, name="truth", ghost=False)]
        folder = source.parent
    elif source.is_dir():
        actors, notes = _folder_actors(source)
        folder = source
    else:
        raise InputError("expected a result folder, a capture folder, truth.npz or a .bvh file",
                         path=source)
    if truth is not None:
        actors.append(load_truth_actor(truth, name="truth", ghost=True))
    notes += [n for a in actors for n in a.notes]
    readers_file = Path(readers) if readers is not None else folder / "readers.yaml"
    found = load_readers(readers_file) if readers is not None or readers_file.is_file() else None
    return Scene(tuple(actors), found, TAG_SITES, str(source), tuple(notes))


def _folder_actors(folder: Path) -> tuple[list[Actor], list[str]]:
    """Actors of a result folder, a folder of result folders, or a capture folder."""
    if is_result_folder(folder):
        actor = load_result_actor(folder, name="subject")
        return [actor], _summary_notes(folder)
    if is_retarget_folder(folder):
        return [load_retarget_actor(folder)], _summary_notes(folder)
    subs = sorted(p for p in folder.iterdir() if p.is_dir() and is_result_folder(p))
    if subs:
        actors = [load_result_actor(p, name=p.name) for p in subs]
        return actors, [n for p in subs for n in _summary_notes(p, prefix=f"{p.name}: ")]
    if (folder / "truth.npz").is_file():
        return [load_truth_actor(folder / "truth.npz", name="truth", ghost=False)], []
    raise InputError("found neither segments.csv (a solve result), sub-folders holding one, "
                     "robot_motion.npz (a retarget output) nor truth.npz (a simulate capture)",
                     path=folder)


def is_result_folder(folder: Path) -> bool:
    """Whether ``folder`` holds the ``segments.csv`` of a solve result."""
    return (folder / "segments.csv").is_file()


# --------------------------------------------------------------------------- CSV reading
def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    """Header and rows of a comma-separated file."""
    if not path.is_file():
        raise InputError("file not found", path=path)
    with path.open(newline="") as f:
        rows = [r for r in csv.reader(f) if r]
    if not rows:
        raise InputError("empty file, expected a header line", path=path, line=1)
    return [h.strip() for h in rows[0]], rows[1:]


def _column(header: list[str], name: str, path: Path) -> int:
    """Index of a required column."""
    if name not in header:
        raise InputError(f"missing column {name!r}; the header has {', '.join(header)}",
                         path=path, line=1, field=name)
    return header.index(name)


def _floats(rows: list[list[str]], columns: Sequence[int], header: list[str],
            path: Path) -> np.ndarray:
    """The given columns of every row as floats, shape (rows, columns)."""
    out = np.empty((len(rows), len(columns)))
    for r, row in enumerate(rows):
        for c, col in enumerate(columns):
            try:
                out[r, c] = float(row[col])
            except (ValueError, IndexError):
                value = row[col] if col < len(row) else "<missing>"
                raise InputError(f"expected a number, found {value!r}", path=path,
                                 line=r + 2, field=header[col]) from None
    return out


def read_wide_csv(path: Path) -> tuple[np.ndarray, list[str], np.ndarray]:
    """A ``time,<name>,...`` table: times (N,), the names, and values (N, len(names))."""
    header, rows = _read_csv(path)
    t = _column(header, "time", path)
    names = [h for i, h in enumerate(header) if i != t]
    cols = [i for i in range(len(header)) if i != t]
    values = _floats(rows, [t, *cols], header, path)
    return values[:, 0], names, values[:, 1:]


def read_long_csv(path: Path, key: str, value_columns: Sequence[str]
                  ) -> tuple[np.ndarray, list[str], np.ndarray]:
    """A ``time,<key>,v...`` table in long form, pivoted.

    Returns:
        Sorted unique times (N,), the keys in order of first appearance, and values
        (N, keys, len(value_columns)); NaN where a key has no row at a time.
    """
    header, rows = _read_csv(path)
    t_col = _column(header, "time", path)
    k_col = _column(header, key, path)
    v_cols = [_column(header, c, path) for c in value_columns]
    numbers = _floats(rows, [t_col, *v_cols], header, path)
    keys = [row[k_col].strip() for row in rows]
    names = list(dict.fromkeys(keys))
    times, frame = np.unique(numbers[:, 0], return_inverse=True)
    slot = {n: i for i, n in enumerate(names)}
    out = np.full((len(times), len(names), len(value_columns)), np.nan)
    out[frame, [slot[k] for k in keys]] = numbers[:, 1:]
    return times, names, out


def _resample(t_out: np.ndarray, t_in: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Values (len(t_in), k) at the times ``t_out`` (exact copy when the times agree)."""
    if len(t_in) == len(t_out) and np.allclose(t_in, t_out, atol=1e-6):
        return values
    return np.column_stack([np.interp(t_out, t_in, values[:, j])
                            for j in range(values.shape[1])]) if values.shape[1] else \
        np.zeros((len(t_out), 0))


# --------------------------------------------------------------------------- sources
def load_result_actor(folder: str | Path, name: str = "subject") -> Actor:
    """One actor from a ``solve`` result folder (SPEC section 6).

    ``segments.csv`` is required; ``sites.csv``, ``contacts.csv``, ``joint_angles.csv`` and
    ``solve_time.csv`` are used when present.
    """
    root = Path(folder)
    time, segments, seg = read_long_csv(root / "segments.csv", "segment",
                                        ("px", "py", "pz", "qw", "qx", "qy", "qz"))
    actor_sites: tuple[str, ...] = ()
    p_site = np.zeros((len(time), 0, 3))
    if (root / "sites.csv").is_file():
        t_site, site_names, p = read_long_csv(root / "sites.csv", "site", ("x", "y", "z"))
        actor_sites = tuple(site_names)
        p_site = _resample(time, t_site, p.reshape(len(t_site), -1)).reshape(len(time), -1, 3)
    contact_names: tuple[str, ...] = ()
    contacts = np.zeros((len(time), 0), dtype=bool)
    if (root / "contacts.csv").is_file():
        t_c, names, values = read_wide_csv(root / "contacts.csv")
        contact_names = tuple(names)
        contacts = _resample(time, t_c, values) > 0.5
    angle_names: tuple[str, ...] = ()
    angles = np.zeros((len(time), 0))
    if (root / "joint_angles.csv").is_file():
        t_a, names, values = read_wide_csv(root / "joint_angles.csv")
        angle_names, angles = tuple(names), _resample(time, t_a, values)
    solve_ms = None
    if (root / "solve_time.csv").is_file():
        t_s, _, values = read_wide_csv(root / "solve_time.csv")
        solve_ms = _resample(time, t_s, values[:, :1])[:, 0]
    return Actor(
        name=name, time=time, segment_names=tuple(segments),
        segment_parents=model_parents(segments), p_world_segment=seg[..., :3],
        quat_wxyz_world_segment=seg[..., 3:],
        segment_tips={s: t for s, t in MODEL_SEGMENT_TIPS.items() if t in actor_sites},
        site_names=actor_sites, p_world_site=p_site, contact_names=contact_names,
        contacts=contacts, angle_names=angle_names, joint_angles_deg=angles,
        solve_time_ms=solve_ms)


def load_truth_actor(path: str | Path, name: str = "truth", ghost: bool = True) -> Actor:
    """One actor from the ``truth.npz`` of ``simulate``.

    See :func:`ikfusion.sim.truth.write_truth` for its keys.
    """
    data = read_truth(path)
    segments = [str(s) for s in data["segment_names"]]
    sites = tuple(str(s) for s in data.get("site_names", np.array([])))
    return Actor(
        name=name, time=np.asarray(data["time"], dtype=float), segment_names=tuple(segments),
        segment_parents=model_parents(segments),
        p_world_segment=np.asarray(data["p_world_segment"], dtype=float),
        quat_wxyz_world_segment=np.asarray(data["quat_wxyz_world_segment"], dtype=float),
        segment_tips={s: t for s, t in MODEL_SEGMENT_TIPS.items() if t in sites},
        site_names=sites,
        p_world_site=np.asarray(data.get("p_world_site", np.zeros((len(data["time"]), 0, 3))),
                                dtype=float),
        contact_names=tuple(str(s) for s in data.get("contact_names", CONTACT_SITES)),
        contacts=np.asarray(data.get("contacts", np.zeros((len(data["time"]), 0))), dtype=bool),
        angle_names=tuple(str(s) for s in data.get("joint_angle_names", np.array([]))),
        joint_angles_deg=np.asarray(data.get("joint_angles", np.zeros((len(data["time"]), 0))),
                                    dtype=float),
        ghost=ghost)


def load_bvh_actor(path: str | Path, motion: BvhMotion | None = None) -> Actor:
    """One actor from a BVH file: its joints as segments, End Sites as tips, Z up, metres.

    The unit and up axis are found as for simulation (:mod:`ikfusion.mocap.skeleton_map`).
    ``motion`` is the file already read (bad samples bridged), if it was.
    """
    from ..mocap.skeleton_map import build_skeleton_map
    from ..rotations import matrix_to_quat_wxyz

    motion = read_bvh(path) if motion is None else motion
    smap = build_skeleton_map(motion, level_feet=False)
    poses = motion.world_poses(smap.scale, smap.up)
    names = list(motion.joint_names)
    ends = [f"{names[int(p)]}_end" for p in motion.end_site_parents]
    return Actor(
        name=Path(path).stem, time=np.asarray(motion.times, dtype=float),
        segment_names=tuple(names), segment_parents=np.asarray(motion.parents, dtype=int),
        p_world_segment=poses.p_world_joint,
        quat_wxyz_world_segment=matrix_to_quat_wxyz(poses.R_world_joint),
        segment_tips={names[int(p)]: e for p, e in zip(motion.end_site_parents, ends)},
        site_names=tuple(ends), p_world_site=poses.p_world_end_site)


def load_readers(path: str | Path) -> Readers:
    """UWB readers from a constellation YAML (SPEC section 3)."""
    from ..uwb.constellation import load_constellation

    constellation = load_constellation(path, allow_empty=True)
    return Readers(constellation.ids, constellation.positions)


def model_parents(segments: Sequence[str]) -> np.ndarray:
    """Parent index of each segment of the model (-1 for the root or an unknown name)."""
    slot = {s: i for i, s in enumerate(segments)}
    parents = [MODEL_SEGMENT_PARENTS.get(s) for s in segments]
    return np.array([slot.get(p, -1) if p is not None else -1 for p in parents], dtype=int)


def _summary_notes(folder: Path, prefix: str = "") -> list[str]:
    """Lines worth showing from ``summary.json`` (frames, rate, solve time, warnings)."""
    file = folder / "summary.json"
    if not file.is_file():
        return []
    try:
        summary = json.loads(file.read_text())
    except json.JSONDecodeError as err:
        raise InputError(f"invalid JSON: {err.msg}", path=file, line=err.lineno) from None
    notes = []
    if "frames" in summary:
        rate = summary.get("rate", summary.get("fps", 0.0))
        notes.append(f"{prefix}{summary['frames']} frames at {rate:.1f} Hz")
    if "joint_limit_violations" in summary:  # a retarget output
        notes.append(f"{prefix}{summary.get('robot')}: joint-limit violations "
                     f"{summary['joint_limit_violations']}, foot slide "
                     f"{summary.get('foot_slide_mm_max', float('nan')):.2f} mm max")
    if "solve_time_ms_mean" in summary:
        notes.append(f"{prefix}solve time per frame: mean "
                     f"{summary['solve_time_ms_mean']:.2f} ms, p95 "
                     f"{summary.get('solve_time_ms_p95', float('nan')):.2f} ms")
    notes.extend(f"{prefix}warning: {w}" for w in summary.get("warnings", []))
    return notes
