"""The time-of-arrival model shared by the solver, the simulator and the tests.

All quantities are metres (times multiplied by the speed of light)::

    toa_m = tau + ||p_world_reader_m - p_world_tag|| + clock_offset_m + nlos_m + e_m

``tau`` is the transmit time on the common timeline, ``clock_offset_m`` the offset of reader m's
clock, ``nlos_m >= 0`` the extra path of a non-line-of-sight reception and ``e_m`` the noise.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .constellation import Constellation


def predict_toa(
    p_world_tag: npt.ArrayLike, tau: npt.ArrayLike, constellation: Constellation
) -> np.ndarray:
    """Line-of-sight, noise-free times of arrival.

    Args:
        p_world_tag: Tag positions, shape (T, 3) [m].
        tau: Transmit times, shape (T,) [m].
        constellation: The readers.

    Returns:
        Times of arrival, shape (T, M) [m].
    """
    p = np.atleast_2d(np.asarray(p_world_tag, dtype=float))
    t = np.broadcast_to(np.asarray(tau, dtype=float), (p.shape[0],))
    dist = np.linalg.norm(constellation.positions[None, :, :] - p[:, None, :], axis=2)
    return t[:, None] + dist + constellation.clock_offsets[None, :]


def toa_residuals(
    toa: npt.ArrayLike,
    p_world_tag: npt.ArrayLike,
    tau: npt.ArrayLike,
    constellation: Constellation,
) -> np.ndarray:
    """Measured minus predicted times of arrival (positive = late, as NLOS makes them).

    Args:
        toa: Measured times of arrival, shape (T, M) [m], NaN where missing.
        p_world_tag: Tag positions, shape (T, 3) [m].
        tau: Transmit times, shape (T,) [m].
        constellation: The readers.

    Returns:
        Residuals, shape (T, M) [m]; NaN where the measurement or the fix is missing.
    """
    return np.asarray(toa, dtype=float) - predict_toa(p_world_tag, tau, constellation)
