"""``live --view``: the bodies drawn in Rerun as they are solved (a .rrd file, the web page)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.view.serve import free_port

rerun = pytest.importorskip("rerun", reason="live --view needs rerun-sdk (extra 'view')")

SEGMENTS = 23


def _joint_frames(rrd: Path, entity: str) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] (N,) and segment origins (N, S, 3) [m] logged at ``entity`` in an .rrd file."""
    store = rerun.chunk.RrdReader(rrd).store()
    times: list[float] = []
    points: list[np.ndarray] = []
    for chunk in store.stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        nanoseconds = batch.column("time").to_numpy().astype("timedelta64[ns]").astype(np.int64)
        times += list(nanoseconds / 1e9)
        points += [np.array(row, dtype=float) for row in
                   batch.column("Points3D:positions").to_pylist()]
    order = np.argsort(times, kind="stable")
    return np.array(times)[order], np.stack(points)[order]


def _segments_csv(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) and segment origins (N, S, 3) [m] of a result folder's segments.csv."""
    lines = (folder / "segments.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    t, px = header.index("time"), header.index("px")
    table = np.array([[float(r[t])] + [float(v) for v in r[px:px + 3]] for r in rows])
    table = table.reshape(-1, SEGMENTS, 4)
    return table[:, 0, 0], table[:, :, 1:]


def test_view_recording_holds_every_frame_of_the_record(capture: Path, tmp_path: Path) -> None:
    """``--view FILE.rrd`` during a replay: every solved frame is on the timeline at its
    capture time, its segment origins those of the ``--record`` result folder within 1e-4 m
    (``--view`` exited 2, "not available", before)."""
    rrd, live = tmp_path / "live.rrd", tmp_path / "live"
    assert main(["live", "--replay", str(capture), "--speed", "0", "--record", str(live),
                 "--view", str(rrd), "--quiet"]) == 0
    t_view, p_view = _joint_frames(rrd, "/world/actor/joints")
    t_rec, p_rec = _segments_csv(live)
    assert len(t_rec) == 600 and p_view.shape == p_rec.shape == (600, SEGMENTS, 3)
    np.testing.assert_allclose(t_view, t_rec, atol=1e-6, rtol=0)
    np.testing.assert_allclose(p_view, p_rec, atol=1e-4, rtol=0)
    store = rerun.chunk.RrdReader(rrd).store()
    assert any(c.entity_path == "/world/readers" for c in store.stream().to_chunks())


def test_view_needs_the_extra_before_anything_starts(capture: Path, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """Without rerun-sdk, ``--view`` is exit 2 naming the extra, and nothing was recorded."""
    monkeypatch.setitem(sys.modules, "rerun", None)  # makes `import rerun` fail
    live = tmp_path / "live"
    assert main(["live", "--replay", str(capture), "--speed", "0", "--record", str(live),
                 "--view", "--quiet"]) == 2
    assert "pip install 'ikfusion[view]'" in capsys.readouterr().err
    assert not live.exists()


def test_view_target_is_checked(capture: Path, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    """A --view target that is no viewer and no .rrd file is a usage error (exit 2)."""
    assert main(["live", "--replay", str(capture), "--speed", "0", "--view",
                 str(tmp_path / "x.txt"), "--quiet"]) == 2
    assert "--view takes web, native or a file name ending in .rrd" in capsys.readouterr().err


def _children(pid: int) -> list[int]:
    """Process ids of the children of ``pid`` (Linux /proc)."""
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        out += [int(c) for c in (task / "children").read_text().split()]
    return out


def test_web_view_serves_the_page_and_a_closed_viewer_does_not_stop_live(
        capture: Path, tmp_path: Path) -> None:
    """``--view web``: the page is served from this machine while the replay runs; when the
    viewer's server goes away mid-stream, live carries on and records every frame."""
    live = tmp_path / "live"
    env = {**os.environ, "PYTHONPATH": os.environ.get("PYTHONPATH") or
           str(Path(__file__).resolve().parents[3])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikfusion", "live", "--replay", str(capture), "--speed", "1",
         "--record", str(live), "--view", "web", "--no-browser", "--view-port",
         str(free_port()), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stderr is not None
        url = None
        for line in proc.stderr:
            found = re.search(r"viewer at (http://\S+)", line)
            if found:
                url = found.group(1)
                break
        assert url is not None and url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        servers = _children(proc.pid)
        assert servers, "no viewer server process"
        for pid in servers:  # the viewer goes away while frames are still coming
            os.kill(pid, signal.SIGKILL)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    solved = int(re.search(r"(\d+) frames solved", out).group(1))  # type: ignore[union-attr]
    summary = json.loads((live / "summary.json").read_text())
    assert summary["live"]["complete"] is True and summary["frames"] == solved > 0
    assert len((live / "joint_angles.csv").read_text().splitlines()) == solved + 1
    assert any("the viewer went away" in w for w in summary["warnings"])


def test_the_web_viewer_server_ends_with_a_killed_live(capture: Path) -> None:
    """``live --view web`` killed (SIGKILL, no clean-up) leaves no viewer server holding its
    ports (Linux)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("the server is tied to live's lifetime on Linux")
    env = {**os.environ, "PYTHONPATH": os.environ.get("PYTHONPATH") or
           str(Path(__file__).resolve().parents[3])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikfusion", "live", "--replay", str(capture), "--speed", "1",
         "--view", "web", "--no-browser", "--view-port", str(free_port()), "--quiet"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    servers: list[int] = []
    try:
        assert proc.stderr is not None
        assert any("viewer at http://" in line for line in proc.stderr)
        servers = _children(proc.pid)
        assert servers, "no viewer server process"
    finally:
        proc.kill()
        proc.wait()
    deadline = time.monotonic() + 10.0
    while any(_state(pid) and "zombie" not in _state(pid) for pid in servers):
        assert time.monotonic() < deadline, "the viewer server outlived live"
        time.sleep(0.1)


def _state(pid: int) -> str:
    """A process's state from /proc (``zombie``, ``sleeping``...), or "" once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return ""
    return next((line for line in status.splitlines() if line.startswith("State:")), "").lower()


def test_sink_draws_every_frame_of_every_actor(result_poses: list, tmp_path: Path) -> None:
    """Two actors in 20 Hz batches of a 30 Hz stream: each actor's every frame is on the
    timeline with its own segment origins, its curves named after it."""
    from dataclasses import replace

    from ikfusion.live.rerun_view import RerunViewSink

    rrd = tmp_path / "two.rrd"
    rec = rerun.RecordingStream("test")
    rec.save(rrd)
    sink = RerunViewSink(rec, 20.0, several=True)
    shifted = [replace(p, actor="B", p_world_segment=p.p_world_segment + [1.0, 0.0, 0.0])
               for p in result_poses]
    for a, b in zip(result_poses, shifted):
        sink.send([a, b])
    sink.close()
    for poses in (result_poses, shifted):
        t, p = _joint_frames(rrd, f"/world/{poses[0].actor}/joints")
        np.testing.assert_allclose(t, [q.time_s for q in poses], atol=1e-6, rtol=0)
        np.testing.assert_allclose(p, np.stack([q.p_world_segment for q in poses]),
                                   atol=1e-4, rtol=0)
    for actor in ("A", "B"):
        names = [str(v) for c in rerun.chunk.RrdReader(rrd).store().stream().to_chunks()
                 if c.entity_path == f"/plots/{actor}/angles/jRightKnee_flex" and c.is_static
                 for v in c.to_record_batch().column("SeriesLines:names").to_pylist()]
        assert names and f"jRightKnee_flex ({actor})" in names[0]


def test_native_view_without_a_display_is_a_usage_error(capture: Path, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    """``--view native`` on a Linux machine without a display: exit 2 at once, nothing
    recorded (it was an internal error: the viewer program was looked up on PATH)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    live = tmp_path / "live"
    assert main(["live", "--replay", str(capture), "--speed", "0", "--record", str(live),
                 "--view", "native", "--quiet"]) == 2
    assert "--view native needs a display" in capsys.readouterr().err
    assert not live.exists()
