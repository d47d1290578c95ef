"""What ``ikfusion live`` solves: the actors (model, sensor map, rate) and a replay's files.

``--replay`` takes a ``simulate`` capture folder (map, body and UWB files taken from it), a
session file (as ``solve --session``: every actor's recording, one UWB log), or one recording
(MT Manager prefix, folder or file, IMU CSV, MVNX) with ``--map``. The UWB tags of an actor
are tracked as the TOA samples arrive (:class:`~ikfusion.app.tag_stream.TagStream`), for a
replay as for ``--udp``/``--lsl`` with a session file naming the UWB files, exactly as
``solve --causal`` does.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from ..app.session import ActorInputs, load_session
from ..app.tag_stream import TagStream, open_tag_stream
from ..app.uwb_aiding import UwbInputs
from ..errors import InputError
from ..io.recording import ImuRecording
from ..io.sensor_map import load_sensor_map
from ..model.human_model import HumanModel
from ..uwb.toa_log import read_toa_csv
from .replay import recording_samples, toa_samples
from .samples import Sample

#: The files of a ``simulate`` capture folder that ``--replay`` takes.
CAPTURE_MAP, CAPTURE_BODY, CAPTURE_IMU = "sensors.yaml", "body.yaml", "imu"
CAPTURE_UWB = ("toa.csv", "readers.yaml", "tags.yaml")


@dataclass
class ActorSetup:
    """One actor of a live session before it starts.

    Attributes:
        name: Actor name (its ``--record`` sub-folder in a session).
        model: Its body model.
        sensor_map: Sensor id -> segment.
        rate: Sample rate [Hz].
        recording: The recording replayed, or None (a live source).
        uwb: Its UWB tags tracked as the TOAs arrive (UWB files given), or None.
    """

    name: str
    model: HumanModel
    sensor_map: Mapping[str, str]
    rate: float
    recording: ImuRecording | None = None
    uwb: TagStream | None = None

    def samples(self, named: bool) -> Iterator[Sample]:
        """The replayed samples (``named``: each names the actor)."""
        if self.recording is None:
            return iter(())
        return recording_samples(self.recording, self.sensor_map,
                                 self.name if named else None)


def actor_inputs(path: Path, map_file: Path | None, body: Path | None, height: float | None
                 ) -> tuple[list[ActorInputs], UwbInputs | None, str | None]:
    """The actors of a ``--replay`` path, their UWB files and the session's correction."""
    if path.is_dir() and (path / CAPTURE_MAP).is_file():
        uwb = None
        if all((path / f).is_file() for f in CAPTURE_UWB):
            toa, readers, tags = (path / f for f in CAPTURE_UWB)
            uwb = UwbInputs(toa, readers, tags, smooth=False)
        own_body = body if body is not None or height is not None else path / CAPTURE_BODY
        return [ActorInputs(None, path / CAPTURE_IMU, map_file or path / CAPTURE_MAP,
                            own_body if own_body and own_body.is_file() else None, height,
                            causal=True)], uwb, None
    if path.is_file() and path.suffix.lower() in (".yaml", ".yml"):
        session = load_session(path)
        if session.uwb is not None:
            session.uwb = UwbInputs(session.uwb.toa, session.uwb.readers, session.uwb.tags,
                                    smooth=False)
        return session.actors, session.uwb, session.correction
    if not path.exists() and not path.parent.is_dir():
        raise InputError("does not exist", path=path, field="replay")
    if map_file is None and path.suffix.lower() != ".mvnx":
        raise InputError("give --map for a recording (a capture folder or a session file "
                         "brings its own)", path=path, field="map")
    return [ActorInputs(None, path, map_file, body, height, causal=True)], None, None


def replay_setups(path: Path, map_file: Path | None, body: Path | None, height: float | None,
                  correction: str | None) -> tuple[list[ActorSetup], Iterator[Sample] | None]:
    """The actors of a replay and the samples of its TOA log (None without UWB).

    Raises:
        InputError: Missing or bad files (naming file, line and field).
    """
    actors, uwb, session_correction = actor_inputs(path, map_file, body, height)
    setups = []
    for actor in actors:
        sensor_map, recording, mvnx = actor.read()
        model = actor.model(mvnx)
        aiding = None if uwb is None else open_tag_stream(
            uwb, model, sensor_map, actor.name, correction or session_correction or "no-slide",
            recording.rate)
        setups.append(ActorSetup(actor.name or "actor", model, sensor_map, recording.rate,
                                 recording, aiding))
    toa = None if uwb is None else toa_samples(read_toa_csv(uwb.toa))
    return setups, toa


def source_setups(map_file: Path | None, body: Path | None, height: float | None,
                  session: Path | None, rate: float) -> list[ActorSetup]:
    """The actors of a live source (``--udp``, ``--lsl``): from ``--session`` or ``--map``.

    Raises:
        InputError: Neither given, or bad files.
    """
    uwb, mode = None, "no-slide"
    if session is not None:
        loaded = load_session(session)
        actors, uwb, mode = loaded.actors, loaded.uwb, loaded.correction
    elif map_file is not None:
        actors = [ActorInputs(None, Path("."), map_file, body, height)]
    else:
        raise InputError("a live source needs --map (one actor) or --session FILE",
                         field="map")
    out = []
    for actor in actors:
        if actor.sensor_map is None:
            raise InputError("every actor needs a sensor map", path=session, field="map")
        model, sensor_map = actor.model(), load_sensor_map(actor.sensor_map)
        tags = None if uwb is None else open_tag_stream(uwb, model, sensor_map, actor.name,
                                                        mode, rate)
        out.append(ActorSetup(actor.name or "actor", model, sensor_map, rate, uwb=tags))
    return out
