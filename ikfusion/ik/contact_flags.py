"""The per-frame contact flags of a :class:`.pose.Pose`, worked out once per pattern of bits."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class ContactFlags:
    """Contact point name -> standing on the floor, from the contact task's bits.

    A point stands when it is held (``active``) and not held horizontally only (``free_z``:
    a rising heel). The few patterns a recording takes are kept (a frame's dict is a copy of
    its pattern's, so a caller may change it).

    Args:
        names: The contact points' names, in the task's order.
        kept: How many patterns to keep before starting over (a bound on memory).
    """

    def __init__(self, names: Sequence[str], kept: int = 256) -> None:
        self.names = list(names)
        self.kept = kept
        self._patterns: dict[bytes, dict[str, bool]] = {}

    def __call__(self, active: np.ndarray, free_z: np.ndarray) -> dict[str, bool]:
        """``{name: active and not free_z}`` (k,) bool arrays -> a new dict."""
        key = active.tobytes() + free_z.tobytes()
        flags = self._patterns.get(key)
        if flags is None:
            if len(self._patterns) >= self.kept:
                self._patterns.clear()
            flags = self._patterns[key] = {
                name: on and not free
                for name, on, free in zip(self.names, active.tolist(), free_z.tolist())}
        return flags.copy()
