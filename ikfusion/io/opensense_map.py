"""OpenSense's sensor mapping XML, read as a sensor map (SPEC section 4).

OpenSim's OpenSense ships the sensor placement of a trial as XML (``myIMUMappings.xml``)::

    <OpenSimDocument Version="40000">
      <XsensDataReaderSettings>
        <trial_prefix>MT_012005D6_009-001</trial_prefix>
        <ExperimentalSensors>
          <ExperimentalSensor name="_00B42268">
            <name_in_model>torso_imu</name_in_model>
          </ExperimentalSensor>
          ...

Each ``ExperimentalSensor`` names a sensor id (OpenSim puts ``_`` in front, since its names may
not start with a digit) and the IMU frame in the OpenSim model, ``<body>_imu``. The body is
turned into our segment with :data:`OPENSIM_BODY_SEGMENTS`. Other elements (the trial prefix,
the reader's rotation settings) are not used.

The file is parsed with the standard library's expat parser; a document type declaration (the
only place where entities can be declared, and so expanded into a "billion laughs") is refused,
as no OpenSense file has one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from ..errors import ConfigError
from ..yaml_files import read_user_file

__all__ = ["OPENSIM_BODY_SEGMENTS", "OpenSenseSensor", "is_xml_file", "read_opensense_mapping"]

#: OpenSim body name (Rajagopal 2015 and gait2392 full-body models; scapula/clavicle as in
#: upper-limb models) -> our MVN segment (SPEC section 2). ``calcn`` (the calcaneus, where
#: OpenSense puts a foot IMU) is the foot; ``talus`` carries no sensor in OpenSense. The torso is
#: one rigid body in OpenSim, whose IMU sits on the chest: T8. Both forearm bones are the forearm.
OPENSIM_BODY_SEGMENTS: dict[str, str] = {
    "pelvis": "Pelvis",
    "torso": "T8",
    "head": "Head",
    "femur_r": "RightUpperLeg",
    "tibia_r": "RightLowerLeg",
    "calcn_r": "RightFoot",
    "toes_r": "RightToe",
    "femur_l": "LeftUpperLeg",
    "tibia_l": "LeftLowerLeg",
    "calcn_l": "LeftFoot",
    "toes_l": "LeftToe",
    "scapula_r": "RightShoulder",
    "clavicle_r": "RightShoulder",
    "humerus_r": "RightUpperArm",
    "ulna_r": "RightForeArm",
    "radius_r": "RightForeArm",
    "hand_r": "RightHand",
    "scapula_l": "LeftShoulder",
    "clavicle_l": "LeftShoulder",
    "humerus_l": "LeftUpperArm",
    "ulna_l": "LeftForeArm",
    "radius_l": "LeftForeArm",
    "hand_l": "LeftHand",
}

#: Suffix OpenSense gives an IMU frame: ``<body>_imu``.
IMU_FRAME_SUFFIX = "_imu"


@dataclass
class OpenSenseSensor:
    """One ``<ExperimentalSensor>`` entry.

    Attributes:
        name: The ``name`` attribute as written (e.g. ``_00B42268``).
        line: 1-based line of the element in the file.
        frame: The ``name_in_model`` text (e.g. ``torso_imu``), ``None`` when absent.
    """

    name: str
    line: int
    frame: str | None = None
    _text: list[str] = field(default_factory=list, repr=False)

    @property
    def sensor_id(self) -> str:
        """The sensor id without OpenSim's leading underscore."""
        return self.name.strip().lstrip("_")


def is_xml_file(path: Path) -> bool:
    """Whether a map file is XML: a ``.xml`` name, or text starting with ``<``."""
    if path.suffix.lower() == ".xml":
        return True
    try:
        with path.open("rb") as f:
            head = f.read(64)
    except OSError:
        return False  # the YAML reader reports it
    for bom in (b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff"):
        head = head.removeprefix(bom)
    return head.replace(b"\x00", b"").lstrip().startswith(b"<")


def read_opensense_mapping(path: str | Path) -> dict[str, tuple[str, int]]:
    """The sensors of an OpenSense mapping XML.

    Args:
        path: The XML file (e.g. ``myIMUMappings.xml``).

    Returns:
        Sensor id as written without OpenSim's ``_`` prefix -> (our segment, line of its
        ``ExperimentalSensor`` element).

    Raises:
        ConfigError: Unreadable or not well-formed XML, a DOCTYPE, no sensors, a sensor without
            ``name`` or ``name_in_model``, a body we do not know (listing the known ones), or a
            sensor listed twice; naming the file and the line.
    """
    file = Path(path)
    sensors = _parse(read_user_file(file, "the sensor map"), file)
    if not sensors:
        raise ConfigError(
            "no <ExperimentalSensor name=\"_<sensor id>\"><name_in_model>pelvis_imu"
            "</name_in_model></ExperimentalSensor> entries: an OpenSense mapping lists one per "
            "sensor (or give the YAML map of SPEC section 3)", path=file)
    out: dict[str, tuple[str, int]] = {}
    for sensor in sensors:
        sid = sensor.sensor_id
        if not sid:
            raise ConfigError("an <ExperimentalSensor> needs a name=\"_<sensor id>\"", path=file,
                              line=sensor.line, field="name")
        frame = (sensor.frame or "").strip()
        if not frame:
            raise ConfigError(f"sensor {sid} has no <name_in_model> (e.g. pelvis_imu)", path=file,
                              line=sensor.line, field="name_in_model")
        body = frame.removesuffix(IMU_FRAME_SUFFIX)
        if body not in OPENSIM_BODY_SEGMENTS:
            raise ConfigError(
                f"unknown OpenSim body {body!r} for sensor {sid}; known bodies (optionally with "
                f"{IMU_FRAME_SUFFIX}): {', '.join(OPENSIM_BODY_SEGMENTS)}", path=file,
                line=sensor.line, field="name_in_model")
        if sid in out:
            raise ConfigError(f"sensor {sid} is listed twice (lines {out[sid][1]} and "
                              f"{sensor.line})", path=file, line=sensor.line, field="name")
        out[sid] = (OPENSIM_BODY_SEGMENTS[body], sensor.line)
    return out


def _parse(data: bytes, file: Path) -> list[OpenSenseSensor]:
    """The ``ExperimentalSensor`` entries, wherever they sit in the document."""
    parser = expat.ParserCreate()
    sensors: list[OpenSenseSensor] = []
    open_tags: list[str] = []

    def start(tag: str, attributes: dict[str, str]) -> None:
        open_tags.append(tag)
        if tag == "ExperimentalSensor":
            sensors.append(OpenSenseSensor(attributes.get("name", ""),
                                           parser.CurrentLineNumber))

    def end(tag: str) -> None:
        open_tags.pop()
        if tag == "name_in_model" and sensors and "ExperimentalSensor" in open_tags:
            sensors[-1].frame = "".join(sensors[-1]._text)

    def text(chunk: str) -> None:
        if open_tags and open_tags[-1] == "name_in_model" and sensors:
            sensors[-1]._text.append(chunk)

    def refuse_doctype(*_: object) -> None:
        raise ConfigError("a <!DOCTYPE> (entity declarations) is not accepted in a sensor map",
                          path=file, line=parser.CurrentLineNumber)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    parser.StartDoctypeDeclHandler = refuse_doctype
    parser.EntityDeclHandler = refuse_doctype
    try:
        parser.Parse(data, True)
    except expat.ExpatError as err:
        raise ConfigError(f"not valid XML: {expat.ErrorString(err.code)} (column "
                          f"{err.offset + 1})", path=file, line=err.lineno) from None
    except (LookupError, ValueError) as err:  # an unknown encoding in the XML declaration
        raise ConfigError(f"not valid XML: {err}", path=file, line=parser.CurrentLineNumber) \
            from None
    return sensors
