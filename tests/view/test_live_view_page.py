"""``live --view web`` in headless Chromium: the body is drawn and the view follows the stream.

Needs /usr/bin/chromium (Debian package ``chromium``); the page reaches only 127.0.0.1.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from view_headless import CHROMIUM, Browser, body_pixels, wait_for_body

from ikfusion.cli import main
from ikfusion.view.serve import free_port

pytest.importorskip("rerun", reason="live --view needs rerun-sdk (extra 'view')")
ROOM = Path(__file__).resolve().parents[2] / "configs" / "constellations" / "room_6x8.yaml"


@pytest.mark.skipif(not os.path.exists(CHROMIUM),
                    reason=f"{CHROMIUM} is absent (apt-get install chromium)")
def test_live_page_draws_the_body_and_follows_the_newest_frame(tmp_path: Path) -> None:
    """A 40 s walk replayed at half its pace (80 s of stream): the page shows the body without
    any click, and while the stream goes on the body walks on (the time cursor follows it).

    The page can take tens of seconds to load on a busy machine (a 40 s stream once ended
    before Chromium drew it), so the stream is long, the test stops it as soon as the body has
    moved, and the body's movement is polled rather than sampled once at a fixed delay."""
    pytest.importorskip("PIL.Image")
    capture = tmp_path / "capture"
    assert main(["simulate", "--motion", "gait", "--seconds", "40", "--readers", str(ROOM),
                 "--seed", "3", "--out", str(capture), "--quiet"]) == 0
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikfusion", "live", "--replay", str(capture), "--speed", "0.5",
         "--view", "web", "--no-browser", "--view-port", str(free_port()), "--quiet"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        url = next((m.group(1) for line in proc.stderr
                    if (m := re.search(r"viewer at (http://\S+)", line))), None)
        assert url is not None and url.startswith("http://127.0.0.1:")
        with Browser() as browser:
            browser.goto(url)
            first = tmp_path / "first.png"
            assert wait_for_body(browser, first, timeout=90) > 200, "no body drawn"
            assert proc.poll() is None, "the replay ended before the page drew the body"
            shift, deadline = 0.0, time.monotonic() + 30.0
            while shift <= 20.0 and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(1.0)
                later = tmp_path / "later.png"
                assert wait_for_body(browser, later, timeout=30) > 200, "the body vanished"
                shift = float(np.linalg.norm(np.argwhere(body_pixels(later)).mean(axis=0)
                                             - np.argwhere(body_pixels(first)).mean(axis=0)))
            assert shift > 20.0, "the view did not follow the newest frames"
    finally:
        proc.terminate()  # SIGTERM: the viewer server goes with live (see web_viewer_server)
        proc.wait(timeout=30)
