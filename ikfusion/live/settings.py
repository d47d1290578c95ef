"""Thresholds of the live pipeline, from ``configs/live.yaml``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..paths import shipped_config
from ..settings_files import Overlay, load_settings
from ..yaml_files import read_yaml_document


@dataclass(frozen=True)
class LiveSettings:
    """How samples become frames and how often a recording is flushed.

    Attributes:
        calibration_s: The first this many seconds are buffered and calibrated on [s].
        deadline_periods: A frame is complete when every sensor is in or this many sample
            periods passed (in capture time, or live in wall time) [periods].
        clock_jump_s: A sensor this far from the stream's newest frame has jumped [s].
        max_lag_s: Live, a frame released (complete or due) longer ago than this when its
            turn comes is dropped (the solver fell behind) [s].
        flush_s: ``--record`` flushes its rows this often [s].
        view_rate_hz: ``--view`` sends batches of frames at most this often per second of
            capture time [Hz] (every frame is sent).
    """

    calibration_s: float
    deadline_periods: float
    clock_jump_s: float
    max_lag_s: float
    flush_s: float
    view_rate_hz: float

    @classmethod
    def load(cls, path: str | Path | None = None, **overrides: Any) -> LiveSettings:
        """The shipped ``configs/live.yaml``, overlaid by a user file; keywords win.

        Raises:
            ConfigError: An unknown key, a key in the wrong section or a value of the wrong
                type, naming the file, the line and the key.
        """
        overlays = [] if path is None else [Overlay(read_yaml_document(path, "live settings"))]
        return load_settings(cls, shipped_config("live.yaml"), "live settings", overlays,
                             overrides)
