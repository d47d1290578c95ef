"""Rauch-Tung-Striebel smoothing of the error-state filter, for recordings processed offline.

The filter (:mod:`ikfusion.uwb.ekf`) estimates each instant from the past only. A recording is
processed after the fact, so every instant can also use what came later: when readers are
blocked, the position across the few readers still heard comes from the IMU alone and drifts;
the transmissions after the blockage pin the end of that stretch, and the backward pass carries
that information back through the IMU's own dynamics (the "HD reprocessing" of commercial suits).

The forward pass logs, for every propagation step ``j``, the state and covariance before it
(after the updates at its start), its error-state transition ``F_j`` and process noise ``Q_j``,
and the predicted state after it. Backward, with ``P_pred = F P F^T + Q``::

    C_j = P_j F_j^T P_pred^-1
    x_s,j = x_j (+) C_j (x_s,j+1 (-) x_pred,j)
    P_s,j = P_j + C_j (P_s,j+1 - P_pred,j) C_j^T

where (+) and (-) are :func:`~ikfusion.uwb.ekf_model.inject_error` and
:func:`~ikfusion.uwb.ekf_model.state_difference` (attitude on the right, in the sensor frame).
A reset of the filter (the gate re-opened on a fix) is carried back like any update, spread
over the steps before it in proportion to how uncertain they were.
"""

from __future__ import annotations

import numpy as np

from .ekf_model import (
    NominalState,
    fill_transition,
    inject_error,
    new_transition,
    state_difference,
)

#: What rebuilds a step's transition: mid-step rotation, bias-free specific force and rate, dt.
Motion = tuple[np.ndarray, np.ndarray, np.ndarray, float]


class SmootherLog:
    """What the forward pass keeps for the backward pass (one entry per propagation step).

    About 2.6 kB per step (the covariance and two states); the transitions are rebuilt.
    """

    def __init__(self) -> None:
        self._x: list[NominalState] = []
        self._P: list[np.ndarray] = []
        self._motion: list[Motion] = []
        self._q: list[np.ndarray] = []
        self._x_pred: list[NominalState] = []

    def __len__(self) -> int:
        return len(self._x)

    def propagated(self, x_before: NominalState, P_before: np.ndarray, motion: Motion,
                   q_diag: np.ndarray, x_pred: NominalState) -> None:
        """Log one step.

        Args:
            x_before: State before the step (after the updates at its start).
            P_before: Its covariance.
            motion: What rebuilds the step's transition (see :data:`Motion`).
            q_diag: Process noise added over the step (diagonal).
            x_pred: State after the step, before any update.
        """
        self._x.append(x_before)
        self._P.append(P_before)
        self._motion.append(motion)
        self._q.append(q_diag)
        self._x_pred.append(x_pred)

    def smooth(self, x_last: NominalState, P_last: np.ndarray
               ) -> list[tuple[NominalState, np.ndarray]]:
        """Smoothed (state, covariance) at the start of every step, and last the final one.

        Args:
            x_last: The filter's final state (after the last step and its updates).
            P_last: Its covariance.
        """
        n = len(self._x)
        out: list[tuple[NominalState, np.ndarray]] = [(x_last, P_last)] * (n + 1)
        x_s, P_s = x_last, P_last
        F = new_transition()
        for j in range(n - 1, -1, -1):
            P = self._P[j]
            fill_transition(F, *self._motion[j])
            FP = F @ P
            P_pred = FP @ F.T
            P_pred[np.diag_indices_from(P_pred)] += self._q[j]
            try:
                C = np.linalg.solve(P_pred, FP).T
            except np.linalg.LinAlgError:
                C = np.linalg.lstsq(P_pred, FP, rcond=None)[0].T
            x = self._x[j].copy()
            inject_error(x, C @ state_difference(x_s, self._x_pred[j]))
            P_s = P + C @ (P_s - P_pred) @ C.T
            P_s = 0.5 * (P_s + P_s.T)
            x_s = x
            out[j] = (x_s, P_s)
        return out
