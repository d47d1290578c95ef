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
        latency_budget_s: Live, when the solver fell behind: a frame waiting behind a newer one
            is solved only if its pose can still leave this soon after its first sample
            arrived, else dropped (the newest frame waiting is always solved) [s].
        flush_s: ``--record`` flushes its rows this often [s].
        view_rate_hz: ``--view`` sends batches of frames at most this often per second of
            capture time [Hz] (every frame is sent).
    """

    calibration_s: float
    deadline_periods: float
    clock_jump_s: float
    latency_budget_s: float
    flush_s: float
    view_rate_hz: float

    shipped_file = "live.yaml"
    what = "live settings"
