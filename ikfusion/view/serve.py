"""Serve a scene to the browser, or save it as a Rerun ``.rrd`` file.

The web viewer is Rerun's own, shipped inside the ``rerun-sdk`` wheel and served from this
machine: nothing is fetched from the internet. The scene is saved to a temporary ``.rrd`` file
and Rerun's server (the ``rerun`` program of the same wheel) serves it: ``port`` serves the
viewer page over HTTP and a second, free port streams the recording to it (gRPC). Both listen
on ``host`` only: 127.0.0.1 by default, so only this machine sees the motion (there is no
authentication); ``--host 0.0.0.0`` opens it to every network interface (the lab network).
"""

from __future__ import annotations

import errno
import socket
import subprocess
import sys
import tempfile
import threading
import time
import webbrowser
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from urllib.parse import quote

from ..errors import InputError
from .draw import log_scene, make_blueprint, require_rerun
from .scene import Scene

#: Application id of the recordings (Rerun groups recordings by it).
APPLICATION_ID = "ikfusion_view"
#: Interface the viewer listens on unless told otherwise: this machine only.
DEFAULT_HOST = "127.0.0.1"
#: How long Rerun's server may take to start listening [s].
STARTUP_TIMEOUT_S = 60.0


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


def free_port(host: str = DEFAULT_HOST) -> int:
    """A TCP port that is free on ``host`` right now."""
    with socket.socket(_family(host), socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def check_port_free(port: int, host: str = DEFAULT_HOST) -> None:
    """Raise when the viewer's HTTP port is taken on ``host``, or ``host`` is not ours.

    Raises:
        InputError: The port is in use or out of range, or ``host`` is not an address of this
            machine; the message says what to pick instead.
    """
    if not 0 < port < 65536:
        raise InputError(f"port must be between 1 and 65535, got {port}", field="--port")
    try:
        family = _family(host)
    except OSError:
        raise InputError(f"--host {host!r} is not an address of this machine (try 127.0.0.1 "
                         "or 0.0.0.0)", field="--host") from None
    with socket.socket(family, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError as err:
            if err.errno == errno.EADDRNOTAVAIL:
                raise InputError(f"--host {host!r} is not an address of this machine (try "
                                 "127.0.0.1 or 0.0.0.0)", field="--host") from None
            raise InputError(f"port {port} is in use ({err.strerror}); pick another with "
                             "--port", field="--port") from None


def _family(host: str) -> socket.AddressFamily:
    """IPv4 or IPv6, from the address ``host`` resolves to."""
    return socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)[0][0]


def viewer_url(port: int, grpc_uri: str, host: str = DEFAULT_HOST) -> str:
    """Address of the viewer page connected to the recording at ``grpc_uri``.

    The welcome screen is hidden: it lists online examples, which an offline machine cannot get.
    """
    return f"http://{host}:{port}/?url={quote(grpc_uri, safe='')}&hide_welcome_screen"


def page_host(host: str) -> str:
    """The name a browser uses to reach a server listening on ``host``.

    A wildcard (``0.0.0.0``, ``::``) listens everywhere; the page is then announced under this
    machine's name so that other machines can open the address printed.
    """
    return socket.gethostname() if host in ("0.0.0.0", "::", "") else host


def rerun_program() -> Path:
    """The ``rerun`` program shipped in the rerun-sdk wheel (it serves the page on a host)."""
    import rerun_cli

    program = Path(rerun_cli.__file__).parent / "rerun"
    if not program.is_file():
        from .draw import ViewerUnavailable

        raise ViewerUnavailable(f"the rerun program is missing from the rerun-sdk wheel "
                                f"({program}); reinstall with pip install 'ikfusion[view]'")
    return program


def serve(scene: Scene, port: int = 9090, open_browser: bool = True,
          announce: Callable[[str], None] = print, stop: threading.Event | None = None,
          host: str = DEFAULT_HOST) -> None:
    """Serve the scene to the browser until ``stop`` is set (or the process is interrupted).

    Args:
        scene: What to show.
        port: HTTP port of the viewer page.
        open_browser: Open the page in the default browser.
        announce: Called once with the page address when it is ready.
        stop: Event that ends serving; None serves until interrupted.
        host: Interface both ports listen on (127.0.0.1: this machine only; 0.0.0.0: all).

    Raises:
        InputError: The port is taken or ``host`` is not an address of this machine.
        RuntimeError: Rerun's server did not start (its own message is included).
    """
    require_rerun()
    check_port_free(port, host)
    with tempfile.TemporaryDirectory(prefix="ikfusion_view_") as tmp:
        rrd = save_recording(scene, Path(tmp) / "scene.rrd")
        with web_viewer_server(port, host, rrd) as (url, _):
            if open_browser:
                webbrowser.open(url)
            announce(url)
            (stop or threading.Event()).wait()


@contextmanager
def web_viewer_server(port: int, host: str = DEFAULT_HOST,
                      rrd: Path | None = None) -> Iterator[tuple[str, str]]:
    """Rerun's server (its ``rerun`` program) serving the web viewer, stopped on exit.

    Args:
        port: HTTP port of the viewer page (checked free by the caller).
        host: Interface both ports listen on.
        rrd: A recording to serve; None serves what a logging process sends to the gRPC
            address (``live --view``; the server keeps at most a memory limit of it for late
            pages, oldest dropped first).

    Yields:
        The page address (connected to the recording) and the gRPC address to log to
        (``rerun+http://HOST:PORT/proxy``, reachable from this machine).

    Raises:
        RuntimeError: The server did not start (its own message is included).
    """
    program = rerun_program()
    grpc_port = free_port(host)
    with tempfile.TemporaryDirectory(prefix="ikfusion_viewer_") as tmp:
        log = Path(tmp) / "rerun.log"
        with log.open("w") as log_file:
            server = subprocess.Popen(
                [str(program), "--serve-web", "--bind", host, "--web-viewer-port", str(port),
                 "--port", str(grpc_port), *([str(rrd)] if rrd is not None else [])],
                stdin=subprocess.DEVNULL, stdout=log_file, stderr=subprocess.STDOUT,
                preexec_fn=_die_with_parent if sys.platform == "linux" else None)
        try:
            name = page_host(host)
            local = "127.0.0.1" if name == socket.gethostname() else name
            _wait_listening(local, port, server, log)
            url = viewer_url(port, f"rerun+http://{name}:{grpc_port}/proxy", name)
            yield url, f"rerun+http://{local}:{grpc_port}/proxy"
        finally:
            server.terminate()
            try:
                server.wait(timeout=10)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def _die_with_parent() -> None:
    """Ask Linux to end the server when this process ends (run in the server before it starts).

    Even when this process is killed (SIGKILL), no orphan server keeps the ports.
    """
    import ctypes
    import signal

    pr_set_pdeathsig = 1
    ctypes.CDLL(None).prctl(pr_set_pdeathsig, signal.SIGTERM)


def _wait_listening(host: str, port: int, server: subprocess.Popen[bytes], log: Path) -> None:
    """Wait until ``server`` accepts connections on ``port``.

    Raises:
        RuntimeError: It exited or did not listen within :data:`STARTUP_TIMEOUT_S`.
    """
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        if server.poll() is not None:
            break
        try:
            with socket.create_connection((host, port), timeout=1.0):
                return
        except OSError:
            time.sleep(0.2)
    tail = log.read_text(errors="replace")[-2000:]
    raise RuntimeError(f"Rerun's viewer server did not start on {host}:{port} (exit code "
                       f"{server.poll()}): {tail}")
