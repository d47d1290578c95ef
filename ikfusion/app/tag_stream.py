"""The UWB tags of one actor tracked as the samples arrive: the fixes of a causal solve.

:class:`TagStream` is what ``live`` (any source: replay, UDP, LSL) and ``solve --causal`` give
the :class:`~ikfusion.live.actor_stream.ActorStream` for UWB. It takes the TOA samples as they
arrive (:meth:`TagStream.add_toa`; ``solve --causal`` hands it the TOA log, pulled up to each
frame), builds the drift correction once the actor's calibration is known (the tag lever arms
need the mountings), and then, frame by frame (:meth:`TagStream.frame`), steps each tag's
filter (:class:`~ikfusion.uwb.ekf_stream.UnitFilterStream`) on the frame's IMU sample of the
tag's segment and the transmissions received before the frame, and writes the tag fix of that
frame into the correction. Every choice looks at the past only:

* the transmissions of frame ``k`` are the TOAs with a time before frame ``k``'s, grouped by
  (tag, seq) as offline; a TOA arriving after its frame was stepped is late: dropped, counted;
* a filter starts at the last fix once its tag's fixes span ``_CLOCK_FIT_SECONDS / 2`` (or
  its first fix is ``_CLOCK_FIT_SECONDS`` old), the transmit-time rate fitted on the fixes of
  the last ``_CLOCK_FIT_SECONDS`` (the frames of the start-up buffer are stepped when it is
  full, so a tag heard from the start starts about a second in);
* a foot unit's zero-velocity updates come from the stance the actor stream recognised from
  past samples;
* a tag whose last ``FIT_TRANSMISSIONS`` transmissions do not fit the constellation
  (:func:`ikfusion.uwb.health.fit_from_counts`) stops aiding until they do again; a reader not
  heard for ``READER_LOST_S`` while others are is reported lost (status line and warnings).
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..imu.calibration import Calibration
from ..model.human_model import HumanModel
from .correction import CorrectionSettings, DriftCorrection, SiteFixes
from .uwb_aiding import TrackedTags, UwbAiding, UwbInputs

if TYPE_CHECKING:
    from ..live.actor_stream import Reading
    from ..live.samples import ToaSample
    from ..uwb.constellation import Constellation
    from ..uwb.ekf import EkfOptions, UnitTransmissions
    from ..uwb.ekf_stream import UnitFilterStream
    from ..uwb.tracking import TagInfo

#: Nominal transmission rate of the tags [Hz] (as :func:`ikfusion.uwb.tracking.track_tags`).
TX_RATE = 10.0
#: A tag is judged on its last this many transmissions ...
FIT_TRANSMISSIONS = 50
#: ... once it has at least this many.
FIT_MIN_TRANSMISSIONS = 20
#: A reader heard before and silent this long while others are heard is lost [s].
READER_LOST_S = 2.0


@dataclass
class _Tag:
    """One tag's state in the stream."""

    info: TagInfo
    segment: str
    pending: list[ToaSample] = field(default_factory=list)  # received, not yet stepped
    in_order: bool = True  # ``pending`` is in time order (TOAs arrived in time order)
    waiting: list[ToaSample] = field(default_factory=list)  # stepped before the start
    filter: UnitFilterStream | None = None
    horizon: float = -np.inf  # TOAs before this time were stepped
    next_try: float = -np.inf  # the start is not tried again before this time [s]
    seq: tuple[float, int, int, int] | None = None  # last (time, raw, unwrapped, max raw)
    late: int = 0
    problem: str | None = None
    judged: int = 0  # transmissions its filter had evaluated when its fit was last judged
    times: list[float] = field(default_factory=list)
    p: list[np.ndarray] = field(default_factory=list)
    cov: list[np.ndarray] = field(default_factory=list)


class TagStream:
    """The tags of one actor tracked causally (see the module docstring).

    Args:
        tags: The actor's tags (tag id -> :class:`~ikfusion.uwb.tracking.TagInfo`).
        constellation: The readers.
        model: The actor's model (tag sites, for the lever arms).
        sensor_map: Sensor id -> segment (each tag's segment needs a sensor).
        mode: Correction mode (``off``, ``slide``, ``no-slide``).
        rate: IMU sample rate [Hz].
        toa: A TOA log in time order pulled up to each frame (``solve --causal``), or None
            (the samples come through :meth:`add_toa`).
        settings: Correction settings (the shipped ones when None).
        options: Filter tuning (causal).

    Raises:
        InputError: A tag whose segment has no sensor, an actor without tags.
    """

    def __init__(self, tags: Mapping[str, TagInfo], constellation: Constellation,
                 model: HumanModel, sensor_map: Mapping[str, str], mode: str, rate: float, *,
                 toa: Iterator[ToaSample] | None = None,
                 settings: CorrectionSettings | None = None,
                 options: EkfOptions | None = None) -> None:
        from ..uwb.imu_units import tag_segment

        if not tags:
            raise InputError("no UWB tag for this actor", field="tags")
        mapped = set(sensor_map.values())
        self.tags: dict[str, _Tag] = {}
        for tag_id, info in tags.items():
            segment = tag_segment(model, info.site)
            if segment not in mapped:
                raise InputError(f"tag {tag_id} on {info.site} needs a sensor on {segment}; "
                                 f"the map covers {', '.join(sorted(mapped))}", field="sensors")
            self.tags[tag_id] = _Tag(info, segment)
        self.constellation, self.model, self.mode = constellation, model, mode
        self.rate = float(rate)
        self.settings = settings
        self.options = options
        self.correction: DriftCorrection | None = None
        self._toa = toa
        self._next: ToaSample | None = None
        self._column = {rid: j for j, rid in enumerate(constellation.ids)}
        from ..uwb.ekf import UnitTransmissions

        m = len(self._column)
        self._no_transmission = UnitTransmissions(
            np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, m)),
            np.zeros((0, 3)), np.zeros(0), np.zeros((0, 4, 4)))
        self.unknown_readers: set[str] = set()
        self.heard = np.full(len(constellation.ids), -np.inf)  # last TOA time per reader
        self.lost: dict[str, float] = {}  # reader -> since when [s]
        self.events: list[str] = []
        self.time = -np.inf

    # ------------------------------------------------------------------ input
    def add_toa(self, sample: ToaSample) -> None:
        """One TOA sample as it arrived (another actor's tags and unknown readers ignored)."""
        tag = self.tags.get(sample.tag)
        if tag is None:
            return
        column = self._column.get(sample.reader)
        if column is None:
            self.unknown_readers.add(sample.reader)
            return
        if not (np.isfinite(sample.time_s) and np.isfinite(sample.toa_m)):
            return
        if sample.time_s < tag.horizon:
            tag.late += 1
            return
        if tag.pending and sample.time_s < tag.pending[-1].time_s:
            tag.in_order = False
        tag.pending.append(sample)
        self.heard[column] = max(self.heard[column], sample.time_s)

    def __call__(self, calibration: Calibration) -> DriftCorrection | None:
        """The drift correction of the actor, built when its calibration is known."""
        from ..uwb.ekf import EkfOptions
        from ..uwb.ekf_stream import UnitFilterStream
        from ..uwb.imu_units import tag_levers

        mounting = {s: R.T for s, R in calibration.R_sensor_segment.items()}
        levers = tag_levers(self.model, {t: s.info for t, s in self.tags.items()}, mounting)
        c = self.constellation
        for tag_id, tag in self.tags.items():
            tag.filter = UnitFilterStream(c.positions, c.clock_offsets, levers[tag_id], c.sigma,
                                          self.rate, self.options or EkfOptions(smooth=False))
            tag.filter.fill_fix = self._fill_fix
        fixes = [SiteFixes(t.info.site, np.zeros((0, 3)), np.zeros((0, 3, 3)))
                 for t in self.tags.values()]
        self.correction = DriftCorrection(fixes, self.mode, self.settings
                                          if self.settings is not None
                                          else CorrectionSettings.load())
        return self.correction

    # ------------------------------------------------------------------ per frame
    def frame(self, k: int, time_s: float, readings: Mapping[str, Reading],
              still: Mapping[str, bool]) -> None:
        """Step every tag to frame ``k`` at ``time_s`` [s] and write its fixes.

        Args:
            k: Frame index in the correction.
            time_s: Frame time [s].
            readings: Segment -> its sensor's reading of the frame.
            still: Foot segment -> it stands still (stance from past samples).
        """
        correction = self.correction
        if correction is None:
            return
        self._pull(time_s)
        correction.grow(k + 1)
        self.time = time_s
        for i, tag in enumerate(self.tags.values()):
            p, cov = self._step(tag, time_s, readings.get(tag.segment),
                                bool(still.get(tag.segment, False)))
            tag.times.append(time_s)
            tag.p.append(p)
            tag.cov.append(cov)
            aiding = tag.problem is None
            correction.fixes[i].p_world[k] = p if aiding else np.nan
            correction.fixes[i].cov[k] = cov if aiding else np.nan
        self._judge_readers(time_s)

    def _pull(self, time_s: float) -> None:
        """The replayed TOA log's samples before ``time_s`` handed to :meth:`add_toa`."""
        if self._toa is None:
            return
        while True:
            if self._next is None:
                self._next = next(self._toa, None)
                if self._next is None:
                    self._toa = None
                    return
            if self._next.time_s >= time_s:
                return
            self.add_toa(self._next)
            self._next = None

    def _step(self, tag: _Tag, time_s: float, reading: Reading | None, still: bool
              ) -> tuple[np.ndarray, np.ndarray]:
        """Tag ``tag`` stepped to ``time_s``: its position and covariance (NaN unstarted)."""
        filt = tag.filter
        assert filt is not None
        none = (np.full(3, np.nan), np.full((3, 3), np.nan))
        filt.sample(time_s, None if reading is None else reading.acc,
                    None if reading is None else reading.gyr,
                    None if reading is None else reading.R_world_sensor)
        due = _take_due(tag, time_s)
        tag.horizon = time_s
        if filt.started:
            p, cov = filt.step(self._transmissions(tag, due, located=False), still)
            self._judge_tag(tag, filt)
            return p, cov
        return self._try_start(tag, filt, due, time_s) or none

    def _try_start(self, tag: _Tag, filt: UnitFilterStream, due: list[ToaSample],
                   time_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Start the filter from the fixes of the last seconds when they are enough."""
        from ..uwb.tracking import _CLOCK_FIT_SECONDS, start_at

        keep = time_s - _CLOCK_FIT_SECONDS - 0.5
        tag.waiting = [s for s in tag.waiting if s.time_s >= keep] + due
        heard = [s.time_s for s in tag.waiting]
        if (time_s < tag.next_try or not heard
                or time_s - min(heard) < 0.5 * _CLOCK_FIT_SECONDS):
            return None  # too little heard yet to fit the clock: no fix computed
        tag.next_try = time_s + 0.25
        tx = self._transmissions(tag, tag.waiting, batch=True)
        assert tx.fix_clock is not None
        ok = np.flatnonzero(np.isfinite(tx.fix_clock)
                            & (tx.time >= time_s - _CLOCK_FIT_SECONDS))
        if ok.size == 0:
            return None
        span = float(tx.time[ok[-1]] - tx.time[ok[0]])
        if span < 0.5 * _CLOCK_FIT_SECONDS and time_s - tx.time[ok[0]] < _CLOCK_FIT_SECONDS:
            return None
        tag.waiting = []
        return filt.start(start_at(tx, int(ok[-1]), ok))

    def _transmissions(self, tag: _Tag, rows: list[ToaSample], batch: bool = False,
                       located: bool = True) -> UnitTransmissions:
        """``rows`` grouped into transmissions with their fixes (seq unwrapped as it goes).

        ``batch``: unwrapped on their own (the start's window); else continuing the tag's
        last transmission. ``located`` False: the fixes are left NaN, for the filter to fill
        (:meth:`_fill_fix`) when it needs one.
        """
        from ..uwb.locate import LocateOptions, locate
        from ..uwb.toa_log import ToaLog, group_transmissions
        from ..uwb.tracking import SPEED_OF_LIGHT, unwrap_sequence

        m = len(self._column)
        if not rows and not batch:  # most frames of a tag: nothing heard in their interval
            return self._no_transmission
        rows = _without_repeats(rows)
        log = ToaLog(np.array([s.time_s for s in rows], dtype=float),
                     np.array([s.tag for s in rows], dtype=object),
                     np.array([s.seq for s in rows], dtype=np.int64),
                     np.array([s.reader for s in rows], dtype=object),
                     np.array([s.toa_m for s in rows], dtype=float), np.zeros(len(rows), int))
        grouped = group_transmissions(log, self.constellation.ids)
        if batch:
            seq = unwrap_sequence(grouped.time, grouped.seq, TX_RATE)
            raw = grouped.seq
            tag.seq = None if not len(seq) else (float(grouped.time[-1]), int(raw[-1]),
                                                 int(seq[-1]), int(raw.max()))
        else:
            seq = np.array([_unwrap_next(tag, float(t), int(s))
                            for t, s in zip(grouped.time, grouped.seq)], dtype=np.int64)
        tau = seq.astype(float) * (SPEED_OF_LIGHT / TX_RATE)
        from ..uwb.ekf import UnitTransmissions

        if not len(seq):
            return UnitTransmissions(np.zeros(0), seq, tau, np.zeros((0, m)), np.zeros((0, 3)),
                                     np.zeros(0), np.zeros((0, 4, 4)))
        if not located:
            t_count = len(seq)
            return UnitTransmissions(grouped.time, seq, tau, grouped.toa,
                                     np.full((t_count, 3), np.nan), np.full(t_count, np.nan),
                                     np.full((t_count, 4, 4), np.nan))
        fixes = locate(grouped.toa, self.constellation, LocateOptions())
        ok = fixes.ok
        return UnitTransmissions(grouped.time, seq, tau, grouped.toa,
                                 np.where(ok[:, None], fixes.p_world_tag, np.nan),
                                 np.where(ok, fixes.clock - tau, np.nan), fixes.cov)

    def _fill_fix(self, tx: UnitTransmissions, i: int) -> None:
        """Locate transmission ``i`` of ``tx`` into its (NaN) fix rows."""
        from ..uwb.locate import LocateOptions, locate

        assert tx.fix_p_world_tag is not None and tx.fix_clock is not None
        assert tx.fix_cov is not None
        if np.isfinite(tx.fix_clock[i]):
            return
        fixes = locate(tx.toa[i:i + 1], self.constellation, LocateOptions())
        if fixes.ok[0]:
            tx.fix_p_world_tag[i] = fixes.p_world_tag[0]
            tx.fix_clock[i] = fixes.clock[0] - tx.tau_nominal[i]
            tx.fix_cov[i] = fixes.cov[0]

    # ------------------------------------------------------------------ health
    def _judge_tag(self, tag: _Tag, filt: UnitFilterStream) -> None:
        """The tag aids while its last transmissions fit the constellation."""
        from ..uwb.health import fit_from_counts

        if filt.evaluated == tag.judged:  # no transmission since: the same fit
            return
        tag.judged = filt.evaluated
        received, used, toas_used, toas_rejected = filt.last_counts(FIT_TRANSMISSIONS)
        if received < FIT_MIN_TRANSMISSIONS:
            return
        fit = fit_from_counts(received, used, toas_used, toas_rejected)
        if fit.problem != tag.problem and (fit.problem is None) != (tag.problem is None):
            self.events.append(
                f"UWB tag {tag.info.id} ({tag.info.site}) stops aiding at {self.time:.1f} s: "
                f"{fit.problem}" if fit.problem is not None else
                f"UWB tag {tag.info.id} ({tag.info.site}) aids again from {self.time:.1f} s")
        tag.problem = fit.problem

    def _judge_readers(self, time_s: float) -> None:
        """Readers silent for ``READER_LOST_S`` while others are heard are lost."""
        newest = float(self.heard.max()) if len(self.heard) else -np.inf
        for rid, j in self._column.items():
            last = float(self.heard[j])
            silent = np.isfinite(last) and newest - last > READER_LOST_S \
                and time_s - newest < READER_LOST_S
            if silent and rid not in self.lost:
                self.lost[rid] = last
                self.events.append(f"UWB reader {rid} lost: nothing heard since {last:.1f} s")
            elif not silent and rid in self.lost and last > self.lost[rid]:
                del self.lost[rid]
                self.events.append(f"UWB reader {rid} heard again at {last:.1f} s")

    # ------------------------------------------------------------------ reports
    def status(self) -> str:
        """A short status: lost readers, tags not aiding ('' when all is well)."""
        parts = []
        if self.lost:
            parts.append("UWB reader " + ",".join(sorted(self.lost)) + " lost")
        off = [t.info.id for t in self.tags.values() if t.problem is not None]
        if off:
            parts.append("tag " + ",".join(off) + " not aiding")
        return "; ".join(parts)

    def aiding(self) -> UwbAiding:
        """What the stream did, as :class:`~ikfusion.app.uwb_aiding.UwbAiding` for the summary.

        The tags are judged as offline on the whole stream (``fits``), besides the per-stretch
        judgement that decided whether a tag aided while it ran.
        """
        from ..uwb.ekf_stream import UnitFilterStream
        from ..uwb.health import faulty_readers, reader_report, tag_fit

        tracks = {}
        for tag_id, tag in self.tags.items():
            filt = tag.filter or UnitFilterStream(
                self.constellation.positions, self.constellation.clock_offsets, np.zeros(3),
                self.constellation.sigma, self.rate)
            n = len(tag.times)
            tracks[tag_id] = filt.track(np.array(tag.times, dtype=float),
                                        np.array(tag.p).reshape(n, 3),
                                        np.array(tag.cov).reshape(n, 3, 3))
        infos = {t: s.info for t, s in self.tags.items()}
        tracked = TrackedTags(infos, tracks, self.constellation.ids, smoothed=False)
        fits = {t: tag_fit(tr) for t, tr in tracks.items()}
        warnings = [*self.events]
        warnings += [f"UWB tag {t} ({infos[t].site}) does not fit the constellation: "
                     f"{f.problem}; check the readers file (ids, positions) and the tags file"
                     for t, f in fits.items() if f.problem is not None]
        late = sum(t.late for t in self.tags.values())
        if late:
            warnings.append(f"UWB: {late} TOA(s) arrived after their frame and were dropped")
        if self.unknown_readers:
            warnings.append("UWB: TOAs of readers not in the readers file were ignored: "
                            + ", ".join(sorted(self.unknown_readers)))
        readers = reader_report(list(tracks.values()), self.constellation.ids)
        warnings += faulty_readers(readers)
        used = self.correction if self.correction is not None and any(
            np.isfinite(f.p_world).any() for f in self.correction.fixes) else None
        if used is None:
            warnings.append("UWB: no tag aided the solve, it is IMU-only")
        return UwbAiding(tracked, used, self.mode, fits, readers, warnings)


def _unwrap_next(tag: _Tag, time_s: float, raw: int) -> int:
    """The unwrapped number of the tag's next transmission (its counter may wrap)."""
    if tag.seq is None:
        tag.seq = (time_s, raw, raw, raw)
        return raw
    t0, raw0, unwrapped0, top = tag.seq
    top = max(top, raw)
    modulus = max(256, 1 << top.bit_length())
    expected = int(np.rint((time_s - t0) * TX_RATE))
    step = (raw - raw0 - expected + modulus // 2) % modulus - modulus // 2 + expected
    tag.seq = (time_s, raw, unwrapped0 + step, top)
    return unwrapped0 + step


def _take_due(tag: _Tag, time_s: float) -> list[ToaSample]:
    """The tag's pending TOAs before ``time_s`` [s] (in arrival order), taken off ``pending``.

    In time order (the usual case, also a start-up buffer's many TOAs) a bisection; else a
    scan of them all.
    """
    pending = tag.pending
    if not pending or pending[0].time_s >= time_s and tag.in_order:
        return []
    if tag.in_order:
        i = bisect.bisect_left(pending, time_s, key=lambda s: s.time_s)
        tag.pending = pending[i:]
        return pending[:i]
    tag.pending = [s for s in pending if s.time_s >= time_s]
    tag.in_order = all(a.time_s <= b.time_s for a, b in zip(tag.pending, tag.pending[1:]))
    return [s for s in pending if s.time_s < time_s]


def _without_repeats(rows: list[ToaSample]) -> list[ToaSample]:
    """``rows`` with a reader's repeated report of a transmission dropped.

    A stream may deliver a TOA twice (a resent packet); in a file that is an input error.
    """
    seen: set[tuple[str, int, str]] = set()
    out = []
    for s in rows:
        key = (s.tag, s.seq, s.reader)
        if key not in seen:
            seen.add(key)
            out.append(s)
    return out


def open_tag_stream(files: UwbInputs, model: HumanModel, sensor_map: Mapping[str, str],
                    actor: str | None, mode: str, rate: float, *,
                    replay_log: bool = False) -> TagStream:
    """The :class:`TagStream` of one actor from the readers and tags files of a session.

    Args:
        files: The UWB files (the TOA log read only with ``replay_log``).
        model: The actor's model.
        sensor_map: Its sensor map (sensor id -> segment).
        actor: The actor's name (None: every tag of the tags file).
        mode: Correction mode.
        rate: IMU sample rate [Hz].
        replay_log: The stream pulls the TOA log itself frame by frame (``solve --causal``);
            else its samples come through :meth:`TagStream.add_toa` (``live``).

    Raises:
        InputError: Bad files (file, line and field named), an actor without tags.
    """
    from ..live.replay import toa_samples
    from ..uwb.constellation import load_constellation
    from ..uwb.toa_log import read_toa_csv
    from ..uwb.tracking import load_tags

    tags = load_tags(files.tags)
    if actor is not None:
        tags = {k: t for k, t in tags.items() if t.actor == actor}
        if not tags:
            raise InputError(f"no tag of actor {actor!r}", path=files.tags, field="actor")
    log = None
    if replay_log:
        samples = sorted(toa_samples(read_toa_csv(files.toa)), key=lambda s: s.time_s)
        log = iter(samples)
    return TagStream(tags, load_constellation(files.readers), model, sensor_map, mode, rate,
                     toa=log)
