"""``benchmarks/bench_drift_steps.py``: the pelvis's lost distance split into the held point's
motion and the body's shape, on a hand-made capture whose answer is known."""

from __future__ import annotations

import csv
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from benchmark_scripts import benchmark_script

FEET = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]


def _drift_steps() -> ModuleType:
    """``benchmarks/bench_drift_steps.py`` as a module."""
    return benchmark_script("bench_drift_steps.py")


def _write(path: Path, header: list[str], rows: list[list[object]]) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)


def _heel_walk(tmp_path: Path, segment_names: list[str], p_segments: np.ndarray
               ) -> tuple[Path, np.ndarray]:
    """A capture of 4 frames at 60 Hz over a planted left heel (the other points still, not
    planted), its segments ``p_segments`` (4, n, 3) [m]: the folder and the sites (4, 4, 3)."""
    heel = np.array([0.5, 0.1, 0.0])
    sites_true = np.tile(np.array([heel, heel + [0.2, 0, 0], heel - [0, 0.2, 0],
                                   heel + [0.2, -0.2, 0]]), (4, 1, 1))
    capture = tmp_path / "capture"
    capture.mkdir()
    contacts = np.zeros((4, 4), dtype=bool)
    contacts[:, 0] = True
    np.savez(capture / "truth.npz", time=np.arange(4) / 60.0,
             segment_names=np.array(segment_names), site_names=np.array(FEET),
             contact_names=np.array(FEET), p_world_segment=p_segments,
             p_world_site=sites_true, contacts=contacts)
    return capture, sites_true


def test_lost_distance_splits_into_point_and_shape(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The pelvis walks +x 10 mm per frame over a planted left heel. The solve holds that heel:
    in frame 2 its pelvis falls 3 mm behind with the heel in place (the body's shape), in frame
    3 the held heel slips 2 mm back and the pelvis with it (the point): -5 = -2 + -3 mm."""
    t = np.arange(4) / 60.0
    pelvis_true = np.array([[0.0, 0, 1], [0.01, 0, 1], [0.02, 0, 1], [0.03, 0, 1]])
    capture, sites_true = _heel_walk(tmp_path, ["Pelvis"], pelvis_true[:, None, :])
    result = tmp_path / "result"
    result.mkdir()
    pelvis_solved = pelvis_true + [[0, 0, 0], [0, 0, 0], [-0.003, 0, 0], [-0.005, 0, 0]]
    sites_solved = sites_true.copy()
    sites_solved[3, 0, 0] -= 0.002
    _write(result / "segments.csv", ["time", "segment", "px", "py", "pz"],
           [[tk, "Pelvis", *p] for tk, p in zip(t, pelvis_solved, strict=True)])
    _write(result / "sites.csv", ["time", "site", "x", "y", "z"],
           [[tk, name, *sites_solved[k, i]] for k, tk in enumerate(t)
            for i, name in enumerate(FEET)])
    _write(result / "contacts.csv", ["time", *FEET], [[tk, 1, 0, 0, 0] for tk in t])

    assert _drift_steps().main([str(capture), str(result), "--frames", "0", "1"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("LeftHeel (truth:1)"))
    frames, pelvis, moved, point, shape = row.split()[2:]
    assert (int(frames), float(pelvis), float(moved)) == (3, -5.0, 0.0)
    assert (float(point), float(shape)) == (-2.0, -3.0)
    gains = [float(line.split()[3]) for line in out.splitlines()[-4:]]
    assert gains == [0.0, 0.0, -3.0, -2.0]


def test_a_short_stride_on_a_closed_path_is_counted(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Issue #19: a walk round a 2 m circle whose solved pelvis keeps 98 % of every stride
    (a circle 2 % smaller through the same start) ends where the truth ends after a full lap
    (end error 0 mm): the step sums say the pelvis fell 2 % short. Heel strikes alternate
    every 0.35 m of the circle."""
    n = 361
    t = np.arange(n) / 60.0
    angle = np.linspace(0.0, 2 * np.pi, n)
    pelvis_true = np.stack([2 * np.sin(angle), 2 * (1 - np.cos(angle)), np.ones(n)], axis=1)
    pelvis_solved = pelvis_true * [0.98, 0.98, 1.0]
    contacts = np.zeros((n, 4), dtype=bool)
    phase = (np.arange(n) // 18) % 2  # 0.3 s per step
    contacts[:, 0] = phase == 0
    contacts[:, 2] = phase == 1
    sites = np.repeat(pelvis_true[:, None, :] * [1, 1, 0], 4, axis=1)
    capture = tmp_path / "capture"
    capture.mkdir()
    np.savez(capture / "truth.npz", time=t, segment_names=np.array(["Pelvis"]),
             site_names=np.array(FEET), contact_names=np.array(FEET),
             p_world_segment=pelvis_true[:, None, :], p_world_site=sites, contacts=contacts)
    result = tmp_path / "result"
    result.mkdir()
    _write(result / "segments.csv", ["time", "segment", "px", "py", "pz"],
           [[tk, "Pelvis", *p] for tk, p in zip(t, pelvis_solved, strict=True)])
    _write(result / "sites.csv", ["time", "site", "x", "y", "z"],
           [[tk, name, *sites[k, i]] for k, tk in enumerate(t) for i, name in enumerate(FEET)])
    _write(result / "contacts.csv", ["time", *FEET], [[tk, 0, 0, 0, 0] for tk in t])

    assert _drift_steps().main([str(capture), str(result)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("end error 0.0 mm")
    line = next(line for line in out.splitlines() if line.startswith("steps:"))
    assert line.split("(")[1].split()[0] == "2.00"


def test_shape_splits_into_the_links_of_the_held_leg(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """The pelvis walks +x 10 mm per frame over a planted left heel, the legs' joints still.
    In frame 2 the solve's left hip (and the pelvis with it) falls 3 mm behind while its knee,
    ankle and heel stay where the truth's are: the body's shape lost 3 mm, all in the thigh."""
    t = np.arange(4) / 60.0
    pelvis_true = np.array([[0.0, 0, 1], [0.01, 0, 1], [0.02, 0, 1], [0.03, 0, 1]])
    legs = {f"{side}{name}": np.array([0.5 + 0.05 * k, 0.1 * s, z])
            for side, s in (("Left", 1.0), ("Right", -1.0))
            for k, (name, z) in enumerate((("Foot", 0.08), ("LowerLeg", 0.5),
                                           ("UpperLeg", 0.9), ("Toe", 0.02)))}
    segment_names = ["Pelvis", *legs]
    p_segments = np.concatenate([pelvis_true[:, None, :],
                                 np.tile(np.array(list(legs.values())), (4, 1, 1))], axis=1)
    capture, sites_true = _heel_walk(tmp_path, segment_names, p_segments)
    result = tmp_path / "result"
    result.mkdir()
    p_solved = p_segments.copy()
    behind = [segment_names.index("Pelvis"), segment_names.index("LeftUpperLeg")]
    p_solved[2:, behind, 0] -= 0.003
    _write(result / "segments.csv", ["time", "segment", "px", "py", "pz"],
           [[tk, name, *p_solved[k, j]] for k, tk in enumerate(t)
            for j, name in enumerate(segment_names)])
    _write(result / "sites.csv", ["time", "site", "x", "y", "z"],
           [[tk, name, *sites_true[k, i]] for k, tk in enumerate(t)
            for i, name in enumerate(FEET)])
    _write(result / "contacts.csv", ["time", *FEET], [[tk, 1, 0, 0, 0] for tk in t])

    assert _drift_steps().main([str(capture), str(result)]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("LeftHeel (truth:1)"))
    assert [float(x) for x in row.split()[3:]] == [-3.0, 0.0, 0.0, -3.0]
    line = next(line for line in out.splitlines() if line.startswith("shape by link"))
    parts = dict(zip(line.split(": ")[1].split()[::2],
                     map(float, line.split(": ")[1].split()[1::2]), strict=True))
    assert parts == {"toe": 0.0, "foot": 0.0, "shank": 0.0, "thigh": -3.0, "pelvis": 0.0}
