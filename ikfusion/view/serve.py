"""Serve a scene to the browser, or save it as a Rerun ``.rrd`` file.

The web viewer is Rerun's own, shipped inside the ``rerun-sdk`` wheel and served from this
machine: nothing is fetched from the internet. Two local ports are used: ``port`` serves the
viewer page over HTTP and a second, free port streams the recording to it (gRPC). Rerun binds
both on every network interface, so other machines of the lab network can open the page too.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from pathlib import Path
from urllib.parse import quote

from ..errors import InputError
from .draw import log_scene, make_blueprint, require_rerun
from .scene import Scene

#: Application id of the recordings (Rerun groups recordings by it).
APPLICATION_ID = "ikfusion_view"


def save_recording(scene: Scene, path: str | Path) -> Path:
    """Write the scene with its layout to an ``.rrd`` file that ``rerun FILE`` opens.

    Raises:
        InputError: The file name does not end in ``.rrd``.
    """
    rr = require_rerun()
    out = Path(path)
    if out.suffix.lower() != ".rrd":
        raise InputError("--save writes a Rerun recording; give a file name ending in .rrd",
                         path=out, field="--save")
    out.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(APPLICATION_ID)
    rec.save(out, default_blueprint=make_blueprint(scene))
    log_scene(rec, scene)
    rec.flush()
    rec.disconnect()
    return out


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def check_port_free(port: int) -> None:
    """Raise when the viewer's HTTP port is taken (Rerun binds it on every interface).

    Raises:
        InputError: The port is in use or out of range; the message says to pick another.
    """
    if not 0 < port < 65536:
        raise InputError(f"port must be between 1 and 65535, got {port}", field="--port")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("0.0.0.0", port))
        except OSError as err:
            raise InputError(f"port {port} is in use ({err.strerror}); pick another with "
                             "--port", field="--port") from None


def viewer_url(port: int, grpc_uri: str, host: str = "127.0.0.1") -> str:
    """Address of the viewer page connected to the recording at ``grpc_uri``.

    The welcome screen is hidden: it lists online examples, which an offline machine cannot get.
    """
    return f"http://{host}:{port}/?url={quote(grpc_uri, safe='')}&hide_welcome_screen"


def serve(scene: Scene, port: int = 9090, open_browser: bool = True,
          announce: Callable[[str], None] = print, stop: threading.Event | None = None) -> None:
    """Serve the scene to the browser until ``stop`` is set (or the process is interrupted).

    Args:
        scene: What to show.
        port: HTTP port of the viewer page.
        open_browser: Open the page in the default browser.
        announce: Called once with the page address when it is ready.
        stop: Event that ends serving; None serves until interrupted.
    """
    rr = require_rerun()
    check_port_free(port)
    rec = rr.RecordingStream(APPLICATION_ID)
    grpc_uri = rec.serve_grpc(grpc_port=free_port(), default_blueprint=make_blueprint(scene))
    log_scene(rec, scene)
    rec.flush()
    rr.serve_web_viewer(web_port=port, open_browser=open_browser, connect_to=grpc_uri)
    announce(viewer_url(port, grpc_uri))
    (stop or threading.Event()).wait()
