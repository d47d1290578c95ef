"""What a calibration returns: options, the result with its covariances, and its error type."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .constellation import Constellation, save_constellation


class CalibrationError(InputError):
    """A calibration log that cannot give a calibration; the message says what to do.

    Attributes:
        readers: Ids of the readers at fault, when the problem is specific to some.
    """

    def __init__(
        self,
        message: str,
        path: str | Path | None = None,
        field: str | None = None,
        readers: Sequence[str] = (),
    ) -> None:
        super().__init__(message, path=path, field=field)
        self.readers = tuple(readers)


@dataclass(frozen=True)
class CalibrationOptions:
    """Settings of :func:`~ikfusion.uwb.calibration.calibrate`.

    Attributes:
        sigma: Range noise [m] for the covariance; None estimates it a posteriori from the kept
            residuals, ``sqrt(sum r^2 / (n - p))``.
        origin: Reader put at the origin (default: the first reader of the heights).
        axis: Reader put on the +x axis (default: the second).
        threshold: Receptions later than this many robust sigmas are rejected as NLOS.
        early_threshold: Receptions earlier than this many robust sigmas are rejected.
        max_rounds: Largest number of rejection rounds (each one an IPOPT solve).
        min_wand_receptions: Wand receptions every reader needs.
        min_wand_transmissions: Wand transmissions heard by 5 readers or more the log needs.
        height_sigma: Uncertainty of the given reader heights [m], written as the z variance of
            each reader's covariance.
        warn_sigma: Predicted horizontal reader error above which a warning names the reader
            [m].
        max_sigma: Predicted horizontal reader error at the start above which the calibration
            is refused as undetermined, naming the readers [m].
        max_iterations: IPOPT iterations per solve.
        tolerance: IPOPT tolerance.
        seed: Seed of the random starts of the first estimate.
        coverage: Coverage radius written as the output's ``range`` [m] (None: not written).
        reader_links: Also use the reader-to-reader transmissions in the joint problem (they
            always give the first estimate). Right when the calibration tags sit at the reader
            antennas; a tag a few centimetres from its reader's antenna biases them.
    """

    sigma: float | None = None
    origin: str | None = None
    axis: str | None = None
    threshold: float = 4.0
    early_threshold: float = 6.0
    max_rounds: int = 10
    min_wand_receptions: int = 30
    min_wand_transmissions: int = 30
    height_sigma: float = 0.0
    warn_sigma: float = 0.10
    max_sigma: float = 0.5
    max_iterations: int = 200
    tolerance: float = 1e-8
    seed: int = 0
    coverage: float | None = None
    reader_links: bool = True


@dataclass(frozen=True)
class OutlierReport:
    """Receptions rejected as NLOS or gross errors at the solution.

    Attributes:
        receptions: Receptions in the joint problem.
        rejected: Of those, rejected.
        wand_receptions: Wand receptions in the problem.
        wand_rejected: Wand receptions rejected.
        per_reader: Rejected fraction of each reader's receptions, shape (M,).
        unused: Receptions left out of the problem (own-tag receptions, transmissions heard by
            too few readers or without a first fix).
    """

    receptions: int
    rejected: int
    wand_receptions: int
    wand_rejected: int
    per_reader: np.ndarray
    unused: int

    @property
    def fraction(self) -> float:
        """Rejected fraction of the receptions in the problem."""
        return self.rejected / max(self.receptions, 1)


@dataclass(frozen=True)
class UwbCalibration:
    """The result of :func:`~ikfusion.uwb.calibration.calibrate`.

    Attributes:
        constellation: Calibrated readers in the output frame: positions [m], clock offsets [m]
            (the origin reader's is 0), ``position_covariance`` (3x3 [m^2]) per reader, the
            range ``sigma``; save it with :meth:`save`.
        initial: The first estimate (reader-to-reader table, wand fixes), same frame.
        position_covariance: Joint covariance of the horizontal reader positions after the
            rigid alignment of ``frame``, shape (2M, 2M) [m^2], interleaved ``x1, y1, x2, ...``.
        clock_covariance: Covariance of the clock offsets with their common part removed, shape
            (M, M) [m^2].
        wand_time: Reception time of each solved wand transmission, shape (W,) [s].
        p_world_wand: Its position in the output frame, shape (W, 3) [m].
        sigma: Range sigma used for the covariance [m] (given, or a posteriori).
        residual_rms: RMS of the kept residuals [m].
        outliers: The rejection report.
        rounds: Rejection rounds (IPOPT solves).
        iterations: IPOPT iterations over all rounds.
        frame: How the output frame is defined.
        survey_rms: RMS horizontal misfit of the surveyed readers [m] (None without survey).
        timings: Seconds per step (``first_estimate``, ``build``, ``solve``, ``covariance``,
            ``total``).
        warnings: Things the user should know (poorly determined readers, ...).
    """

    constellation: Constellation
    initial: Constellation
    position_covariance: np.ndarray
    clock_covariance: np.ndarray
    wand_time: np.ndarray
    p_world_wand: np.ndarray
    sigma: float
    residual_rms: float
    outliers: OutlierReport
    rounds: int
    iterations: int
    frame: str
    survey_rms: float | None
    timings: Mapping[str, float]
    warnings: tuple[str, ...] = ()

    @property
    def ids(self) -> tuple[str, ...]:
        """Reader ids in order."""
        return self.constellation.ids

    @property
    def horizontal_sigma(self) -> np.ndarray:
        """Predicted horizontal error per reader ``sqrt(var x + var y)``, shape (M,) [m]."""
        var = np.diagonal(self.position_covariance)
        return np.sqrt(np.maximum(var[0::2] + var[1::2], 0.0))

    @property
    def clock_sigma(self) -> np.ndarray:
        """Predicted clock-offset error per reader (common part removed), shape (M,) [m]."""
        return np.sqrt(np.maximum(np.diagonal(self.clock_covariance), 0.0))

    @property
    def predicted_rms(self) -> float:
        """Predicted RMS horizontal reader error after the alignment [m]."""
        return float(np.sqrt(np.mean(self.horizontal_sigma**2)))

    @property
    def joint_covariance(self) -> np.ndarray:
        """Joint covariance of the reader positions, shape (3M, 3M) [m^2].

        Order ``x1, y1, z1, x2, ...``; heights uncorrelated, with the ``height_sigma``
        variance. :func:`~ikfusion.uwb.dop.compute_dop` takes it as ``reader_covariances``.
        """
        m = len(self.ids)
        out = np.zeros((3 * m, 3 * m))
        xy = np.flatnonzero(np.arange(3 * m) % 3 != 2)
        out[np.ix_(xy, xy)] = self.position_covariance
        for j, reader in enumerate(self.constellation.readers):
            if reader.position_covariance is not None:
                out[3 * j + 2, 3 * j + 2] = reader.position_covariance[2, 2]
        return out

    @property
    def predicted_clock_rms(self) -> float:
        """Predicted RMS clock-offset error, common part removed [m]."""
        return float(np.sqrt(np.mean(self.clock_sigma**2)))

    def summary(self) -> dict[str, Any]:
        """Plain mapping of the figures (for JSON and the output file's metadata)."""
        o = self.outliers
        return {
            "readers": len(self.ids),
            "frame": self.frame,
            "sigma_m": round(self.sigma, 5),
            "residual_rms_m": round(self.residual_rms, 5),
            "outlier_fraction": round(o.fraction, 5),
            "outliers": {
                "receptions": o.receptions,
                "rejected": o.rejected,
                "wand_receptions": o.wand_receptions,
                "wand_rejected": o.wand_rejected,
                "unused_receptions": o.unused,
                "per_reader": {rid: round(float(f), 5) for rid, f in zip(self.ids, o.per_reader)},
            },
            "wand_transmissions": int(self.wand_time.shape[0]),
            "predicted_horizontal_sigma_m": {
                rid: round(float(s), 5) for rid, s in zip(self.ids, self.horizontal_sigma)
            },
            "predicted_rms_m": round(self.predicted_rms, 5),
            "clock_offset_sigma_m": {
                rid: round(float(s), 5) for rid, s in zip(self.ids, self.clock_sigma)
            },
            "survey_rms_m": None if self.survey_rms is None else round(self.survey_rms, 5),
            "rounds": self.rounds,
            "iterations": self.iterations,
            "timings_s": {k: round(v, 3) for k, v in self.timings.items()},
            "warnings": list(self.warnings),
        }

    def save(self, path: str | Path) -> Path:
        """Write the readers YAML (the format :func:`load_constellation` reads), atomically.

        The calibration figures go under ``metadata: {calibration: ...}``.
        """
        meta = dict(self.constellation.metadata)
        meta["calibration"] = self.summary()
        return save_constellation(replace(self.constellation, metadata=meta), path)
