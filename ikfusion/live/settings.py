"""Thresholds of the live pipeline, from ``configs/live.yaml``."""

from __future__ import annotations

from dataclasses import dataclass

from ..settings_files import ShippedSettings


@dataclass(frozen=True)
class LiveSettings(ShippedSettings):
    """How samples become frames and how often a recording is flushed.

    Attributes:
        calibration_s: The first this many seconds are buffered and calibrated on [s].
        deadline_periods: A frame is complete when every sensor is in or this many sample
            periods passed (in capture time, or live in wall time) [periods].
        clock_jump_s: A sensor this far from the stream's newest frame has jumped [s].
        max_lag_s: Live, a frame released (complete or due) longer ago than this when its
            turn comes is dropped (the solver fell behind) [s].
        flush_s: ``--record`` flushes its rows this often [s].
    """

    calibration_s: float
    deadline_periods: float
    clock_jump_s: float
    max_lag_s: float
    flush_s: float

    shipped_file = "live.yaml"
    what = "live settings"
