"""NaN, infinite and absurd values inside BVH and MVNX motion: bridged when short, else refused.

The clean file is the independent truth: a bridged file must give (nearly) what the clean
one gives, the bad value must never reach the output, and the warning names the file, the
line and the channel.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.errors import InputError, SolverError
from ikfusion.ik.qp import QpProblem, solve_qp
from ikfusion.ik.settings import SolverSettings
from ikfusion.io.bad_samples import MAX_BAD_SHARE, MAX_BRIDGE_SECONDS, bridge_channel
from ikfusion.io.bvh import read_bvh
from ikfusion.io.mvnx import read_mvnx
from ikfusion.retarget.source import HumanMotion

WALK = "mocap/cmu_02_01_walk.bvh"
MVNX = "mvnx/test_mocap.mvnx"


def _bvh_lines(path: Path, frames: int | None = None) -> tuple[list[str], int]:
    """The file's lines (cut to ``frames`` frames) and the index of its first frame line."""
    lines = path.read_text().splitlines()
    motion = next(i for i, line in enumerate(lines) if line.strip() == "MOTION")
    if frames is not None:
        lines = lines[:motion + 3 + frames]
        lines[motion + 1] = f"Frames: {frames}"
    return lines, motion + 3


def _corrupt_bvh(src: Path, dst: Path, cells: dict[tuple[int, int], str],
                 frames: int | None = None) -> Path:
    """A copy of ``src`` with ``cells[(frame, column)]`` (0-based) replaced by text."""
    lines, first = _bvh_lines(src, frames)
    for (frame, column), text in cells.items():
        words = lines[first + frame].split()
        words[column] = text
        lines[first + frame] = " ".join(words)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def _column(path: Path, frame: int, column: int) -> float:
    lines, first = _bvh_lines(path)
    return float(lines[first + frame].split()[column])


@pytest.mark.parametrize("text", ["nan", "1e29", "-inf"])
def test_a_bad_bvh_angle_is_bridged_from_its_neighbours(shared_data: Path, tmp_path: Path,
                                                        text: str) -> None:
    src = shared_data / WALK
    bad = _corrupt_bvh(src, tmp_path / "bad.bvh", {(100, 10): text})
    clean = read_bvh(src)
    motion = read_bvh(bad)
    column = 10  # LeftUpLeg's second rotation channel in this file
    expected = 0.5 * (_column(src, 99, column) + _column(src, 101, column))
    assert motion.channels[100, column] == pytest.approx(expected)
    untouched = np.ones(motion.channels.shape, dtype=bool)
    untouched[100, column] = False
    assert np.array_equal(motion.channels[untouched], clean.channels[untouched])
    (warning,) = motion.warnings
    line = _bvh_lines(src)[1] + 100 + 1
    assert str(bad) in warning and f"line {line}" in warning
    assert motion.channel_names[column] in warning
    kept = read_bvh(bad, bridge=False)  # the raw values stay available on request
    np.testing.assert_equal(kept.channels[100, column], float(text))


def test_bvh_refuses_what_cannot_be_bridged(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / WALK
    n_frames = read_bvh(src).num_frames
    _, first = _bvh_lines(src)
    rate = 1.0 / read_bvh(src).frame_time
    long_run = int(MAX_BRIDGE_SECONDS * rate) + 2
    cases = {
        "every frame": {(k, 4): "nan" for k in range(n_frames)},
        "a long run": {(50 + k, 4): "nan" for k in range(long_run)},
        "too many": {(k, 4): "1e30" for k in range(0, n_frames, int(0.5 / MAX_BAD_SHARE))},
    }
    for name, cells in cases.items():
        bad = _corrupt_bvh(src, tmp_path / f"{name}.bvh", cells)
        with pytest.raises(InputError) as info:
            read_bvh(bad)
        first_bad = min(k for k, _ in cells) if name != "a long run" else 50
        assert info.value.path == bad, name
        assert info.value.line == first + first_bad + 1, name
        assert info.value.field == "Hips.Yrotation", name


@pytest.fixture
def short_walk(shared_data: Path, tmp_path: Path) -> Path:
    """The first 1.5 s of the CMU walk (a quick retarget)."""
    return _corrupt_bvh(shared_data / WALK, tmp_path / "walk.bvh", {}, frames=180)


def _retarget(source: Path, out: Path) -> tuple[int, dict, np.lib.npyio.NpzFile]:
    code = main(["retarget", str(source), "--robot", "human", "--height", "1.6", "--out",
                 str(out), "--quiet"])
    if code != 0:
        return code, {}, None  # type: ignore[return-value]
    return code, json.loads((out / "summary.json").read_text()), np.load(out /
                                                                          "robot_motion.npz")


def test_retarget_of_a_clip_with_nan_and_a_far_root_tracks_the_clean_clip(
        short_walk: Path, tmp_path: Path) -> None:
    """The reported symptom: exit 0 with frames tens of degrees off (or a hang, a far root)."""
    code, _, clean = _retarget(short_walk, tmp_path / "clean")
    assert code == 0
    bad = _corrupt_bvh(short_walk, tmp_path / "bad.bvh",
                       {(100, 10): "nan", (60, 0): "1e30", (120, 14): "1e29"})
    code, summary, out = _retarget(bad, tmp_path / "bad")
    assert code == 0
    assert np.all(np.isfinite(out["dof_pos"]))
    worst = np.degrees(np.abs(out["dof_pos"] - clean["dof_pos"])).max()
    assert worst < 5.0, f"a joint is {worst:.1f} deg away from the clean clip's"
    assert np.abs(out["root_pos"] - clean["root_pos"]).max() < 0.02
    text = "\n".join(summary["warnings"])
    for channel, line in (("LeftUpLeg.Yrotation", 101), ("Hips.Xposition", 61),
                          ("LeftLeg.Xrotation", 121)):
        assert channel in text and f"line {_bvh_lines(bad)[1] + line}" in text


def test_retarget_and_view_refuse_an_unbridgeable_clip_with_exit_2(
        short_walk: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = _corrupt_bvh(short_walk, tmp_path / "bad.bvh", {(k, 0): "nan" for k in range(180)})
    assert main(["retarget", str(bad), "--robot", "human", "--height", "1.6", "--out",
                 str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "Hips.Xposition" in err and "line" in err
    assert not (tmp_path / "out").exists()


def test_view_of_a_clip_with_a_far_root_saves_and_warns(
        short_walk: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("rerun")
    bad = _corrupt_bvh(short_walk, tmp_path / "bad.bvh", {(60, 0): "1e30"})
    assert main(["view", str(bad), "--save", str(tmp_path / "bad.rrd")]) == 0
    assert "Hips.Xposition" in capsys.readouterr().err
    assert (tmp_path / "bad.rrd").stat().st_size > 0


def _corrupt_mvnx(src: Path, dst: Path, frame: int, element: str, column: int,
                  text: str) -> tuple[Path, int]:
    """A copy with one number of ``<element>`` of normal frame ``index`` replaced; its line."""
    lines = src.read_text().split("\n")
    start = next(i for i, line in enumerate(lines)
                 if f'index="{frame}"' in line and 'type="normal"' in line)
    k = next(i for i in range(start, len(lines)) if lines[i].strip().startswith(f"<{element}>"))
    head, rest = lines[k].split(f"<{element}>")
    body, tail = rest.split(f"</{element}>")
    words = body.split()
    words[column] = text
    lines[k] = f"{head}<{element}>{' '.join(words)}</{element}>{tail}"
    dst.write_text("\n".join(lines))
    return dst, k + 1


def test_mvnx_segment_position_and_orientation_are_bridged(shared_data: Path,
                                                           tmp_path: Path) -> None:
    src = shared_data / MVNX
    clean = read_mvnx(src)
    bad, line = _corrupt_mvnx(src, tmp_path / "far.mvnx", 50, "position", 0, "1e30")
    rec = read_mvnx(bad)
    k = int(np.flatnonzero(clean.frame_index == 50)[0])
    expected = 0.5 * (clean.p_world_segment[k - 1, 0] + clean.p_world_segment[k + 1, 0])
    np.testing.assert_allclose(rec.p_world_segment[k, 0], expected)
    assert any("position of Pelvis" in w and f"line {line}" in w and str(bad) in w
               for w in rec.warnings)
    bad, line = _corrupt_mvnx(src, tmp_path / "nan.mvnx", 50, "orientation", 5, "NaN")
    rec = read_mvnx(bad)
    assert np.all(np.isfinite(rec.quat_wxyz_world_segment))
    assert any("orientation of L5" in w and f"line {line}" in w for w in rec.warnings)
    bad, _ = _corrupt_mvnx(src, tmp_path / "inf.mvnx", 50, "sensorOrientation", 0, "inf")
    rec = read_mvnx(bad)
    assert np.isnan(rec.quat_wxyz_world_sensor[k, 0]).all()  # a missing sample
    assert np.isfinite(rec.quat_wxyz_world_sensor[k, 1:]).all()


def test_mvnx_refuses_a_segment_without_good_frames(shared_data: Path, tmp_path: Path) -> None:
    text = (shared_data / MVNX).read_text()
    start = text.index('type="normal"')
    body = re.sub(r"<position>\S+ ", "<position>nan ", text[start:])
    bad = tmp_path / "all.mvnx"
    bad.write_text(text[:start] + body)
    with pytest.raises(InputError) as info:
        read_mvnx(bad)
    assert info.value.field == "position of Pelvis" and info.value.path == bad
    assert info.value.line is not None
    assert bad.read_text().splitlines()[info.value.line - 1].strip().startswith("<position>")


def test_bridge_channel_interpolates_angles_the_short_way_and_holds_at_the_ends() -> None:
    values = np.full(30, -160.0)
    values[:3] = [170.0, np.nan, -170.0]
    values[-1] = np.nan
    out, warning = bridge_channel(values, np.isnan(values), rate=100.0, path=None,
                                  channel="x", kind="angle_deg")
    np.testing.assert_allclose(out[:3], [170.0, 180.0, -170.0])
    np.testing.assert_allclose(out[3:], -160.0)
    assert warning is not None and "frame 2," in warning and "frame 30" in warning


def test_qp_refuses_non_finite_numbers_with_a_clear_error() -> None:
    n = 6
    c = np.zeros(n)
    c[2] = np.nan
    problem = QpProblem(np.eye(n), c, np.zeros((0, n)), np.zeros(0), np.zeros((0, n)),
                        np.zeros(0))
    with pytest.raises(SolverError, match="NaN or infinite numbers in c"):
        settings = SolverSettings.load()
        solve_qp(problem, settings.backend, settings.qp)


def test_retarget_refuses_a_motion_with_a_far_pose() -> None:
    n = 3
    R = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
    p = np.zeros((n, 2, 3))
    p[1, 0, 0] = 1e30
    motion = HumanMotion(np.arange(n) / 60.0, ["Pelvis", "RightUpperLeg"], p, R, [],
                         np.zeros((n, 0), dtype=bool), 0.9, "api")
    with pytest.raises(InputError, match="frame 1 .* position of Pelvis"):
        motion.check()
