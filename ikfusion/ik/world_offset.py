"""Where the drift correction has put the solved body in the world: the only thing it touches.

Inertial tracking places the body by chaining contacts, and drifts. A drift correction
(:mod:`ikfusion.app.correction`) moves it toward absolute positions in four ways, all through a
:class:`WorldOffset`:

* :meth:`~WorldOffset.translate`: the whole solved state moves (body, anchors, contact history),
  e.g. to the first absolute fix;
* :meth:`~WorldOffset.slide`: every planted point moves, and the body with it (feet slide);
* :meth:`~WorldOffset.lead_steps`: planted points stay; swing feet are led toward the offset
  and the pelvis follows them (:class:`.support.SupportFollower`);
* :meth:`~WorldOffset.turn`: every orientation target turns about the vertical.

Moves of the solved state are applied by the solver at the start of its next frame
(:meth:`~WorldOffset.take_moves`), so the correction never reaches into the solver's state.
"""

from __future__ import annotations

import numpy as np

from ..rotations import axis_rotation
from .support import SupportFollower


class WorldOffset:
    """The drift correction's moves and turn of the solved body (see the module docstring).

    Args:
        support: The solver's support follower (it leads swing feet, the pelvis follows).
    """

    def __init__(self, support: SupportFollower) -> None:
        self._support = support
        self.reset()

    def reset(self) -> None:
        """No move and no turn."""
        self.heading = 0.0
        self.R_heading: np.ndarray | None = None
        self._moves: list[tuple[str, np.ndarray]] = []

    def translate(self, delta: np.ndarray) -> None:
        """Move the whole solved state by ``delta`` (3,) [m], horizontal part only.

        Body, anchors and contact history move together, e.g. to place the body where the first
        absolute fix says.
        """
        d = _horizontal(delta)
        self._support.shift(d)
        self._moves.append(("all", d))

    def slide(self, delta: np.ndarray) -> None:
        """Move every planted point by ``delta`` (3,) [m], horizontal part only.

        The body follows its feet, which slide: the ``slide`` correction of a drifting position.
        """
        d = _horizontal(delta)
        self._support.shift(d)
        self._moves.append(("planted", d))

    def lead_steps(self, offset: np.ndarray, max_step: float) -> None:
        """Lead feet that lift off from now on toward the correction ``offset`` (3,) [m].

        Horizontal part only; each step takes at most ``max_step`` [m] of it. Planted points
        never move: each swing foot is led gradually to its offset and the pelvis follows it
        after touch-down, so the body walks into place: the ``no-slide`` correction.
        """
        self._support.set_step(offset, max_step)

    def turn(self, yaw: float) -> None:
        """Turn every orientation target by ``yaw`` [rad] more about the vertical, from now on.

        The heading correction of sensors whose heading drifted (a magnetically disturbed
        hall): the body turns with its targets, the position correction takes it from there.
        """
        self.heading += float(yaw)
        self.R_heading = axis_rotation("z", self.heading)

    @property
    def shifted(self) -> np.ndarray:
        """How far the position corrections have moved the body so far (3,) [m]."""
        return self._support.displacement

    def take_moves(self) -> list[tuple[str, np.ndarray]]:
        """The moves since the last call, in order: (``"all"`` or ``"planted"``, (3,) [m])."""
        moves, self._moves = self._moves, []
        return moves


def _horizontal(delta: np.ndarray) -> np.ndarray:
    return np.array([float(delta[0]), float(delta[1]), 0.0])
