"""UWB aiding of a solve: one IMU + UWB filter per tag, its positions as drift correction.

Each tag is tracked by the tightly coupled filter of its IMU unit
(:func:`ikfusion.uwb.tracking.track_tags`, raw TOAs, NLOS gating); the tracked positions and
covariances, on the IMU timeline, become the :class:`ikfusion.correction.DriftCorrection` of the
solve. The TOA log's ``time`` column must be on the recording's timeline (seconds from its first
sample); the IMU world frame and the constellation frame are taken to be the same (ENU).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .correction import DriftCorrection, SiteFixes
from .errors import InputError
from .imu.calibration import Calibration, calibrate_recording
from .io.reader import read_imu
from .io.recording import ImuRecording
from .io.sensor_map import SensorMap, load_sensor_map
from .model import Body
from .model.human_model import HumanModel
from .sim.uwb_capture import imu_units_from_recording
from .uwb.constellation import load_constellation
from .uwb.ekf import EkfOptions, UnitTrack
from .uwb.toa_log import read_toa_csv
from .uwb.tracking import TagInfo, load_tags, track_tags


@dataclass
class UwbInputs:
    """The UWB files of a session (SPEC sections 3-4), and how to filter them.

    ``smooth``: the tag filters also run backward over the recording (every instant uses the
    whole file, :mod:`ikfusion.uwb.smoother`); False keeps them causal, as they would run live.
    """

    toa: Path
    readers: Path
    tags: Path
    smooth: bool = True


def track_recording_tags(recording: ImuRecording, sensor_map: Mapping[str, str],
                         model: HumanModel, calibration: Calibration,
                         files: UwbInputs, actor: str | None = None
                         ) -> tuple[dict[str, TagInfo], dict[str, UnitTrack]]:
    """Track the tags of one actor with the IMU of the segment each sits on.

    ``actor`` None tracks every tag of the file.

    Raises:
        InputError: Bad files (naming file, line and field), a tag without a sensor, an actor
            without tags.
    """
    tags = load_tags(files.tags)
    if actor is not None:
        tags = {k: t for k, t in tags.items() if t.actor == actor}
        if not tags:
            raise InputError(f"no tag of actor {actor!r}", path=files.tags, field="actor")
    constellation = load_constellation(files.readers)
    log = read_toa_csv(files.toa)
    mounting = {s: R.T for s, R in calibration.R_sensor_segment.items()}
    units = imu_units_from_recording(recording, sensor_map, tags, model, mounting)
    return tags, track_tags(log, constellation, tags, units,
                            options=EkfOptions(smooth=files.smooth))


@dataclass
class TrackedCapture:
    """A capture folder read, calibrated on its N-pose and its tags tracked, for any solves."""

    recording: ImuRecording
    sensor_map: SensorMap
    model: HumanModel
    calibration: Calibration
    tags: dict[str, TagInfo]
    tracks: dict[str, UnitTrack]


def track_capture(folder: str | Path, smooth: bool = True) -> TrackedCapture:
    """Read a capture folder as ``simulate --readers`` writes it and track its tags.

    The folder holds ``imu/``, ``sensors.yaml``, ``body.yaml``, ``toa.csv``, ``readers.yaml``
    and ``tags.yaml``; ``smooth`` as in :class:`UwbInputs`.

    Raises:
        InputError: Bad files (naming file, line and field).
    """
    root = Path(folder)
    sensor_map = load_sensor_map(root / "sensors.yaml")
    recording = read_imu(root / "imu", sensor_map=sensor_map)
    model = HumanModel.from_body(Body.from_yaml(root / "body.yaml"))
    calibration = calibrate_recording(recording, sensor_map)
    files = UwbInputs(root / "toa.csv", root / "readers.yaml", root / "tags.yaml", smooth)
    tags, tracks = track_recording_tags(recording, sensor_map, model, calibration, files)
    return TrackedCapture(recording, sensor_map, model, calibration, tags, tracks)


def drift_correction(tags: Mapping[str, TagInfo], tracks: Mapping[str, UnitTrack],
                     time: np.ndarray, mode: str) -> DriftCorrection:
    """The correction of a solve on ``time`` from the tag tracks (interpolated when needed)."""
    fixes = []
    for tag_id, track in tracks.items():
        if len(track.time) == len(time) and np.allclose(track.time, time):
            p, cov = track.p_world_tag, track.cov
        else:
            p = np.stack([np.interp(time, track.time, track.p_world_tag[:, i],
                                    left=np.nan, right=np.nan) for i in range(3)], axis=1)
            index = np.clip(np.searchsorted(track.time, time), 0, len(track.time) - 1)
            cov = track.cov[index]
        fixes.append(SiteFixes(tags[tag_id].site, p, cov))
    return DriftCorrection(fixes, mode=mode)


def uwb_summary(tracks: Mapping[str, UnitTrack],
                correction: DriftCorrection, smoothed: bool = True) -> dict[str, object]:
    """What ``summary.json`` reports about UWB.

    Per tag: transmissions and TOAs used and rejected, time without UWB; whether the tracks
    were smoothed over the recording; and the remaining horizontal gap of the correction.
    """
    per_tag = {}
    for tag_id, track in tracks.items():
        t = track.totals
        per_tag[tag_id] = {
            "transmissions": int(t.transmissions), "transmissions_used": int(t.transmissions_used),
            "toas": int(t.toas), "toas_used": int(t.toas_used),
            "toas_rejected": int(t.toas_rejected), "resets": int(t.resets),
            "seconds_without_uwb": float(t.seconds_without_uwb),
        }
    gap = correction.gap[np.isfinite(correction.gap)]
    return {"used": True, "correction": correction.mode, "smoothed": smoothed, "tags": per_tag,
            "gap_mean_m": float(gap.mean()) if gap.size else None,
            "gap_max_m": float(gap.max()) if gap.size else None}
