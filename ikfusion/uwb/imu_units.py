"""The IMU units of UWB tags from a real recording (the input of the tag filters).

Each tag rides on a segment; that segment's sensor, with the lever arm from the sensor to the
tag, is the tag's IMU unit (:class:`ikfusion.uwb.tracking.ImuUnit`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from ..errors import InputError
from ..io.recording import ImuRecording
from ..model.human_model import HumanModel
from .tracking import ImuUnit, TagInfo

#: Tag sites on the feet (their units get zero-velocity updates in stance).
FOOT_TAG_SITES = ("LeftFootTop", "RightFootTop")


def tag_segment(model: HumanModel, site: str) -> str:
    """Segment carrying a tag site (its sensor is the tag's IMU unit)."""
    return model.site(site).segment


def imu_units_from_recording(recording: ImuRecording, sensor_map: Mapping[str, str],
                             tags: Mapping[str, TagInfo], model: HumanModel,
                             R_segment_sensor: Mapping[str, np.ndarray] | None = None,
                             heights: Mapping[str, np.ndarray] | None = None,
                             ) -> dict[str, ImuUnit]:
    """The IMU units of the tags from a real recording and its sensor map.

    The lever arm comes from the model in its neutral pose (segment frames parallel to the
    world) and the sensor-to-segment calibration ``R_segment_sensor``; without a calibration
    for a segment the sensor is taken as aligned with it.

    Args:
        recording: The IMU recording (orientation, acc and gyr of each sensor).
        sensor_map: Sensor id -> segment.
        tags: The tags.
        model: The subject's model (site positions).
        R_segment_sensor: Segment -> mounting rotation (3, 3), e.g. from ``solve``'s
            calibration.
        heights: Tag id -> tag height per sample (N,) [m] for the height aid.

    Raises:
        InputError: A tag whose segment has no sensor, or a sensor without acc/gyr.
    """
    streams = recording.segment_streams(sensor_map)
    levers = tag_levers(model, tags, R_segment_sensor)
    out = {}
    for tag_id, tag in tags.items():
        segment = tag_segment(model, tag.site)
        stream = streams.get(segment)
        if stream is None:
            raise InputError(f"tag {tag_id} on {tag.site} needs a sensor on {segment}; the map "
                             f"covers {', '.join(sorted(streams))}", field="sensors")
        if stream.acc is None or stream.gyr is None:
            raise InputError(f"sensor {stream.sensor_id} ({segment}) has no Acc/Gyr columns; "
                             "the UWB filter needs both", path=stream.path, field="Acc_X")
        acc = np.where(stream.valid[:, None], stream.acc, np.nan)
        gyr = np.where(stream.valid[:, None], stream.gyr, np.nan)
        out[tag_id] = ImuUnit(recording.time, stream.R_world_sensor, acc, gyr, levers[tag_id],
                              None if heights is None else heights.get(tag_id),
                              foot=tag.site in FOOT_TAG_SITES)
    return out


def tag_levers(model: HumanModel, tags: Mapping[str, TagInfo],
               R_segment_sensor: Mapping[str, np.ndarray] | None = None
               ) -> dict[str, np.ndarray]:
    """Tag id -> sensor-to-tag vector in the sensor frame, shape (3,) [m].

    From the model in its neutral pose (segment frames parallel to the world) and the mounting
    ``R_segment_sensor`` of the tag's segment (the sensor taken as aligned without one).
    """
    data = pin.Data(model.model)  # (createData() builds the same, several times slower)
    pin.framesForwardKinematics(model.model, data, model.neutral())
    out = {}
    for tag_id, tag in tags.items():
        segment = tag_segment(model, tag.site)
        R_ws = data.oMf[model.segment_frame_id(segment)].rotation
        mounting = np.eye(3) if R_segment_sensor is None else np.asarray(
            R_segment_sensor.get(segment, np.eye(3)), dtype=float)
        p_tag = data.oMf[model.site_frame_id(tag.site)].translation
        p_sensor = data.oMf[model.site_frame_id(segment)].translation
        out[tag_id] = (R_ws @ mounting).T @ (p_tag - p_sensor)
    return out
