"""Simulated times of arrival, reusable by the capture simulator and by tests.

The model is :func:`ikfusion.uwb.toa_model.predict_toa` plus Gaussian noise, optional NLOS
delays (a fraction of receptions delayed by a uniform extra path) and optional missed
receptions; a reader farther than the constellation's coverage radius hears nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .constellation import Constellation
from .toa_model import predict_toa


@dataclass(frozen=True)
class SimulatedToa:
    """Simulated receptions of T transmissions by M readers.

    Attributes:
        toa: Times of arrival, shape (T, M) [m]; NaN where not received.
        nlos_delay: NLOS extra path added to each reception, shape (T, M) [m] (0 for LOS).
        tau: Transmit times used, shape (T,) [m].
    """

    toa: np.ndarray
    nlos_delay: np.ndarray
    tau: np.ndarray


def simulate_toa(
    p_world_tag: npt.ArrayLike,
    constellation: Constellation,
    rng: np.random.Generator,
    *,
    tau: npt.ArrayLike | None = None,
    sigma: float | None = None,
    nlos_fraction: float = 0.0,
    nlos_delay: tuple[float, float] = (0.2, 2.0),
    miss_probability: float = 0.0,
) -> SimulatedToa:
    """Times of arrival of transmissions from known tag positions.

    Args:
        p_world_tag: Tag positions at transmit time, shape (T, 3) [m].
        constellation: Readers (positions, clock offsets, coverage radius, default sigma).
        rng: Random generator (seed it for reproducible captures).
        tau: Transmit times, shape (T,) [m]; by default uniform over [0, 1000) m.
        sigma: Range noise [m]; the constellation's ``sigma`` by default.
        nlos_fraction: Probability that a reception is delayed by NLOS.
        nlos_delay: Range of the uniform NLOS extra path [m].
        miss_probability: Probability that a reader misses a transmission.

    Returns:
        The simulated receptions.
    """
    p = np.atleast_2d(np.asarray(p_world_tag, dtype=float))
    t_count = p.shape[0]
    m = len(constellation.readers)
    t = rng.uniform(0.0, 1000.0, t_count) if tau is None else np.asarray(tau, dtype=float)
    t = np.broadcast_to(t, (t_count,)).astype(float)
    s = constellation.sigma if sigma is None else float(sigma)
    toa = predict_toa(p, t, constellation) + rng.normal(0.0, s, (t_count, m))
    delayed = rng.random((t_count, m)) < nlos_fraction
    delay = np.where(delayed, rng.uniform(nlos_delay[0], nlos_delay[1], (t_count, m)), 0.0)
    toa = toa + delay
    heard = rng.random((t_count, m)) >= miss_probability
    if constellation.range is not None:
        dist = np.linalg.norm(constellation.positions[None] - p[:, None], axis=2)
        heard &= dist <= constellation.range
    toa = np.where(heard, toa, np.nan)
    return SimulatedToa(toa=toa, nlos_delay=np.where(heard, delay, 0.0), tau=t)
