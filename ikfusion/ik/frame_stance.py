"""A frame's IMU stance evidence for the contact points, as arrays and bits, once per pattern.

``Frame.feet_still`` (segment -> stands still by its IMU) and ``Frame.points_moving`` (point ->
moves by its foot IMU) change at steps only: a walk meets a few dozen patterns. Per contact
point they become read-only (k,) arrays (1 yes, 0 no, NaN unknown) and, for the stance, the
bits (:mod:`.point_bits`) of the points whose foot stands still and of those whose foot moves;
:class:`FrameStance` keeps them per pattern so that a frame pays a dictionary look-up, and the
usual frame, whose stance equals the last frame's, one comparison of two small dicts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .frame import Frame
from .point_bits import PointBits
from .point_evidence import stance_bits

_PATTERNS = 4096  # at most this many patterns are kept per table (a few dozen in practice)
_Key = tuple[tuple[str, bool], ...]


class FrameStance:
    """The stance evidence of frames for contact points (see the module docstring).

    Args:
        names: The contact point names.
        foot_names: The segment whose IMU stance each point follows (None: none).
        bits: The points' :class:`PointBits`.
    """

    def __init__(self, names: Sequence[str], foot_names: Sequence[str | None],
                 bits: PointBits) -> None:
        self.names = list(names)
        self._foot_names = list(foot_names)
        self._bits = bits
        self._still_of: dict[_Key, tuple[np.ndarray, tuple[int, int]]] = {}
        self._moving_of: dict[_Key, np.ndarray] = {}
        # the last frame's stance and answer (a copy: the usual frame's is equal, a look-up less)
        self._last_still: tuple[dict[str, bool], tuple[np.ndarray, tuple[int, int]] | None] = (
            {}, None)
        self._last_moving: tuple[dict[str, bool], np.ndarray | None] = ({}, None)

    def feet_still(self, frame: Frame) -> tuple[np.ndarray | None, tuple[int, int]]:
        """Per point, 1 its foot stands still by its IMU, 0 moves, NaN unknown; and as bits.

        The (k,) read-only array (None without ``frame.feet_still``) and the bits of the
        points whose foot stands still and of those whose foot moves
        (:func:`.point_evidence.stance_bits`).
        """
        known = frame.feet_still
        if not known:
            return None, (0, 0)
        last, answer = self._last_still
        if answer is not None and known == last:  # (equal values: the same floats and bits)
            return answer
        key = tuple(known.items())
        kept = self._still_of.get(key)
        if kept is None:
            nan = math.nan
            still = np.array([nan if f is None or (s := known.get(f)) is None else float(s)
                              for f in self._foot_names])
            still.setflags(write=False)
            kept = (still, stance_bits(self._bits, still))
            if len(self._still_of) < _PATTERNS:
                self._still_of[key] = kept
        self._last_still = (dict(known), kept)
        return kept

    def points_moving(self, frame: Frame) -> np.ndarray | None:
        """Per point: 1 moves by its foot's IMU (``frame.points_moving``), 0 not, NaN unknown.

        Read-only (None without ``frame.points_moving``).
        """
        known = frame.points_moving
        if not known:
            return None
        last, answer = self._last_moving
        if answer is not None and known == last:
            return answer
        key = tuple(known.items())
        moving = self._moving_of.get(key)
        if moving is None:
            moving = np.array([float(known[n]) if n in known else np.nan for n in self.names])
            moving.setflags(write=False)
            if len(self._moving_of) < _PATTERNS:
                self._moving_of[key] = moving
        self._last_moving = (dict(known), moving)
        return moving
