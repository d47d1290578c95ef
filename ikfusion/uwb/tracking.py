"""Tag tracking: one IMU + UWB filter (:mod:`ikfusion.uwb.ekf`) per tag, and the tags file.

:func:`track_tags` groups a TOA log into transmissions, locates each of them
(:func:`ikfusion.uwb.locate.locate`) to start the filter (position, transmit time and its rate)
and to reset it if it diverges, and runs the filter of each tag on its unit's IMU.

Tags file (SPEC section 3)::

    tags:
      T1: {actor: A, site: HeadTop}     # site: HeadTop | LeftFootTop | RightFootTop
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..atomic import atomic_write_text
from ..errors import ConfigError, InputError
from ..yaml_files import read_yaml
from .constellation import Constellation
from .ekf import (
    EkfOptions,
    ImuSamples,
    UnitStart,
    UnitTrack,
    UnitTransmissions,
    UwbTotals,
    run_unit_filter,
)
from .locate import Fixes, LocateOptions, locate
from .toa_log import ToaLog, Transmissions, group_transmissions

#: Speed of light [m/s]; the nominal schedule ``c * seq / rate`` is in metres.
SPEED_OF_LIGHT = 299_792_458.0
#: Sites a tag may sit on.
TAG_SITE_NAMES = ("HeadTop", "LeftFootTop", "RightFootTop")
#: Time over which the first fixes give the transmit-time rate [s].
_CLOCK_FIT_SECONDS = 2.0


@dataclass(frozen=True)
class TagInfo:
    """One tag of a tags file.

    Attributes:
        id: Tag id as written in TOA logs.
        actor: Name of the actor wearing it.
        site: Model site it sits on (``HeadTop``, ``LeftFootTop``, ``RightFootTop``).
    """

    id: str
    actor: str
    site: str


@dataclass(frozen=True)
class ImuUnit:
    """The IMU a tag sits on, on the IMU timeline.

    Attributes:
        time: Sample times, shape (N,) [s].
        R_world_sensor: Orientation from the IMU's own fusion, shape (N, 3, 3) (ENU world; NaN
            where missing): the initial attitude and a weak aid.
        acc: Specific force in the sensor frame, shape (N, 3) [m/s^2] (NaN where missing).
        gyr: Angular rate in the sensor frame, shape (N, 3) [rad/s] (NaN where missing).
        lever_sensor_tag: Sensor-to-tag vector in the sensor frame, shape (3,) [m].
        height: Tag height from the body, shape (N,) [m], for the optional height aid, or None.
        foot: The unit is on a foot: its stance (from its gyroscope) gives zero-velocity
            updates.
    """

    time: np.ndarray
    R_world_sensor: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    lever_sensor_tag: np.ndarray
    height: np.ndarray | None = None
    foot: bool = False


def load_tags(path: str | Path) -> dict[str, TagInfo]:
    """Read a tags YAML file (SPEC section 3).

    Raises:
        ConfigError: Naming the file and the key at fault.
    """
    path = Path(path)
    return tags_from_dict(read_yaml(path, "tags file"), source=path)


def tags_from_dict(data: object, *, source: Path | None = None) -> dict[str, TagInfo]:
    """Validate a parsed tags mapping ``{tags: {id: {actor, site}}}``.

    Raises:
        ConfigError: Naming the file and the key at fault.
    """
    if not isinstance(data, Mapping) or not isinstance(data.get("tags"), Mapping):
        raise ConfigError("expected a mapping 'tags: {<tag id>: {actor: ..., site: ...}}'",
                          path=source, field="tags")
    out: dict[str, TagInfo] = {}
    for raw_id, entry in data["tags"].items():
        tag_id = str(raw_id).strip()
        where = f"tags.{tag_id}"
        if not isinstance(entry, Mapping):
            raise ConfigError("expected {actor: <name>, site: <site>}", path=source, field=where)
        unknown = set(entry) - {"actor", "site"}
        if unknown:
            raise ConfigError("unknown key; valid keys are actor, site", path=source,
                              field=f"{where}.{sorted(map(str, unknown))[0]}")
        site = str(entry.get("site", ""))
        if site not in TAG_SITE_NAMES:
            raise ConfigError(f"site must be one of {', '.join(TAG_SITE_NAMES)}, found {site!r}",
                              path=source, field=f"{where}.site")
        out[tag_id] = TagInfo(tag_id, str(entry.get("actor", "")), site)
    return out


def save_tags(tags: Mapping[str, TagInfo], path: str | Path) -> Path:
    """Write a tags YAML file (atomically). Returns the path written."""
    data = {"tags": {t.id: {"actor": t.actor, "site": t.site} for t in tags.values()}}
    return atomic_write_text(Path(path), yaml.safe_dump(data, sort_keys=False))


def unwrap_sequence(time: np.ndarray, seq: np.ndarray, rate: float) -> np.ndarray:
    """Unwrap a tag's wrapping transmission counter using the transmission times.

    The counter modulus is the smallest power of two (at least 256) above the largest number
    seen; a counter that never decreases is returned as is.

    Args:
        time: Transmission times in order, shape (T,) [s].
        seq: Transmission numbers, shape (T,).
        rate: Nominal transmission rate [Hz].

    Returns:
        Unwrapped numbers, shape (T,) (int64).
    """
    s = np.asarray(seq, dtype=np.int64)
    if s.shape[0] < 2 or np.all(np.diff(s) > 0):
        return s.copy()
    modulus = max(256, 1 << int(s.max()).bit_length())
    expected = np.rint(np.diff(np.asarray(time, dtype=float)) * rate).astype(np.int64)
    step = np.diff(s) - expected
    step = (step + modulus // 2) % modulus - modulus // 2 + expected
    return np.concatenate([s[:1], s[0] + np.cumsum(step)])


def track_tags(
    toa_log: ToaLog,
    constellation: Constellation,
    tags: Mapping[str, TagInfo],
    imu_units: Mapping[str, ImuUnit],
    *,
    options: EkfOptions | None = None,
    tx_rate: float = 10.0,
    locate_options: LocateOptions | None = None,
    use_height: bool = False,
) -> dict[str, UnitTrack]:
    """Track every tag with its unit's IMU and the raw TOAs.

    Args:
        toa_log: The receptions (SPEC section 4); ``time`` on the IMU timeline [s].
        constellation: Readers (positions, clock offsets, range noise ``sigma``).
        tags: Tag id -> :class:`TagInfo` (e.g. from :func:`load_tags`).
        imu_units: Tag id -> the :class:`ImuUnit` it sits on.
        options: Filter tuning.
        tx_rate: Nominal transmission rate of the tags [Hz].
        locate_options: Settings of the per-transmission fixes that start and reset filters.
        use_height: Use each unit's ``height`` as a pseudo-measurement.

    Returns:
        Tag id -> :class:`~ikfusion.uwb.ekf.UnitTrack` (positions all NaN for a tag that was
        never located).

    Raises:
        InputError: A tag without an IMU unit, or a TOA log that does not fit the readers.
    """
    missing = [t for t in tags if t not in imu_units]
    if missing:
        raise InputError(f"no IMU unit for tag(s) {', '.join(missing)}; units are given for "
                         f"{', '.join(imu_units) or 'none'}", path=toa_log.source, field="tag")
    grouped = group_transmissions(toa_log, constellation.ids)
    fixes = locate(grouped.toa, constellation, locate_options or LocateOptions())
    out = {}
    for tag_id in tags:
        rows = np.flatnonzero(grouped.tag.astype(str) == tag_id)
        unit = imu_units[tag_id]
        tx = unit_transmissions(grouped, fixes, rows, tx_rate)
        out[tag_id] = track_unit(unit, tx, constellation, options, use_height=use_height)
    return out


def unit_transmissions(grouped: Transmissions, fixes: Fixes, rows: np.ndarray,
                       tx_rate: float) -> UnitTransmissions:
    """The filter's view of one tag's transmissions (rows of ``grouped`` and ``fixes``).

    Args:
        grouped: All transmissions.
        fixes: Their per-transmission fixes.
        rows: This tag's rows, in time order.
        tx_rate: Nominal transmission rate [Hz].
    """
    time = grouped.time[rows]
    seq = unwrap_sequence(time, grouped.seq[rows], tx_rate)
    tau_nominal = seq.astype(float) * (SPEED_OF_LIGHT / tx_rate)
    ok = fixes.ok[rows]
    p_fix = np.where(ok[:, None], fixes.p_world_tag[rows], np.nan)
    clock_fix = np.where(ok, fixes.clock[rows] - tau_nominal, np.nan)
    cov_fix = fixes.cov[rows]
    return UnitTransmissions(time, seq, tau_nominal, grouped.toa[rows], p_fix, clock_fix,
                             cov_fix)


def track_unit(unit: ImuUnit, tx: UnitTransmissions, constellation: Constellation,
               options: EkfOptions | None = None, *, use_height: bool = False) -> UnitTrack:
    """Run the filter of one unit, started at its first fix inside the IMU's time span."""
    imu = ImuSamples(unit.time, unit.acc, unit.gyr, unit.R_world_sensor,
                     unit.height if use_height else None, _stance(unit) if unit.foot else None)
    start = first_start(tx, float(unit.time[0]), float(unit.time[-1]))
    if start is None:
        return _empty_track(unit.time, tx, len(constellation.readers))
    return run_unit_filter(imu, tx, constellation.positions, constellation.clock_offsets, start,
                           unit.lever_sensor_tag, constellation.sigma, options)


def _stance(unit: ImuUnit) -> np.ndarray:
    """(N,) where a foot unit stands still, from its gyroscope (:func:`foot_still`)."""
    from ..imu.stance import foot_still

    rate = 1.0 / float(np.median(np.diff(unit.time))) if len(unit.time) > 1 else 60.0
    return np.asarray(foot_still(unit.R_world_sensor, rate, unit.gyr) == 1.0)


def first_start(tx: UnitTransmissions, t_begin: float, t_end: float) -> UnitStart | None:
    """The filter start at the first fix in ``[t_begin, t_end]``, or None without one.

    The transmit-time rate is the median slope of the fixes' offsets over the next
    ``_CLOCK_FIT_SECONDS`` (0 with a large uncertainty when there is only one fix).
    """
    if tx.fix_p_world_tag is None or tx.fix_clock is None or tx.fix_cov is None:
        return None
    ok = np.isfinite(tx.fix_clock) & (tx.time >= t_begin) & (tx.time <= t_end)
    if not ok.any():
        return None
    first = int(np.flatnonzero(ok)[0])
    window = np.flatnonzero(ok & (tx.time <= float(tx.time[first]) + _CLOCK_FIT_SECONDS))
    return start_at(tx, first, window)


def start_at(tx: UnitTransmissions, row: int, window: np.ndarray) -> UnitStart:
    """The filter start at the fix of transmission ``row``, its clock rate fitted on ``window``.

    The transmit-time rate is the median slope of the offsets of the fixes ``window`` (rows
    of ``tx`` with a fix, in time order); 0 with a large uncertainty with fewer than two.
    """
    assert tx.fix_p_world_tag is not None and tx.fix_clock is not None
    assert tx.fix_cov is not None
    rate, rate_sigma = 0.0, 1.0e4
    if window.size >= 2:
        slopes = np.diff(tx.fix_clock[window]) / np.diff(tx.time[window])
        rate = float(np.median(slopes))
        spread = float(np.median(np.abs(slopes - rate))) * 1.4826
        rate_sigma = max(1.0, 3.0 * spread / np.sqrt(window.size - 1))
    cov = np.asarray(tx.fix_cov[row], dtype=float)
    clock_sigma = max(0.05, 3.0 * float(np.sqrt(max(cov[3, 3], 0.0))))
    return UnitStart(float(tx.time[row]), tx.fix_p_world_tag[row], cov[:3, :3],
                     float(tx.fix_clock[row]), rate, clock_sigma, rate_sigma)


def _empty_track(time: np.ndarray, tx: UnitTransmissions, m: int) -> UnitTrack:
    n, t_count = time.shape[0], len(tx)
    heard = np.isfinite(tx.toa)
    totals = UwbTotals(int(heard.any(axis=1).sum()), 0, int(heard.sum()), 0, 0, 0,
                       float(time[-1] - time[0]) if n else 0.0)
    none = np.zeros((t_count, m), dtype=bool)
    return UnitTrack(time, np.full((n, 3), np.nan), np.full((n, 3, 3), np.nan),
                     np.full((n, 4), np.nan), tx.time, tx.seq, none, none.copy(), heard,
                     np.zeros(t_count, dtype=bool), totals)
