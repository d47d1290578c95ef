"""Solving one actor, or a session of several actors in one world frame.

An actor is an IMU recording, its sensor map and body; a session adds one UWB constellation,
one TOA log and one tags file for everybody (each tag names its actor), and writes one result
folder per actor under the output folder. ``ikfusion solve`` runs one actor from its options
or every actor of ``--session FILE``:

.. code-block:: yaml

    toa: toa.csv                 # paths relative to this file
    readers: readers.yaml
    tags: tags.yaml              # tags: {A1: {actor: alice, site: HeadTop}, ...}
    correction: no-slide         # off | slide | no-slide (default no-slide)
    actors:
      alice: {imu: alice/imu, map: alice/sensors.yaml, body: alice/body.yaml}
      bob: {imu: bob/imu, map: bob/sensors.yaml, height: 1.82}

All actors share the timeline of the TOA log (seconds from the recordings' first sample).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..ik import Motion, Solver
from ..ik.assumed import segment_coverage
from ..imu.calibration import calibrate_recording
from ..imu.mvn_calibration import calibration_from_mvnx
from ..io.mvnx import MvnxRecording, read_mvnx
from ..io.reader import read_imu
from ..io.recording import ImuRecording, check_sensor_ids
from ..io.sensor_map import load_sensor_map
from ..model import Body, HumanModel
from ..output_folders import check_output_folder, folder_name_problem, prepare_output_folder
from ..results import write_result_folder
from ..results.mvn_comparison import compare_with_mvn
from ..yaml_files import read_yaml
from .pipeline import solve_recording
from .tag_stream import open_tag_stream
from .uwb_aiding import UwbAiding, UwbInputs, track_recording_tags, uwb_aiding


@dataclass
class ActorInputs:
    """What one actor's solve reads.

    Attributes:
        name: The actor (as the tags file names it; None for a single solve of every tag).
        imu: MT Manager prefix, folder or file, IMU CSV or MVNX.
        sensor_map: Sensor map (YAML or OpenSense XML); None for an MVNX file, whose sensors
            are named by their segments.
        body: Body YAML, or None.
        height: Body height [m] when there is no body file (None: the default body).
        window_s: Calibration window [s] (None: automatic), ``pose``: ``npose``/``tpose``.
        forward: ``{segment: axis}`` overriding the heading found from the data.
        rate: Rate [Hz] for files without one.
        causal: Solve with the past only at each instant, as live (the bridging of lost
            samples; the UWB tag filters follow ``UwbInputs.smooth``).
    """

    name: str | None
    imu: Path
    sensor_map: Path | None
    body: Path | None = None
    height: float | None = None
    window_s: tuple[float, float] | None = None
    pose: str = "npose"
    forward: dict[str, str] | None = None
    rate: float | None = None
    causal: bool = False

    def model(self, mvnx: MvnxRecording | None = None) -> HumanModel:
        """The actor's body model (an MVNX take brings its subject's dimensions)."""
        if self.body is not None:
            return HumanModel.from_body(Body.from_yaml(self.body))
        if self.height is not None:
            return HumanModel.from_body(Body.from_height(self.height))
        if mvnx is not None:
            dimensions = mvnx.body_dimensions()
            if "height" in dimensions:
                return HumanModel.from_body(Body.from_dict(dimensions, source=mvnx.path))
        return HumanModel.default()

    def mvnx(self) -> MvnxRecording | None:
        """The MVNX take when ``imu`` is one (MVN's own calibration and result come with it)."""
        return read_mvnx(self.imu) if self.is_mvnx() else None

    def is_mvnx(self) -> bool:
        """Whether ``imu`` is an MVNX file."""
        return self.imu.is_file() and self.imu.suffix.lower() == ".mvnx"

    def read(self) -> tuple[Mapping[str, str], ImuRecording, MvnxRecording | None]:
        """The sensor map, the recording and the MVNX take (None for other recordings).

        An MVNX file needs no map (its sensors are named by segment); any other recording needs
        ``sensor_map`` (the caller checks that first when it wants its own message).
        """
        mvnx = self.mvnx()
        sensor_map: Mapping[str, str] = (load_sensor_map(self.sensor_map)
                                         if self.sensor_map is not None
                                         else mvnx.sensor_map() if mvnx is not None else {})
        if mvnx is not None:
            recording = mvnx.imu_recording()
            recording.warnings += check_sensor_ids(sensor_map, recording.sensors, self.imu)
        else:
            recording = read_imu(self.imu, rate=self.rate, sensor_map=sensor_map)
        return sensor_map, recording, mvnx

    def uses_file_calibration(self) -> bool:
        """Whether an MVNX take keeps MVN's calibration (no window, T-pose or heading given)."""
        return self.window_s is None and self.pose == "npose" and self.forward is None


@dataclass
class Session:
    """Several actors in one world frame (see the module docstring)."""

    actors: list[ActorInputs]
    uwb: UwbInputs | None
    correction: str = "no-slide"
    source: Path | None = None
    notes: list[str] = field(default_factory=list)


def solve_actor(actor: ActorInputs, out: str | Path, uwb: UwbInputs | None = None,
                correction: str | None = None, bvh_up: str = "z",
                progress: bool = False, force: bool = False) -> Motion:
    """Calibrate, track the actor's tags (with UWB), solve and write its result folder.

    ``out`` is replaced only when ikfusion wrote it (or it is empty), or with ``force``; it is
    checked before the solve starts.

    Returns:
        The solved motion (its warnings are in ``summary.json`` too).

    Raises:
        InputError: Bad files (file, line and field named), or a refused ``out``.
    """
    check_output_folder(out, force)
    if actor.sensor_map is None and not actor.is_mvnx():
        raise ConfigError("a sensor map is needed (--map) for anything but an MVNX file",
                          path=actor.imu, field="map")
    sensor_map, recording, mvnx = actor.read()
    model = actor.model(mvnx)
    file_calibration = mvnx is not None and actor.uses_file_calibration()
    aiding: UwbAiding | None = None
    if actor.causal and not file_calibration:  # calibrated as live, on the first seconds
        on_calibration = None if uwb is None else open_tag_stream(
            uwb, model, sensor_map, actor.name, correction or "no-slide", recording.rate,
            replay_log=True)
        window = None if actor.window_s is None else (
            int(round(actor.window_s[0] * recording.rate)),
            int(round(actor.window_s[1] * recording.rate)))
        result = solve_recording(recording, sensor_map, model, window, actor.pose,
                                 actor.forward, Solver(model), progress, causal=True,
                                 correction_for=on_calibration)
        cal = result.calibration
        aiding = None if on_calibration is None else on_calibration.aiding()
    else:
        if mvnx is not None and file_calibration:
            cal = calibration_from_mvnx(mvnx)
        else:
            cal = calibrate_recording(recording, sensor_map, actor.window_s,
                                      forward=actor.forward, pose=actor.pose)
        if uwb is not None:
            tracked = track_recording_tags(recording, sensor_map, model, cal, uwb, actor.name)
            aiding = uwb_aiding(tracked, recording.time, correction or "no-slide")
        fix = None if aiding is None else aiding.correction
        result = solve_recording(recording, sensor_map, model, solver=Solver(model),
                                 progress=progress, correction=fix, calibration=cal,
                                 causal=actor.causal)
    summary: dict[str, object] = {"used": False}
    if aiding is not None and uwb is not None:
        result.motion.warnings += aiding.warnings
        summary = {**aiding.summary(), "readers_file": str(uwb.readers.resolve())}
    extra: dict[str, Any] = {
        "calibration": {"method": cal.method, "heading_deg": float(np.degrees(cal.heading)),
                        "window_s": [cal.window[0] / recording.rate,
                                     cal.window[1] / recording.rate]},
        "uwb": summary,
        "segments": segment_coverage(model.segment_names, cal.R_sensor_segment),
        "bridged": result.bridged,
    }
    if actor.name is not None:
        extra["actor"] = actor.name
    if mvnx is not None:
        extra["mvn_comparison"] = compare_with_mvn(result.motion, mvnx)
        result.motion.warnings += extra["mvn_comparison"]["warnings"]
    write_result_folder(result.motion, out, bvh_up=bvh_up, extra_summary=extra, force=force)
    return result.motion


def solve_session(session: Session, out: str | Path, bvh_up: str = "z",
                  progress: bool = False, force: bool = False) -> dict[str, Motion]:
    """Solve every actor of a session into ``out/<actor>/``.

    ``out`` and the actors' folders are checked before any solve starts (see
    :func:`ikfusion.output_folders.check_output_folder`; ``force`` lifts the check).

    Raises:
        InputError: Bad files, or a refused output folder.
    """
    root = Path(out)
    folders = {a.name or "actor": root / (a.name or "actor") for a in session.actors}
    check_output_folder(root, force)
    for folder in folders.values():
        check_output_folder(folder, force)
    prepare_output_folder(root, "solve --session", force)
    return {name: solve_actor(a, folders[name], session.uwb, session.correction, bvh_up,
                              progress, force)
            for a, name in zip(session.actors, folders)}


def load_session(path: str | Path) -> Session:
    """A session file (see the module docstring).

    Raises:
        ConfigError: Missing keys, unknown correction, missing files (file and key named).
    """
    file = Path(path)
    data = read_yaml(file, "session file")
    if not isinstance(data, dict) or not isinstance(data.get("actors"), dict) \
            or not data["actors"]:
        raise ConfigError("expected 'actors: {<name>: {imu: ..., map: ...}, ...}'", path=file,
                          field="actors")
    correction = str(data.get("correction", "no-slide"))
    if correction not in ("off", "slide", "no-slide"):
        raise ConfigError(f"correction must be off, slide or no-slide, not {correction!r}",
                          path=file, field="correction")
    given = [k for k in ("toa", "readers", "tags") if data.get(k) is not None]
    if given and len(given) < 3:
        missing = sorted({"toa", "readers", "tags"} - set(given))
        raise ConfigError("UWB needs toa, readers and tags", path=file, field=missing[0])
    uwb = UwbInputs(_file(file, data, "toa"), _file(file, data, "readers"),
                    _file(file, data, "tags")) if given else None
    actors = [_actor(file, name, spec) for name, spec in data["actors"].items()]
    return Session(actors, uwb, correction, file)


def _file(session: Path, data: dict[str, Any], key: str, name: str | None = None) -> Path:
    """The path under ``key``, relative to the session file; it must exist."""
    value = data.get(key)
    where = name or key
    if not isinstance(value, str) or not value:
        raise ConfigError("expected a path", path=session, field=where)
    path = Path(value) if Path(value).is_absolute() else session.parent / value
    if not path.exists():
        raise ConfigError(f"{path} does not exist", path=session, field=where)
    return path


def _actor(session: Path, name: Any, spec: Any) -> ActorInputs:
    """One actor of the session file; its name becomes a folder name under ``--out``."""
    if isinstance(name, int) and not isinstance(name, bool):
        name = str(name)
    problem = folder_name_problem(name) if isinstance(name, str) else "it is not text"
    if problem is not None:
        raise ConfigError(f"actor name {name!r} cannot name its result folder: {problem}; use "
                          "a plain name such as 'alice'", path=session, field="actors")
    key = f"actors.{name}"
    if not isinstance(spec, dict):
        raise ConfigError("expected {imu: ..., map: ..., body: ... | height: ...}", path=session,
                          field=key)
    height = spec.get("height")
    if height is not None and not (isinstance(height, (int, float)) and 0.5 < height < 2.5):
        raise ConfigError(f"height must be in metres (0.5-2.5), not {height!r}", path=session,
                          field=f"{key}.height")
    return ActorInputs(
        name=name, imu=_file(session, spec, "imu", f"{key}.imu"),
        sensor_map=_file(session, spec, "map", f"{key}.map") if "map" in spec else None,
        body=_file(session, spec, "body", f"{key}.body") if "body" in spec else None,
        height=None if height is None else float(height))
