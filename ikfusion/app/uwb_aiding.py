"""UWB aiding of a solve: one IMU + UWB filter per tag, its positions as drift correction.

Each tag is tracked by the tightly coupled filter of its IMU unit
(:func:`ikfusion.uwb.tracking.track_tags`, raw TOAs, NLOS gating); the tracked positions and
covariances, on the IMU timeline, become the :class:`ikfusion.app.correction.DriftCorrection` of the
solve. The TOA log's ``time`` column must be on the recording's timeline (seconds from its first
sample); the IMU world frame and the constellation frame are taken to be the same (ENU).

A tag whose data do not fit the constellation (:func:`ikfusion.uwb.health.tag_fit`: almost every
TOA rejected, e.g. permuted reader ids) does not aid the solve, which then falls back to the IMU
for that tag (or entirely) and says so in its warnings; readers rejected more often than a
healthy one ever is are warned about too (:mod:`ikfusion.uwb.health`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from ..imu.calibration import Calibration, calibrate_recording
from ..io.reader import read_imu
from ..io.recording import ImuRecording
from ..io.sensor_map import SensorMap, load_sensor_map
from ..model import Body
from ..model.human_model import HumanModel
from .correction import CorrectionSettings, DriftCorrection, SiteFixes

# ikfusion.uwb (and SciPy's statistics with it) is imported when UWB is used, not by every
# solve that imports this module.
if TYPE_CHECKING:
    from ..uwb.ekf import UnitTrack
    from ..uwb.health import TagFit
    from ..uwb.tracking import TagInfo


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


@dataclass
class TrackedTags:
    """The tags of one actor tracked by their filters, and the readers they were tracked with.

    Attributes:
        tags: Tag id -> :class:`TagInfo`.
        tracks: Tag id -> its filter's :class:`UnitTrack` (columns in ``reader_ids`` order).
        reader_ids: The constellation's reader ids.
        smoothed: The tracks were smoothed over the recording.
    """

    tags: dict[str, TagInfo]
    tracks: dict[str, UnitTrack]
    reader_ids: tuple[str, ...]
    smoothed: bool = True


def track_recording_tags(recording: ImuRecording, sensor_map: Mapping[str, str],
                         model: HumanModel, calibration: Calibration,
                         files: UwbInputs, actor: str | None = None) -> TrackedTags:
    """Track the tags of one actor with the IMU of the segment each sits on.

    ``actor`` None tracks every tag of the file.

    Raises:
        InputError: Bad files (naming file, line and field), a tag without a sensor, an actor
            without tags.
    """
    from ..uwb.constellation import load_constellation
    from ..uwb.ekf import EkfOptions
    from ..uwb.imu_units import imu_units_from_recording
    from ..uwb.toa_log import read_toa_csv
    from ..uwb.tracking import load_tags, track_tags

    tags = load_tags(files.tags)
    if actor is not None:
        tags = {k: t for k, t in tags.items() if t.actor == actor}
        if not tags:
            raise InputError(f"no tag of actor {actor!r}", path=files.tags, field="actor")
    constellation = load_constellation(files.readers)
    log = read_toa_csv(files.toa)
    mounting = {s: R.T for s, R in calibration.R_sensor_segment.items()}
    units = imu_units_from_recording(recording, sensor_map, tags, model, mounting)
    tracks = track_tags(log, constellation, tags, units, options=EkfOptions(smooth=files.smooth))
    return TrackedTags(tags, tracks, constellation.ids, files.smooth)


@dataclass
class TrackedCapture:
    """A capture folder read, calibrated on its N-pose and its tags tracked, for any solves."""

    recording: ImuRecording
    sensor_map: SensorMap
    model: HumanModel
    calibration: Calibration
    tags: dict[str, TagInfo]
    tracks: dict[str, UnitTrack]
    reader_ids: tuple[str, ...] = field(default=())


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
    tracked = track_recording_tags(recording, sensor_map, model, calibration, files)
    return TrackedCapture(recording, sensor_map, model, calibration, tracked.tags,
                          tracked.tracks, tracked.reader_ids)


def drift_correction(tags: Mapping[str, TagInfo], tracks: Mapping[str, UnitTrack],
                     time: np.ndarray, mode: str,
                     settings: CorrectionSettings | None = None) -> DriftCorrection:
    """The correction of a solve on ``time`` from the tag tracks (interpolated when needed).

    ``settings`` None: the shipped ``configs/correction.yaml``.
    """
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
    return DriftCorrection(fixes, mode,
                           settings if settings is not None else CorrectionSettings.load())


@dataclass
class UwbAiding:
    """What UWB brings to one solve: the correction (None: IMU only), the report, warnings.

    Attributes:
        tracked: The tracked tags.
        correction: Drift correction from the tags that fit the constellation, or None when
            none does.
        mode: Correction mode asked for.
        fits: Tag id -> how its data fit the constellation.
        readers: The per-reader report (:func:`ikfusion.uwb.health.reader_report`).
        warnings: Messages for ``summary.json`` warnings and the terminal.
    """

    tracked: TrackedTags
    correction: DriftCorrection | None
    mode: str
    fits: dict[str, TagFit]
    readers: dict[str, dict[str, Any]]
    warnings: list[str]

    def summary(self) -> dict[str, object]:
        """The ``uwb`` block of ``summary.json`` (:func:`uwb_summary`).

        Call it after the solve: the solve fills the correction's remaining gap.
        """
        return uwb_summary(self.tracked.tracks, self.correction, self.tracked.smoothed,
                           fits=self.fits, readers=self.readers, mode=self.mode)


def uwb_aiding(tracked: TrackedTags, time: np.ndarray, mode: str) -> UwbAiding:
    """Judge every tag's track, build the correction from those that fit, and report.

    A tag whose data do not fit the constellation (:func:`ikfusion.uwb.health.tag_fit`) is
    left out, with a warning naming it and the numbers; without any tag left the solve is
    IMU-only and the summary's ``used`` is False.

    Args:
        tracked: The tracked tags.
        time: The solve's frame times [s].
        mode: Correction mode (``slide`` or ``no-slide``).
    """
    from ..uwb.health import faulty_readers, reader_report, tag_fit

    fits = {tag_id: tag_fit(track) for tag_id, track in tracked.tracks.items()}
    aiding = {t: tr for t, tr in tracked.tracks.items() if fits[t].problem is None}
    correction = drift_correction(tracked.tags, aiding, time, mode) if aiding else None
    warnings = [f"UWB tag {t} ({tracked.tags[t].site}) does not aid the solve: {f.problem}; "
                "check the readers file (ids, positions) and the tags file"
                for t, f in fits.items() if f.problem is not None]
    if not aiding:
        warnings.append("UWB: no tag fits the constellation, the solve is IMU-only")
    readers = reader_report(list(tracked.tracks.values()), tracked.reader_ids)
    warnings += faulty_readers(readers)
    return UwbAiding(tracked, correction, mode, fits, readers, warnings)


@dataclass
class AidingOnCalibration:
    """The UWB aiding of a causal solve, built once its calibration is known.

    The :class:`~ikfusion.live.actor_stream.ActorStream` of ``solve --causal`` and ``live
    --replay`` calls it with the calibration of its start-up buffer; the tag filters then run
    forward (``files.smooth`` False) over the TOA log, so each frame's fix uses the TOAs up to
    it. :attr:`aiding` keeps the result for the summary.
    """

    recording: ImuRecording
    sensor_map: Mapping[str, str]
    model: HumanModel
    files: UwbInputs
    actor: str | None
    mode: str
    aiding: UwbAiding | None = None

    def __call__(self, calibration: Calibration) -> DriftCorrection | None:
        """Track the tags with ``calibration``'s mountings; the correction, or None."""
        tracked = track_recording_tags(self.recording, self.sensor_map, self.model, calibration,
                                       self.files, self.actor)
        self.aiding = uwb_aiding(tracked, self.recording.time, self.mode)
        return self.aiding.correction


def uwb_summary(tracks: Mapping[str, UnitTrack], correction: DriftCorrection | None,
                smoothed: bool = True, *, fits: Mapping[str, TagFit] | None = None,
                readers: Mapping[str, object] | None = None,
                mode: str | None = None) -> dict[str, object]:
    """What ``summary.json`` reports about UWB.

    ``used``: True only when at least one tag aided the solve. Per tag: whether it aided,
    why not, transmissions and TOAs received, used and rejected, resets, time without UWB;
    per reader (``readers``, :func:`ikfusion.uwb.health.reader_report`): TOAs received and
    rejected, the rejected share and when; whether the tracks were smoothed over the
    recording; the remaining horizontal gap of the correction [m]; and ``far_from_tags``, the
    stretches where a solved tag site stayed far from its fix (site, ``start_s``, ``end_s``,
    ``max_m``, ``mean_m``; :mod:`.far_from_tags`).

    Args:
        tracks: Tag id -> track.
        correction: The correction built from them, or None (no tag aided).
        smoothed: The tracks were smoothed.
        fits: Tag id -> :class:`~ikfusion.uwb.health.TagFit` (computed when omitted).
        readers: The per-reader report, when known.
        mode: Correction mode, when ``correction`` is None.
    """
    from ..uwb.health import tag_fit

    per_tag: dict[str, object] = {}
    for tag_id, track in tracks.items():
        t = track.totals
        fit = fits[tag_id] if fits is not None else tag_fit(track)
        per_tag[tag_id] = {
            "aiding": correction is not None and fit.problem is None, "problem": fit.problem,
            "transmissions_received": int(t.transmissions),
            "transmissions_used": int(t.transmissions_used),
            "toas_received": int(t.toas), "toas_used": int(t.toas_used),
            "toas_rejected": int(t.toas_rejected), "resets": int(t.resets),
            "seconds_without_uwb": float(t.seconds_without_uwb),
        }
    gap = np.zeros(0) if correction is None else correction.gap[np.isfinite(correction.gap)]
    return {"used": correction is not None,
            "correction": correction.mode if correction is not None else mode,
            "smoothed": smoothed, "tags": per_tag, "readers": dict(readers or {}),
            "gap_mean_m": float(gap.mean()) if gap.size else None,
            "gap_max_m": float(gap.max()) if gap.size else None,
            "far_from_tags": [] if correction is None else
            [i.as_dict() for i in correction.far_from_tags()]}

