"""Targets and information of the heels of swing feet led by the ``no-slide`` correction.

The lead (:class:`.support.SupportFollower`) moves a swing foot's heels by its swing offset
(3,) [m]. Their information is 1 on the horizontal axes; on the vertical axis it is 1 while the
foot's targets are on or above the floor and falls to 0 as the lowest of them sinks
``UNDER_FLOOR_BAND`` under it (the floor, not the lead, sets that foot's height), and as the heel
left the floor up to ``UNDER_FLOOR_BAND`` away from its sensed height (the sensed leg's height is
not to be trusted then: the foot's *height trust*). Every other point has none.

Why the heel is held at the height of the sensed leg: a heel free in height drifts up with the
pelvis (nothing else holds it there while the body stands on one toe), lands high and lifts the
body at each heel strike. Why the height is let go where the sensed leg puts the foot under the
floor: the floor lifts that foot, and a heel held at its sensed height while the floor lifts the
toe pitches the foot about the ankle, which springs back when the toe rises (a pop). Why it is
let go for the whole swing when the heel left the floor away from the sensed leg's height (by
``UNDER_FLOOR_BAND`` or more): a sensed leg that disagreed with the floor in height would pull
the body up after lift-off and down before landing (a run's legs, with feet the sensors put
centimetres under the floor).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

_HORIZONTAL = np.diag([1.0, 1.0, 0.0])  # information of a lead on the x and y axes
_VERTICAL = np.diag([0.0, 0.0, 1.0])  # ... and on the z axis
#: (points, lag or None, lean, offset or None) of :class:`LedBase`
_Led = tuple[np.ndarray, tuple[float, ...] | None, tuple[float, ...], np.ndarray | None]
UNDER_FLOOR_BAND = 0.01  # [m] the lead lets a heel's height go as its foot sinks this far
# under the floor, or as the heel lifts off this far from the sensed leg's height


def lead_targets(p_points: np.ndarray, led: Sequence[tuple[np.ndarray, tuple[float, ...], float]],
                 heels: np.ndarray, floor_z: float) -> tuple[np.ndarray, np.ndarray]:
    """Targets (k, 3) [m] and information (k, 3, 3) of the led feet (see the module docstring).

    Args:
        p_points: (k, 3) contact points of the warm start [m].
        led: Per led foot: its points (k,) (a mask), its swing offset (3,) [m] and height trust.
        heels: (k,) the points a foot is led by (on the foot itself, not on its toes).
        floor_z: Height of the floor [m] (world z).
    """
    targets = p_points.copy()
    info = np.zeros((len(p_points), 3, 3))
    for points, swing, trust in led:
        targets[points] += swing
        sunk = floor_z - float(targets[points, 2].min())
        height = min(band_share(-sunk), trust)
        info[points & heels] = _HORIZONTAL + height * _VERTICAL
    return targets, info


def band_share(height: float) -> float:
    """1 at or above 0, falling to 0 at ``-UNDER_FLOOR_BAND`` [m] and below."""
    return min(max(1.0 + height / UNDER_FLOOR_BAND, 0.0), 1.0)


class LedBase:
    """Where the contact points were led in the last solved frame, and how far it put them off.

    The deviation (solved less led, (k, 3) [m]) is read only when a foot lifts off (its heel
    leaves the floor where it is, :class:`.support.SupportFollower`), a few times a walk: the
    led points ``points + lag + lean`` are kept as their terms and added up then (the same
    sums as when kept added up).

    Args:
        k: Number of contact points.
    """

    def __init__(self, k: int) -> None:
        self._k = k
        self._base: _Led | None = None
        self._recorded: tuple[np.ndarray, _Led] | None = None

    def keep(self, points: np.ndarray, lag: tuple[float, ...] | None = None,
             lean: tuple[float, ...] = (0.0, 0.0, 0.0), offset: np.ndarray | None = None) -> None:
        """This frame's points (k, 3) [m], led by ``lag`` then ``lean`` (3,) [m] (None: led).

        ``offset`` (3,) [m] moves the points first (None: none); no array is written to after.
        """
        self._base = (points, lag, lean, offset)

    def record(self, p_solved: np.ndarray) -> None:
        """After solving: the solved points (k, 3) [m] of the frame kept (none kept: no change)."""
        if self._base is not None:
            self._recorded, self._base = (p_solved, self._base), None

    def deviation(self) -> np.ndarray:
        """(k, 3) [m] the last recorded solved points less where they were led (zeros: none)."""
        if self._recorded is None:
            return np.zeros((self._k, 3))
        p_solved, (points, lag, lean, offset) = self._recorded
        if offset is not None:
            points = points + offset
        return p_solved - (points if lag is None else points + lag + lean)

