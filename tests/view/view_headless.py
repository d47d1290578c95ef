"""A tiny headless-Chromium driver for the viewer tests, over the DevTools pipe (stdlib only).

Chromium started with ``--remote-debugging-pipe`` reads DevTools commands on file descriptor 3
and writes replies on descriptor 4, each message a JSON object ended by a NUL byte. That is all
the tests need to open a page, wait, and take screenshots, without a driver package.
Every host except 127.0.0.1 is mapped to nowhere, so a page cannot reach the network.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

CHROMIUM = "/usr/bin/chromium"

_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--window-size=1024,640",
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1", "--remote-debugging-pipe",
)


class Browser:
    """One headless Chromium with one page, driven through the DevTools pipe."""

    def __init__(self, executable: str = CHROMIUM) -> None:
        self._profile = tempfile.mkdtemp(prefix="ikfusion-chromium-")
        to_child_r, self._to_child = os.pipe()
        self._from_child, from_child_w = os.pipe()
        # The child must see our pipe ends as its fds 3 (commands in) and 4 (replies out).
        # Copy both ends above 4 first: dup2 onto the same number would keep close-on-exec.
        def remap() -> None:
            high_r, high_w = os.dup(to_child_r), os.dup(from_child_w)
            os.dup2(high_r, 3)
            os.dup2(high_w, 4)

        self._proc = subprocess.Popen(
            [executable, *_FLAGS, f"--user-data-dir={self._profile}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=remap, close_fds=False)
        os.close(to_child_r)
        os.close(from_child_w)
        self._buffer = b""
        self._next_id = 0
        self.session = self._attach()

    def _send(self, method: str, params: dict[str, Any] | None = None,
              session: str | None = None) -> dict[str, Any]:
        """Send one command and return its result (events in between are dropped)."""
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method,
                                   "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._to_child, json.dumps(message).encode() + b"\0")
        while True:
            reply = self._read()
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return dict(reply.get("result", {}))

    def _read(self) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            chunk = os.read(self._from_child, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self._buffer += chunk
        raw, self._buffer = self._buffer.split(b"\0", 1)
        return dict(json.loads(raw))

    def _attach(self) -> str:
        targets = self._send("Target.getTargets")["targetInfos"]
        page = next(t for t in targets if t["type"] == "page")
        return str(self._send("Target.attachToTarget",
                              {"targetId": page["targetId"], "flatten": True})["sessionId"])

    def goto(self, url: str, timeout: float = 30.0) -> None:
        """Open ``url`` in the page and wait until its document has loaded."""
        self._send("Page.navigate", {"url": url}, self.session)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            time.sleep(0.5)
            try:
                if self.evaluate("document.readyState") == "complete":
                    return
            except RuntimeError:  # the page is between documents
                continue
        raise RuntimeError(f"{url} did not load within {timeout} s")

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page."""
        result = self._send("Runtime.evaluate", {"expression": expression,
                                                 "returnByValue": True}, self.session)
        return result.get("result", {}).get("value")

    def press_space(self) -> None:
        """Press and release the space bar (Rerun: play / pause)."""
        self.press_key(" ", "Space", 32, text=" ")

    def press_key(self, key: str, code: str, virtual_code: int, text: str | None = None) -> None:
        """Press and release one key (``key``/``code`` as in DOM KeyboardEvent)."""
        event = {"key": key, "code": code, "windowsVirtualKeyCode": virtual_code}
        down = {"type": "keyDown", **event, **({"text": text} if text else {})}
        self._send("Input.dispatchKeyEvent", down, self.session)
        self._send("Input.dispatchKeyEvent", {"type": "keyUp", **event}, self.session)

    def screenshot(self, path: str | Path) -> Path:
        """Write a PNG of the page."""
        data = self._send("Page.captureScreenshot", {"format": "png"}, self.session)["data"]
        out = Path(path)
        out.write_bytes(base64.b64decode(data))
        return out

    def close(self) -> None:
        """Stop Chromium and remove its profile."""
        try:
            self._send("Browser.close")
        except (RuntimeError, OSError):
            pass
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        for fd in (self._to_child, self._from_child):
            try:
                os.close(fd)
            except OSError:
                pass
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def body_pixels(png: Path) -> np.ndarray:
    """Mask of the 3-D view area (left 55 %, between the top bar and the time panel) where the
    main actor's blue (66, 135, 245) is drawn."""
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    h, w, _ = rgb.shape
    area = rgb[int(0.08 * h):int(0.72 * h), :int(0.55 * w)]
    return np.all(np.abs(area - np.array([66, 135, 245])) <= 12, axis=2)


def wait_for_body(browser: Browser, png: Path, timeout: float) -> int:
    """Screenshot until the body shows (the wasm viewer starts slowly in software GL)."""
    deadline = time.monotonic() + timeout
    while True:
        browser.screenshot(png)
        count = int(body_pixels(png).sum())
        if count > 200 or time.monotonic() > deadline:
            return count
        time.sleep(2.0)
