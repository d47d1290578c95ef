"""The stride loss: the solved pelvis's travel from foot strike to foot strike against the truth's.

Closed forms: a solve whose horizontal track is the true one scaled by ``k`` about any point
travels ``k`` times as far in every step, wherever the steps point and however the pelvis sways,
so it falls short by exactly ``100 (1 - k)`` %; a solve shifted by a constant loses nothing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import evaluate
from ikfusion.app.stride_loss import foot_strikes, steps, stride_loss_percent
from ikfusion.ik import Motion
from ikfusion.model import HumanModel
from ikfusion.results import write_result_folder
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import write_truth

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]


def _alternating_contacts(time: np.ndarray, step_s: float) -> np.ndarray:
    """(N, 4) feet that swing in turn: each foot off for the first 40 % of its own cycle of
    ``2 step_s``, the right foot half a cycle after the left; the toe lands a frame after the
    heel."""
    contacts = np.zeros((len(time), 4), dtype=bool)
    for side, offset in ((0, 0.0), (2, step_s)):
        phase = ((time - offset) % (2 * step_s)) / (2 * step_s)
        contacts[:, side] = phase >= 0.4
        contacts[1:, side + 1] = contacts[:-1, side]
    return contacts


def test_strikes_are_the_feet_touching_down_after_a_swing() -> None:
    """One strike per foot landing (heel and toe of a foot count once), none for a foot that
    lets go for a single frame."""
    time = np.arange(0.0, 6.0, 0.01)
    contacts = _alternating_contacts(time, 0.5)
    strikes = foot_strikes(time, contacts, NAMES)
    np.testing.assert_allclose(np.diff(time[strikes]), 0.5, atol=0.011)
    assert len(strikes) == 12  # the left foot off from the start lands at 0.4 s: a strike
    flicker = contacts.copy()
    flicker[250, :] = False  # both feet let go for one frame (10 ms)
    assert foot_strikes(time, flicker, NAMES) == strikes


@pytest.mark.parametrize("k", [0.97, 1.0, 1.02])
def test_a_scaled_track_falls_short_by_the_scale(k: float) -> None:
    """A curved walk with sway, solved as the true track scaled by ``k`` about a point off the
    path: ``100 (1 - k)`` % short; shifted instead: 0 %."""
    time = np.arange(0.0, 8.0, 0.01)
    a = 0.4 * time  # a 2.5 m circle walked at 1 m/s
    p_true = np.stack([2.5 * np.sin(a) + 0.03 * np.sin(2 * np.pi * time),
                       2.5 * (1 - np.cos(a)), np.full_like(time, 0.9)], axis=1)
    strikes = foot_strikes(time, _alternating_contacts(time, 0.55), NAMES)
    centre = np.array([1.0, -2.0, 0.0])
    scaled = steps(centre + k * (p_true - centre), p_true, strikes)
    assert stride_loss_percent(scaled) == pytest.approx(100.0 * (1.0 - k), abs=1e-9)
    shifted = steps(p_true + [0.3, -0.2, 0.0], p_true, strikes)
    assert stride_loss_percent(shifted) == pytest.approx(0.0, abs=1e-9)


def test_too_few_steps_or_too_little_travel_give_no_figure() -> None:
    time = np.arange(0.0, 8.0, 0.01)
    p_true = np.stack([time, np.zeros_like(time), np.ones_like(time)], axis=1)
    contacts = _alternating_contacts(time, 0.55)
    few = steps(p_true, p_true, foot_strikes(time, contacts, NAMES)[:4])  # 3 steps
    assert stride_loss_percent(few) is None
    still = steps(0.01 * p_true, 0.01 * p_true, foot_strikes(time, contacts, NAMES))
    assert stride_loss_percent(still) is None


@pytest.fixture(scope="module")
def walk():
    """A 5 s straight walk of the generator (2.5 m after a 0.5 s stand, 7 steps)."""
    return generate_gait(HumanModel.default(), GaitParameters(duration=5.0, stand=0.5),
                         rate=60.0)


def test_evaluate_reports_the_stride_loss_of_a_scaled_walk(walk, tmp_path: Path) -> None:
    """The generator's walk solved with its pelvis's horizontal track scaled by 0.97 (the rest of
    the body following it): 3 % short; the truth itself: 0 %."""
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    n = len(walk.time)

    def result(q: np.ndarray, name: str) -> Path:
        motion = Motion(walk.model, walk.time, q, walk.contact_names, walk.contacts,
                        np.zeros(n), np.ones(n, dtype=int), np.zeros(n, dtype=bool))
        return write_result_folder(motion, tmp_path / name)

    exact = evaluate(result(walk.q, "exact"), truth_file).stride_loss_percent
    assert exact == pytest.approx(0.0, abs=0.01)
    q = walk.q.copy()
    q[:, :2] *= 0.97
    assert evaluate(result(q, "short"), truth_file).stride_loss_percent == pytest.approx(
        3.0, abs=0.01)
