"""Draw a :class:`~ikfusion.view.scene.Scene` into a Rerun recording.

Entity layout (world frame Z up, metres; one duration timeline ``time`` in seconds):

- ``world/floor``: a grid on z = 0; ``world/readers``: UWB readers with their ids;
- ``world/<actor>/bones``: a line from each segment origin to each child's origin (leaf segments
  end at their tip site, e.g. Head -> HeadTop), ``world/<actor>/joints``: segment origins,
  ``world/<actor>/axes``: short X/Y/Z (red/green/blue) arrows of each segment frame,
  ``world/<actor>/contacts``: contact points, large and yellow while in contact,
  ``world/<actor>/tags/<site>``: tag site now, ``world/<actor>/paths/<site>``: its whole path;
- ``world/<actor>/capsules``: a human's body, a capsule around each bone (not for ghosts), or
  ``world/<actor>/links/<link>/<visual>``: a robot's URDF meshes (see :mod:`.shapes`);
- ``plots/<actor>/angles/<column>`` [deg], ``plots/<actor>/contacts/<point>`` (phases stacked:
  point i is drawn at i + 0.8 while in contact, at i otherwise), ``plots/<actor>/solve_time_ms``.
  Each series is named after its column (``jRightKnee_flex``, ``LeftHeel``; with the actor's
  name in brackets when several actors are drawn) in its own colour, with legends shown; a
  column has the same colour in every actor (paler in a ghost).

Rerun is optional (the ``view`` extra); :func:`require_rerun` imports it with a clear message.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..rotations import quat_wxyz_to_matrix
from .rerun_lib import ViewerUnavailable as ViewerUnavailable
from .rerun_lib import entity_name, require_rerun
from .scene import Actor, Readers, Scene
from .shapes import log_capsules, log_link_meshes

#: Name of the one timeline that drives the 3-D view and the plots.
TIMELINE = "time"

#: Joint-angle curves shown by default (the rest are one click away in the viewer).
DEFAULT_CURVES: tuple[str, ...] = (
    "jRightHip_flex", "jRightKnee_flex", "jRightAnkle_flex",
    "jLeftHip_flex", "jLeftKnee_flex", "jLeftAnkle_flex",
)

#: Distinct colours of plotted series, readable on a dark background (Trubetskoy's list).
SERIES_PALETTE: tuple[tuple[int, int, int], ...] = (
    (230, 25, 75), (60, 180, 75), (255, 225, 25), (0, 130, 200), (245, 130, 48),
    (145, 30, 180), (70, 240, 240), (240, 50, 230), (210, 245, 60), (250, 190, 212),
    (0, 128, 128), (220, 190, 255), (170, 110, 40), (255, 250, 200), (128, 0, 0),
    (170, 255, 195), (128, 128, 0), (255, 215, 180), (0, 0, 128), (128, 128, 128),
)
_ACTOR_COLORS = ((66, 135, 245), (245, 130, 48), (60, 180, 75), (145, 30, 180), (70, 240, 240))
_GHOST_COLOR = (200, 200, 200, 110)
_AXIS_COLORS = np.array([[230, 40, 40], [40, 200, 40], [40, 90, 240]], dtype=np.uint8)
_CONTACT_ON = (255, 220, 0)
_CONTACT_OFF = (90, 90, 90)
_AXIS_LENGTH = 0.08  # [m]
_LEAF_STUB = 0.08  # [m] bone of a leaf segment without a tip site, along its -Z axis


def actor_color(index: int, actor: Actor) -> tuple[int, ...]:
    """RGB(A) colour of an actor: a palette colour, or faint grey for a ghost."""
    return _GHOST_COLOR if actor.ghost else _ACTOR_COLORS[index % len(_ACTOR_COLORS)]


def log_scene(rec: Any, scene: Scene) -> None:
    """Log the whole scene into the recording stream ``rec`` (a ``rerun.RecordingStream``)."""
    rr = require_rerun()
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_floor(rec, scene)
    if scene.readers is not None and len(scene.readers.ids):
        log_readers(rec, scene.readers)
    if scene.notes:
        rec.log("notes", rr.TextDocument("\n\n".join(scene.notes)), static=True)
    curve_colors = scene_curve_colors(scene)
    for i, actor in enumerate(scene.actors):
        color = actor_color(i, actor)
        tag = f" ({actor.name})" if len(scene.actors) > 1 else ""
        log_actor_curves(rec, actor, color, curve_colors, tag)  # first: quick to show
        log_actor_paths(rec, actor, scene.tag_sites, color)
        log_actor_frames(rec, actor, scene.tag_sites, color)


def floor_lines(scene: Scene, spacing: float = 0.5, margin: float = 1.0) -> list[np.ndarray]:
    """Grid lines on z = 0 covering every actor's path with a margin, each (2, 3) [m]."""
    points = [a.p_world_segment[:, 0, :2] for a in scene.actors if a.frames]
    if scene.readers is not None and len(scene.readers.ids):
        points.append(scene.readers.p_world_reader[:, :2])
    xy = np.concatenate([p[np.all(np.isfinite(p), axis=1)] for p in points]) if points else \
        np.zeros((1, 2))
    if not len(xy):
        xy = np.zeros((1, 2))
    lo = np.floor((xy.min(axis=0) - margin) / spacing) * spacing
    hi = np.ceil((xy.max(axis=0) + margin) / spacing) * spacing
    lines = [np.array([[x, lo[1], 0.0], [x, hi[1], 0.0]])
             for x in np.arange(lo[0], hi[0] + spacing / 2, spacing)]
    lines += [np.array([[lo[0], y, 0.0], [hi[0], y, 0.0]])
              for y in np.arange(lo[1], hi[1] + spacing / 2, spacing)]
    return lines


def log_floor(rec: Any, scene: Scene, margin: float = 1.0) -> None:
    """The floor grid (static), ``margin`` [m] beyond the actors' paths and the readers."""
    rr = require_rerun()
    rec.log("world/floor", rr.LineStrips3D(floor_lines(scene, margin=margin), radii=0.003,
                                           colors=(120, 120, 120)), static=True)


def log_readers(rec: Any, readers: Readers) -> None:
    """UWB readers as labelled points on poles down to the floor (static)."""
    rr = require_rerun()
    p = readers.p_world_reader
    rec.log("world/readers", rr.Points3D(p, radii=0.06, colors=(220, 60, 200),
                                         labels=list(readers.ids)), static=True)
    poles = [np.array([q, [q[0], q[1], 0.0]]) for q in p]
    rec.log("world/readers/poles", rr.LineStrips3D(poles, radii=0.005, colors=(220, 60, 200)),
            static=True)


def segment_rotations(actor: Actor) -> np.ndarray | None:
    """``R_world_segment`` of every frame and segment, shape (N, S, 3, 3), or None."""
    if actor.quat_wxyz_world_segment is None:
        return None
    return quat_wxyz_to_matrix(actor.quat_wxyz_world_segment)


def bone_strips(actor: Actor) -> np.ndarray:
    """Bones of every frame as 2-point strips, shape (N, B, 2, 3) [m] (see :func:`bones`)."""
    return bones(actor)[0]


def bones(actor: Actor) -> tuple[np.ndarray, list[tuple[str, str]]]:
    """Bones of every frame as 2-point strips (N, B, 2, 3) [m], and their (start, end) names.

    A bone joins each segment origin to each child's origin. A leaf segment ends at its tip
    site when it has one, else in a short stub along its -Z axis (distal in the N-pose) when its
    orientation is known (its end is then named ``tip``).
    """
    P = actor.p_world_segment
    R = segment_rotations(actor)
    names = actor.segment_names
    starts = [P[:, int(p)] for p in actor.segment_parents if p >= 0]
    ends = [P[:, c] for c, p in enumerate(actor.segment_parents) if p >= 0]
    labels = [(names[int(p)], names[c]) for c, p in enumerate(actor.segment_parents) if p >= 0]
    for s, name in enumerate(names):
        if actor.children(s):
            continue
        tip = actor.segment_tips.get(name)
        j = actor.site_index(tip) if tip else None
        if tip and j is not None:
            starts.append(P[:, s])
            ends.append(actor.p_world_site[:, j])
            labels.append((name, tip))
        elif R is not None:
            starts.append(P[:, s])
            ends.append(P[:, s] - _LEAF_STUB * R[:, s, :, 2])
            labels.append((name, "tip"))
    if not starts:
        return np.zeros((actor.frames, 0, 2, 3)), []
    return np.stack([np.stack(starts, axis=1), np.stack(ends, axis=1)], axis=2), labels


def segment_axes(actor: Actor, R_world_segment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arrows of the segment frames: origins and vectors, each (N, 3S, 3) [m].

    Per segment, three arrows along its X, Y and Z axes (columns of ``R_world_segment``).
    """
    n, s = R_world_segment.shape[:2]
    origins = np.repeat(actor.p_world_segment, 3, axis=1)
    vectors = _AXIS_LENGTH * np.swapaxes(R_world_segment, 2, 3).reshape(n, 3 * s, 3)
    return origins, vectors


def log_actor_paths(rec: Any, actor: Actor, tag_sites: tuple[str, ...],
                    color: tuple[int, ...]) -> None:
    """Whole paths of the actor's tag sites (static)."""
    rr = require_rerun()
    base = f"world/{entity_name(actor.name)}"
    for site in tag_sites:
        j = actor.site_index(site)
        if j is None:
            continue
        path = actor.p_world_site[:, j]
        path = path[np.all(np.isfinite(path), axis=1)]
        if len(path) > 1:
            rec.log(f"{base}/paths/{site}",
                    rr.LineStrips3D([path], radii=0.004, colors=path_color(color)), static=True)


def path_color(color: tuple[int, ...]) -> tuple[int, ...]:
    """A paler shade of an actor's colour for its tag paths (the body keeps the full one)."""
    return tuple(int(c + 0.5 * (255 - c)) for c in color[:3]) + tuple(color[3:])


def log_actor_frames(rec: Any, actor: Actor, tag_sites: tuple[str, ...],
                     color: tuple[int, ...], styles: bool = True) -> None:
    """Body, segment axes, contact points and tag sites at every frame (sent as columns).

    Args:
        rec: The ``rerun.RecordingStream``.
        actor: The actor; all its frames are sent on the timeline at ``actor.time`` [s].
        tag_sites: Sites drawn as tags (when the actor has them).
        color: The actor's colour.
        styles: Also log the static look of each entity (radii, colours, labels); a stream
            that sends an actor in several batches (``live --view``) does so with its first.
    """
    rr = require_rerun()
    base = f"world/{entity_name(actor.name)}"
    n = actor.frames
    index = [rr.TimeColumn(TIMELINE, duration=actor.time)]

    def send(path: str, archetype: Any, per_frame: int, style: Callable[[], Any],
             **columns: Any) -> None:
        if styles:  # built only when logged: a live batch sends the frames alone
            rec.log(path, style(), static=True)
        rec.send_columns(path, indexes=index, columns=archetype.columns(**columns).partition(
            lengths=np.full(n, per_frame)))

    radius = 0.012 if actor.ghost else 0.02
    strips, names = bones(actor)
    send(f"{base}/bones", rr.LineStrips3D, strips.shape[1],
         lambda: rr.LineStrips3D.from_fields(radii=radius, colors=color),
         strips=strips.reshape(-1, 2, 3))
    if actor.meshes is not None:
        log_link_meshes(rec, base, index, actor.meshes, path_color(color))
    elif not actor.ghost and strips.shape[1]:
        log_capsules(rec, f"{base}/capsules", index, strips, names, color, styles)
    S = len(actor.segment_names)
    send(f"{base}/joints", rr.Points3D, S,
         lambda: rr.Points3D.from_fields(radii=1.3 * radius, colors=color),
         positions=actor.p_world_segment.reshape(-1, 3))
    R = segment_rotations(actor)
    if R is not None and not actor.ghost:
        origins, vectors = segment_axes(actor, R)
        send(f"{base}/axes", rr.Arrows3D, 3 * S,
             lambda: rr.Arrows3D.from_fields(radii=0.004, colors=np.tile(_AXIS_COLORS, (S, 1))),
             origins=origins.reshape(-1, 3), vectors=vectors.reshape(-1, 3))
    sites = [actor.site_index(c) for c in actor.contact_names]
    if actor.contact_names and all(j is not None for j in sites):
        on = actor.contacts.reshape(-1)
        send(f"{base}/contacts", rr.Points3D, len(sites),
             lambda: rr.Points3D.from_fields(labels=list(actor.contact_names), show_labels=False),
             positions=actor.p_world_site[:, [int(j) for j in sites if j is not None]]
             .reshape(-1, 3),
             radii=np.where(on, 0.035, 0.015),
             colors=np.where(on[:, None], _CONTACT_ON, _CONTACT_OFF).astype(np.uint8))
    for site in tag_sites:
        j = actor.site_index(site)
        if j is not None:
            send(f"{base}/tags/{site}", rr.Points3D, 1,
                 lambda: rr.Points3D.from_fields(radii=0.03, colors=color),
                 positions=actor.p_world_site[:, j])


def log_actor_curves(rec: Any, actor: Actor, color: tuple[int, ...],
                     curve_colors: dict[str, tuple[int, int, int]], tag: str = "",
                     styles: bool = True) -> None:
    """Joint angles [deg], stacked contact phases and solve time [ms] on the timeline.

    Every series is named after its column (``jRightKnee_flex``, ``LeftHeel``), followed by
    ``tag`` (e.g. `` (truth)``) when several actors share the plots.

    Args:
        rec: The ``rerun.RecordingStream``.
        actor: The actor.
        color: The actor's colour (its solve-time curve).
        curve_colors: Colour of each joint-angle column (see :func:`series_colors`); a ghost's
            curves are drawn paler.
        tag: Text appended to every series name.
        styles: Also log each series' name, colour and width (static), as
            :func:`log_actor_frames`.
    """
    rr = require_rerun()
    base = f"plots/{entity_name(actor.name)}"
    index = [rr.TimeColumn(TIMELINE, duration=actor.time)]

    def series(path: str, name: str, values: np.ndarray, rgb: tuple[int, ...]) -> None:
        if styles:
            rec.log(path, rr.SeriesLines(names=name + tag, colors=rgb[:3], widths=1.5),
                    static=True)
        rec.send_columns(path, indexes=index,
                         columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float)))

    for j, column in enumerate(actor.angle_names):
        rgb = curve_colors.get(column, color[:3])
        series(f"{base}/angles/{column}", column, actor.joint_angles_deg[:, j],
               path_color(rgb) if actor.ghost else rgb)
    contact_colors = series_colors(actor.contact_names)
    for j, point in enumerate(actor.contact_names):
        series(f"{base}/contacts/{point}", point, j + 0.8 * actor.contacts[:, j],
               contact_colors[point])
    if actor.solve_time_ms is not None:
        series(f"{base}/solve_time_ms", "solve time [ms]", actor.solve_time_ms, color)


def series_colors(names: Sequence[str]) -> dict[str, tuple[int, int, int]]:
    """A distinct colour for each name, in order: :data:`SERIES_PALETTE`, then darker rounds."""
    out: dict[str, tuple[int, int, int]] = {}
    for i, name in enumerate(dict.fromkeys(names)):
        shade = 0.8 ** (i // len(SERIES_PALETTE))
        r, g, b = SERIES_PALETTE[i % len(SERIES_PALETTE)]
        out[name] = (round(r * shade), round(g * shade), round(b * shade))
    return out


def scene_curve_colors(scene: Scene) -> dict[str, tuple[int, int, int]]:
    """Colours of the joint-angle columns of all actors, the same in every actor.

    The curves shown at first get the first (most distinct) colours.
    """
    shown = [c for a in scene.actors for c in default_curves(a)]
    return series_colors(shown + [c for a in scene.actors for c in a.angle_names])


def camera(scene: Scene, live: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Eye position and look target [m]: a side view (from -Y) of the main actor's path.

    ``live``: the path is still to come, so the view takes in the UWB readers' area as well
    (the capture area), or at least 4 m around the first frames.
    """
    pelvis = scene.main.p_world_segment[:, 0]
    if live:
        around = [pelvis[:, :2] - 2.0, pelvis[:, :2] + 2.0]
        if scene.readers is not None and len(scene.readers.ids):
            around.append(scene.readers.p_world_reader[:, :2])
        pelvis = np.concatenate([np.column_stack([xy, np.full(len(xy), 0.9)])
                                 for xy in around])
    pelvis = pelvis[np.all(np.isfinite(pelvis), axis=1)]
    centre = pelvis.mean(axis=0) if len(pelvis) else np.zeros(3)
    span = float(np.ptp(pelvis[:, :2], axis=0).max()) if len(pelvis) else 0.0
    target = np.array([centre[0], centre[1], 0.9])
    distance = 2.4 + 0.5 * span
    return target + np.array([0.35, -1.0, 0.3]) * distance, target


def default_curves(actor: Actor) -> list[str]:
    """The joint curves shown at first (every curve stays selectable).

    :data:`DEFAULT_CURVES` for the human model, a robot's knee and elbow joints otherwise.
    """
    human = [c for c in DEFAULT_CURVES if c in actor.angle_names]
    if human:
        return human
    return [c for c in actor.angle_names if "knee" in c.lower() or "elbow" in c.lower()][:6]


def contact_title(scene: Scene) -> str:
    """Title of the contact-phase plot, naming its rows.

    Row i is drawn at i, raised to i + 0.8 while in contact, e.g.
    ``Contacts (rows 0-3: LeftHeel, LeftToe, RightHeel, RightToe; raised = in contact)``.
    """
    rows: dict[int, list[str]] = {}
    for actor in scene.actors:
        for j, point in enumerate(actor.contact_names):
            if point not in rows.setdefault(j, []):
                rows[j].append(point)
    names = ", ".join("/".join(rows[j]) for j in sorted(rows))
    return f"Contacts (rows 0-{len(rows) - 1}: {names}; raised = in contact)"


def make_blueprint(scene: Scene, live: bool = False) -> Any:
    """The viewer layout: 3-D view left; joint angles, contacts, solve time right.

    A recording opens paused at its start; ``live``: the time cursor follows the newest frame.
    """
    require_rerun()
    import rerun.blueprint as rrb

    plots: list[Any] = []
    curves = [f"/plots/{entity_name(a.name)}/angles/{c}" for a in scene.actors
              for c in default_curves(a)]
    if curves:
        plots.append(rrb.TimeSeriesView(name="Joint angles [deg]", origin="/plots",
                                        contents=curves, plot_legend=rrb.PlotLegend(
                                            visible=True)))
    phases = [f"/plots/{entity_name(a.name)}/contacts/{c}" for a in scene.actors
              for c in a.contact_names]
    if phases:
        plots.append(rrb.TimeSeriesView(name=contact_title(scene), origin="/plots",
                                        contents=phases, plot_legend=rrb.PlotLegend(
                                            visible=True)))
    timing = [f"/plots/{entity_name(a.name)}/solve_time_ms" for a in scene.actors
              if a.solve_time_ms is not None]
    if timing:
        plots.append(rrb.TimeSeriesView(name="Solve time [ms]", origin="/plots",
                                        contents=timing))
    if scene.notes:
        plots.append(rrb.TextDocumentView(name="Summary", origin="/notes"))
    eye, target = camera(scene, live)
    body = rrb.Spatial3DView(name="Body", origin="/world", eye_controls=rrb.EyeControls3D(
        position=eye, look_target=target, eye_up=[0.0, 0.0, 1.0]))
    main = rrb.Horizontal(body, rrb.Vertical(*plots), column_shares=[3, 2]) if plots else body
    return rrb.Blueprint(
        main,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline=TIMELINE, play_state="following" if live else "paused",
                      loop_mode="off" if live else "all"),
    )
