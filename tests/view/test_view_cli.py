"""``ikfusion view`` end to end: a saved ``.rrd`` and the served page in headless Chromium.

The browser test needs /usr/bin/chromium (Debian package ``chromium``) and no network: every
host but 127.0.0.1 is unreachable from the page.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from view_headless import CHROMIUM, Browser, body_pixels, wait_for_body
from view_motion import FRAMES, RATE

from ikfusion.view.serve import free_port

rerun = pytest.importorskip("rerun", reason="ikfusion view needs rerun-sdk (extra 'view')")


def _times_of(rrd: Path, entity: str) -> np.ndarray:
    """Values [s] of the ``time`` timeline at which ``entity`` was logged in an ``.rrd`` file."""
    store = rerun.chunk.RrdReader(rrd).store()
    values: list[float] = []
    for chunk in store.stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        column = chunk.to_record_batch().column("time")
        values += [v.total_seconds() for v in column.to_pylist()]
    return np.unique(values)


def test_save_writes_a_recording_with_every_frame(result_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "motion.rrd"
    done = subprocess.run([sys.executable, "-m", "ikfusion", "view", str(result_folder),
                           "--save", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    times = _times_of(out, "/world/subject/bones")
    assert len(times) == FRAMES
    assert times[-1] - times[0] == pytest.approx((FRAMES - 1) / RATE, abs=1e-6)
    assert len(_times_of(out, "/plots/subject/angles/jRightKnee_flex")) == FRAMES


def test_save_needs_rrd_suffix(result_folder: Path, tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "ikfusion", "view", str(result_folder),
                           "--save", str(tmp_path / "motion.html")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2
    assert ".rrd" in done.stderr


def _read_url(proc: subprocess.Popen[str], timeout: float) -> str:
    """The page address the server prints (``viewer at URL``)."""
    lines: queue.Queue[str] = queue.Queue()
    assert proc.stdout is not None
    stdout = proc.stdout

    def pump() -> None:
        for line in stdout:
            lines.put(line)

    threading.Thread(target=pump, daemon=True).start()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1.0)
        except queue.Empty:
            if proc.poll() is not None:
                break
            continue
        if line.startswith("viewer at "):
            return line.split(" ", 2)[2].strip()
    raise AssertionError(f"no viewer address within {timeout} s (exit code {proc.poll()})")


def _step_until_moved(browser: Browser, start: np.ndarray, png: Path, timeout: float) -> float:
    """Step the time cursor forward (arrow key) until the body has walked away from where it
    stood in ``start``; returns how far its pixels' centroid moved [px].

    The demo stands still for 2 s; software rendering lags, so each step is given time.
    """
    deadline = time.monotonic() + timeout
    origin = np.argwhere(start).mean(axis=0)
    while True:
        for _ in range(10):
            browser.press_key("ArrowRight", "ArrowRight", 39)
        time.sleep(4.0)
        browser.screenshot(png)
        body = body_pixels(png)
        shift = float(np.linalg.norm(np.argwhere(body).mean(axis=0) - origin)) if body.sum() > 200 \
            else 0.0
        if shift > 20.0 or time.monotonic() > deadline:
            return shift


@pytest.fixture(scope="module")
def demo_result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``ikfusion demo`` on a short walk: ``result/`` and ``capture/``."""
    from ikfusion.cli import main

    out = tmp_path_factory.mktemp("demo") / "demo"
    assert main(["demo", "--out", str(out), "--seconds", "5", "--quiet"]) == 0
    return out


@pytest.mark.skipif(not os.path.exists(CHROMIUM),
                    reason=f"{CHROMIUM} is absent (apt-get install chromium)")
def test_served_page_draws_the_body_and_plays(demo_result: Path, tmp_path: Path) -> None:
    """The acceptance test: a demo's result (and its truth as a ghost) in headless Chromium."""
    pytest.importorskip("PIL.Image")
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikfusion", "view", str(demo_result / "result"), "--truth",
         str(demo_result / "capture" / "truth.npz"), "--no-browser", "--port", str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        url = _read_url(proc, timeout=120)
        assert url.startswith(f"http://127.0.0.1:{port}/")
        with Browser() as browser:
            browser.goto(url)
            browser.press_space()  # play and pause at once: the time cursor appears near 0 s
            browser.press_space()
            start = tmp_path / "view_start.png"
            assert wait_for_body(browser, start, timeout=150) > 200, "no body drawn at the start"
            later = tmp_path / "view_later.png"
            shift = _step_until_moved(browser, body_pixels(start), later, timeout=240)
            assert int(body_pixels(later).sum()) > 200, "no body drawn later on the timeline"
            assert shift > 20.0, "the body did not move along the timeline"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _lan_address() -> str | None:
    """This machine's address on its network (not loopback), or None without one.

    Connecting a UDP socket sends nothing; it only picks the interface a packet would leave by.
    """
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.1", 9))
        except OSError:
            return None
        address = str(s.getsockname()[0])
    return None if address.startswith("127.") or address == "0.0.0.0" else address


def _accepts(address: str, port: int) -> bool:
    import socket

    try:
        with socket.create_connection((address, port), timeout=2.0):
            return True
    except OSError:
        return False


@pytest.mark.parametrize("host", [None, "0.0.0.0"])
def test_view_listens_on_this_machine_only_unless_told(result_folder: Path,
                                                       host: str | None) -> None:
    """The page has no password: by default other machines must not reach it."""
    lan = _lan_address()
    if lan is None:
        pytest.skip("this machine has no network address besides loopback")
    port = free_port()
    command = [sys.executable, "-m", "ikfusion", "view", str(result_folder), "--no-browser",
               "--port", str(port)] + ([] if host is None else ["--host", host])
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)
    try:
        url = _read_url(proc, timeout=120)
        grpc_port = int(url.split("%3A")[-1].split("%2F")[0])
        assert _accepts("127.0.0.1", port) and _accepts("127.0.0.1", grpc_port)
        reachable = _accepts(lan, port), _accepts(lan, grpc_port)
        assert reachable == ((False, False) if host is None else (True, True)), url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_port_in_use_is_a_usage_error(result_folder: Path) -> None:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        taken.bind(("0.0.0.0", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = subprocess.run([sys.executable, "-m", "ikfusion", "view", str(result_folder),
                               "--no-browser", "--port", str(port)],
                              capture_output=True, text=True, timeout=300)
    assert done.returncode == 2
    assert f"port {port} is in use" in done.stderr


def test_missing_rerun_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    from ikfusion.view.draw import ViewerUnavailable, require_rerun

    monkeypatch.setitem(sys.modules, "rerun", None)  # makes `import rerun` fail
    with pytest.raises(ViewerUnavailable, match=r"ikfusion\[view\]"):
        require_rerun()
