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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .correction import DriftCorrection
from .errors import ConfigError
from .ik import Motion, Solver
from .imu.calibration import calibrate_recording
from .io.reader import read_imu
from .io.sensor_map import load_sensor_map
from .model import Body, HumanModel
from .pipeline import solve_recording
from .results import write_result_folder
from .uwb_aiding import UwbInputs, drift_correction, track_recording_tags, uwb_summary
from .yaml_files import read_yaml


@dataclass
class ActorInputs:
    """What one actor's solve reads.

    Attributes:
        name: The actor (as the tags file names it; None for a single solve of every tag).
        imu: MT Manager prefix, folder or file, IMU CSV or MVNX.
        sensor_map: Sensor map YAML.
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
    sensor_map: Path
    body: Path | None = None
    height: float | None = None
    window_s: tuple[float, float] | None = None
    pose: str = "npose"
    forward: dict[str, str] | None = None
    rate: float | None = None
    causal: bool = False

    def model(self) -> HumanModel:
        """The actor's body model."""
        if self.body is not None:
            return HumanModel.from_body(Body.from_yaml(self.body))
        if self.height is not None:
            return HumanModel.from_body(Body.from_height(self.height))
        return HumanModel.default()


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
                progress: bool = False) -> Motion:
    """Calibrate, track the actor's tags (with UWB), solve and write its result folder.

    Returns:
        The solved motion (its warnings are in ``summary.json`` too).

    Raises:
        InputError: Bad files (file, line and field named).
    """
    sensor_map = load_sensor_map(actor.sensor_map)
    recording = read_imu(actor.imu, rate=actor.rate, sensor_map=sensor_map)
    model = actor.model()
    cal = calibrate_recording(recording, sensor_map, actor.window_s, forward=actor.forward,
                              pose=actor.pose)
    fix: DriftCorrection | None = None
    summary: dict[str, object] = {"used": False}
    if uwb is not None:
        tags, tracks = track_recording_tags(recording, sensor_map, model, cal, uwb, actor.name)
        fix = drift_correction(tags, tracks, recording.time, correction or "no-slide")
    result = solve_recording(recording, sensor_map, model, solver=Solver(model),
                             progress=progress, correction=fix, calibration=cal,
                             causal=actor.causal)
    if uwb is not None and fix is not None:
        summary = uwb_summary(tracks, fix, uwb.smooth)
    extra: dict[str, Any] = {
        "calibration": {"method": cal.method, "heading_deg": float(np.degrees(cal.heading)),
                        "window_s": [cal.window[0] / recording.rate,
                                     cal.window[1] / recording.rate]},
        "uwb": summary,
        "bridged": result.bridged,
    }
    if actor.name is not None:
        extra["actor"] = actor.name
    write_result_folder(result.motion, out, bvh_up=bvh_up, extra_summary=extra)
    return result.motion


def solve_session(session: Session, out: str | Path, bvh_up: str = "z",
                  progress: bool = False) -> dict[str, Motion]:
    """Solve every actor of a session into ``out/<actor>/``."""
    root = Path(out)
    return {a.name or "actor": solve_actor(a, root / (a.name or "actor"), session.uwb,
                                           session.correction, bvh_up, progress)
            for a in session.actors}


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
    actors = [_actor(file, str(name), spec) for name, spec in data["actors"].items()]
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


def _actor(session: Path, name: str, spec: Any) -> ActorInputs:
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
        sensor_map=_file(session, spec, "map", f"{key}.map"),
        body=_file(session, spec, "body", f"{key}.body") if "body" in spec else None,
        height=None if height is None else float(height))
