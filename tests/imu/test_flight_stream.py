"""Flight sample by sample (live, ``solve --causal``) against the batch detector and the truth."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.imu.flight import detect_flight
from ikfusion.imu.flight_stream import FlightStream
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.model import HumanModel
from ikfusion.sim.gait import gait_preset, generate_gait
from ikfusion.sim.imu import ImuNoise, simulate_imus

RATE = 60.0
FEET = ("LeftFoot", "RightFoot")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


@pytest.fixture(scope="module", params=["jump", "hop", "skip"])
def bouncing(request: pytest.FixtureRequest) -> TruthMotion:
    return generate_gait(HumanModel.default(), gait_preset(request.param, 5.0, stand=1.0),
                         rate=RATE)


def _units(truth: TruthMotion, rng: np.random.Generator, lose: float
           ) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Noisy pelvis and feet units with a fraction ``lose`` of their samples lost (NaN)."""
    imus = simulate_imus(truth.model, truth.time, truth.q, ["Pelvis", *FEET], rng, ImuNoise())
    acc = {s: a.copy() for s, a in zip(imus.segments, imus.acc)}
    gyr = {s: g.copy() for s, g in zip(imus.segments, imus.gyr)}
    for segment in acc:
        lost = rng.random(len(truth.time)) < lose
        acc[segment][lost] = np.nan
        gyr[segment][lost] = np.nan
    return acc.pop("Pelvis"), acc, {f: gyr[f] for f in FEET}


def _streamed(acc_pelvis: np.ndarray, acc_feet: dict[str, np.ndarray],
              gyr_feet: dict[str, np.ndarray]) -> tuple[list[bool], list[bool], int]:
    """(lagged decisions, undelayed ``flying`` per sample, lag), samples fed one by one; a
    lost sample arrives as None, as from a live source."""
    def sample(values: np.ndarray, k: int) -> np.ndarray | None:
        return values[k] if np.isfinite(values[k]).all() else None

    stream = FlightStream(RATE)
    decided, flying = [], []
    for k in range(len(acc_pelvis)):
        d = stream.update(sample(acc_pelvis, k), {f: sample(a, k) for f, a in acc_feet.items()},
                          {f: sample(g, k) for f, g in gyr_feet.items()})
        if d is not None:
            decided.append(d[0])
        flying.append(stream.flying)
    decided += [a for a, _ in stream.flush()]
    return decided, flying, stream.lag


@pytest.mark.parametrize("lose", [0.0, 0.05])
def test_the_stream_decides_every_sample_as_the_batch_detector(
        bouncing: TruthMotion, rng: np.random.Generator, lose: float) -> None:
    acc_pelvis, acc_feet, gyr_feet = _units(bouncing, rng, lose)
    batch = detect_flight(RATE, acc_pelvis, acc_feet, gyr_feet).airborne
    assert batch.sum() > 20  # the motion flies
    decided, _, _ = _streamed(acc_pelvis, acc_feet, gyr_feet)
    np.testing.assert_array_equal(decided, batch)


def test_without_a_gyroscope_a_foot_never_rests(bouncing: TruthMotion,
                                                rng: np.random.Generator) -> None:
    acc_pelvis, acc_feet, gyr_feet = _units(bouncing, rng, 0.0)
    batch = detect_flight(RATE, acc_pelvis, acc_feet, {"LeftFoot": gyr_feet["LeftFoot"]})
    decided, _, _ = _streamed(acc_pelvis, acc_feet,
                              {"LeftFoot": gyr_feet["LeftFoot"],
                               "RightFoot": np.full_like(gyr_feet["RightFoot"], np.nan)})
    np.testing.assert_array_equal(decided, batch.airborne)


def test_the_undelayed_flight_is_the_decided_one_less_its_first_lag_samples(
        bouncing: TruthMotion, rng: np.random.Generator) -> None:
    """What a live frame uses at once: never airborne where the decision (and the truth, but
    for an edge sample) is not, airborne from at most ``lag`` samples into every decided
    flight to its very end."""
    acc_pelvis, acc_feet, gyr_feet = _units(bouncing, rng, 0.0)
    decided, flying_list, lag = _streamed(acc_pelvis, acc_feet, gyr_feet)
    airborne, flying = np.array(decided), np.array(flying_list)
    assert not (flying & ~airborne).any()
    flights = _runs(airborne)
    assert len(flights) >= 5
    for a, b in flights:
        assert flying[min(a + lag, b - 1):b].all(), (a, b)
    truth_air = ~bouncing.contacts.any(axis=1)
    wrong = flying & ~truth_air
    near_edge = np.zeros_like(wrong)
    for a, b in _runs(truth_air):
        near_edge[max(a - 1, 0):b + 1] = True
    assert not (wrong & ~near_edge).any()
