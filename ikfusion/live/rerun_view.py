"""``live --view``: the poses drawn in Rerun as they are solved, the timeline following them.

A :class:`RerunViewSink` turns every actor's frames into the entities of ``ikfusion view``
(:mod:`ikfusion.view.draw`: ``world/<actor>/bones``, ``joints``, ``axes``, ``capsules``; the
joint curves shown first by default under ``plots/<actor>/angles``; the UWB readers) on the
duration timeline ``time`` at each frame's capture time [s]. Frames are sent in batches, at most
``view_rate_hz`` times a second of capture time (``configs/live.yaml``, 20 Hz), every frame
kept: sending one batch costs about 2 ms of CPU whatever it holds (bones, joints, axes,
capsules and six joint curves: ten Rerun column sends), so a batch per frame would cost 2 ms a
frame, the batches of 20 Hz about 0.7 ms a frame of a 60 Hz stream. Rerun sends from its own
thread; a viewer that is closed or slow does not hold the live loop (the web server keeps a
bounded backlog for late pages), and one gone is a warning at the end.

Where the frames go: ``web`` (Rerun's web viewer served from the installed package, as
``ikfusion view``), ``native`` (Rerun's desktop viewer, spawned) or a ``.rrd`` file written as
the stream goes. Rerun is the optional extra ``view``.
"""

from __future__ import annotations

import webbrowser
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..rotations import matrix_to_quat_wxyz
from ..view.draw import (
    actor_color,
    default_curves,
    log_actor_curves,
    log_actor_frames,
    log_floor,
    log_readers,
    make_blueprint,
    scene_curve_colors,
)
from ..view.rerun_lib import require_rerun
from ..view.scene import Actor, Readers, Scene
from ..view.serve import check_port_free, rerun_program, web_viewer_server
from .actor_pose import ActorPose

#: Application id of the live recordings (Rerun groups recordings by it).
APPLICATION_ID = "ikfusion_live"
#: Capture times this close are one instant (frame times are sums of float periods) [s].
_TIME_TOLERANCE_S = 1e-6
#: Floor grid margin around the first frames and the readers [m].
FLOOR_MARGIN_M = 3.0


def pose_actor(poses: Sequence[ActorPose], curves: Sequence[str] | None = None) -> Actor:
    """Frames of one actor as a view :class:`Actor` (world frame Z up, metres, seconds).

    Args:
        poses: The actor's frames in time order (one actor, one model).
        curves: Joint-angle columns to keep (default: all of them).

    Returns:
        The actor: segment origins and orientations, the kept joint angles [deg].
    """
    first = poses[0]
    names = list(first.joint_names) if curves is None else [c for c in curves
                                                              if c in first.joint_names]
    columns = [first.joint_names.index(c) for c in names]
    return Actor(
        name=first.actor,
        time=np.array([p.time_s for p in poses]),
        segment_names=first.segments,
        segment_parents=np.array(first.parents),
        p_world_segment=np.stack([p.p_world_segment for p in poses]),
        quat_wxyz_world_segment=matrix_to_quat_wxyz(np.stack([p.R_world_segment
                                                              for p in poses])),
        angle_names=tuple(names),
        joint_angles_deg=np.stack([p.joint_angles_deg[columns] for p in poses]),
    )


class RerunViewSink:
    """Logs every actor's frames into a Rerun recording, in batches (a :class:`PoseSink`).

    Args:
        rec: The ``rerun.RecordingStream``, connected to where the frames go.
        rate_hz: Batches sent per second of capture time, at most [Hz].
        readers: UWB readers drawn at the start, or None.
        on_close: Called after the last batch is sent (stops a server).
        several: Several actors will come: their curves are named with the actor's name.
    """

    def __init__(self, rec: Any, rate_hz: float, readers: Readers | None = None,
                 on_close: Callable[[], None] | None = None, several: bool = False) -> None:
        self.rec = rec
        self.several = several
        self.period_s = 1.0 / rate_hz
        self.readers = readers
        self._on_close = on_close
        self._pending: dict[str, list[ActorPose]] = {}
        self._firsts: dict[str, Actor] = {}  # each actor's first frame, in order seen
        self._sent_until: dict[str, float] = {}  # capture time of each actor's last batch [s]
        self._curves: dict[str, list[str]] = {}  # the joint curves drawn of each actor
        self._curve_colors: dict[str, tuple[int, int, int]] = {}
        #: Why the viewer is no longer drawn to (it went away), or None.
        self.lost: str | None = None

    def send(self, poses: Sequence[ActorPose]) -> None:
        """Queue the poses of one instant; an actor's batch is sent once it spans a period.

        Raises:
            ConnectionError: The viewer went away (said once; later frames are dropped).
        """
        if self.lost is not None:
            return
        for pose in poses:
            pending = self._pending.setdefault(pose.actor, [])
            pending.append(pose)
            last = self._sent_until.get(pose.actor)
            if last is None or pose.time_s - last >= self.period_s - _TIME_TOLERANCE_S:
                self._flush(pose.actor)

    def close(self) -> None:
        """Send what is queued, wait (at most 5 s) for it to leave, and disconnect.

        Raises:
            ConnectionError: The viewer went away before the end (the frames up to then were
                drawn); everything is released all the same.
        """
        try:
            if self.lost is None:
                for actor in list(self._pending):
                    self._flush(actor)
                self.rec.flush(timeout_sec=5.0)
        except RuntimeError as err:  # Rerun: its connection to the viewer is severed
            self.lost = str(err)
            raise ConnectionError(f"the viewer went away before the end ({err})") from None
        finally:
            self.rec.disconnect()
            if self._on_close is not None:
                self._on_close()

    def _flush(self, name: str) -> None:
        try:
            self._log(name)
        except RuntimeError as err:  # Rerun: its connection to the viewer is severed
            self.lost = str(err)
            self._pending.clear()
            raise ConnectionError(f"the viewer went away, frames no longer drawn ({err})") \
                from None

    def _log(self, name: str) -> None:
        poses = self._pending.pop(name, [])
        if not poses:
            return
        self._sent_until[name] = poses[-1].time_s
        first = name not in self._firsts
        if first:
            self._firsts[name] = pose_actor(poses[:1])
            self._curves[name] = default_curves(self._firsts[name])
            self._start()
        actor = pose_actor(poses, self._curves[name])
        color = actor_color(list(self._firsts).index(name), actor)
        log_actor_frames(self.rec, actor, (), color, styles=first)
        tag = f" ({name})" if self.several else ""
        log_actor_curves(self.rec, actor, color, self._curve_colors, tag, styles=first)

    def _start(self) -> None:
        """The static scene (floor, readers) and the layout of the actors seen so far."""
        rr = require_rerun()
        scene = Scene(tuple(self._firsts.values()), readers=self.readers)
        if len(self._firsts) == 1:
            self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            log_floor(self.rec, scene, margin=FLOOR_MARGIN_M)
            if self.readers is not None and len(self.readers.ids):
                log_readers(self.rec, self.readers)
        self._curve_colors = scene_curve_colors(scene)
        self.rec.send_blueprint(make_blueprint(scene, live=True))


def open_view(target: str, rate_hz: float, readers: Readers | None = None, port: int = 9090,
              host: str = "127.0.0.1", open_browser: bool = True,
              announce: Callable[[str], None] = print, several: bool = False) -> RerunViewSink:
    """The sink of ``live --view TARGET``, connected and ready.

    Args:
        target: ``web`` (the web viewer served on ``host:port``), ``native`` (Rerun's
            desktop viewer, spawned) or a file name ending in ``.rrd`` (written as frames come).
        rate_hz: Batches sent per second of capture time, at most [Hz].
        readers: UWB readers to draw, or None.
        port: HTTP port of the web viewer page.
        host: Interface the web viewer listens on (127.0.0.1: this machine only).
        open_browser: Open the page in the default browser (``web``).
        announce: Called with the page address (``web``) or the file written.
        several: Several actors will come (a session).

    Raises:
        InputError: rerun-sdk is missing (the message names the extra ``view``), the target
            is none of the three, or the port is taken.
        RuntimeError: Rerun's web server did not start.
    """
    rr = require_rerun("live --view")
    rec = rr.RecordingStream(APPLICATION_ID)
    if target == "native":
        rr.spawn(recording=rec, memory_limit="25%", executable_path=str(rerun_program()))
        return RerunViewSink(rec, rate_hz, readers, several=several)
    if target != "web":
        out = Path(target)
        if out.suffix.lower() != ".rrd":
            raise InputError("--view takes web, native or a file name ending in .rrd, not "
                             f"{target!r}", field="view")
        out.parent.mkdir(parents=True, exist_ok=True)
        rec.save(out)
        announce(f"recording the view into {out}")
        return RerunViewSink(rec, rate_hz, readers, several=several)
    check_port_free(port, host)
    stack = ExitStack()
    url, grpc = stack.enter_context(web_viewer_server(port, host))
    try:
        rec.connect_grpc(grpc)
    except BaseException:
        stack.close()
        raise
    if open_browser:
        webbrowser.open(url)
    announce(f"viewer at {url}")
    return RerunViewSink(rec, rate_hz, readers, on_close=stack.close, several=several)
