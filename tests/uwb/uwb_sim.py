"""A small, independent TOA generator for the UWB tests (written from SPEC section 4).

toa = tau + ||p_reader - p_tag|| + clock_offset + nlos + noise, all in metres.
"""

from __future__ import annotations

import numpy as np


def toa_matrix(
    readers: np.ndarray,
    offsets: np.ndarray,
    p_tag: np.ndarray,
    rng: np.random.Generator,
    *,
    sigma: float,
    tau: np.ndarray | None = None,
    nlos_fraction: float = 0.0,
    nlos_range: tuple[float, float] = (0.2, 2.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times of arrival (T, M), the NLOS delays (T, M) and the transmit times (T,)."""
    p_tag = np.atleast_2d(p_tag)
    t_count, m_count = p_tag.shape[0], readers.shape[0]
    if tau is None:
        tau = rng.uniform(-50.0, 5.0e4, t_count)
    toa = np.empty((t_count, m_count))
    for m in range(m_count):
        dist = np.sqrt(np.sum((readers[m] - p_tag) ** 2, axis=1))
        toa[:, m] = tau + dist + offsets[m]
    toa += rng.normal(0.0, sigma, toa.shape)
    delayed = rng.random(toa.shape) < nlos_fraction
    delay = np.where(delayed, rng.uniform(*nlos_range, toa.shape), 0.0)
    return toa + delay, delay, tau


def closed_form_dop(
    point: np.ndarray, readers: np.ndarray, *, dims: int, clock: bool, coverage: float | None
) -> np.ndarray | None:
    """(H^T H)^-1 at one point, H = [unit line of sight, 1], readers in coverage only."""
    rows = []
    for r in readers:
        d = point - r
        n = float(np.sqrt(d @ d))
        if coverage is not None and n > coverage:
            continue
        u = d / n
        rows.append(list(u[:dims]) + ([1.0] if clock else []))
    if len(rows) < dims + int(clock):
        return None
    h = np.array(rows)
    return np.linalg.inv(h.T @ h)
