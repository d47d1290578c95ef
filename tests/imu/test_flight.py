"""Flight from the accelerometers, checked against the generator's contact phases."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.imu.flight import (
    FlightDetector,
    FlightEvidence,
    FlightPhases,
    FlightThresholds,
    _held_for,
    detect_flight,
    flight_evidence,
    world_acceleration,
)
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.model import HumanModel
from ikfusion.sim.gait import gait_preset, generate_gait
from ikfusion.sim.imu import ImuNoise, SimulatedImus, simulate_imus

RATE = 60.0
UNITS = ["Pelvis", "LeftFoot", "RightFoot"]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _imus(truth: TruthMotion, rng: np.random.Generator, noise: ImuNoise) -> SimulatedImus:
    return simulate_imus(truth.model, truth.time, truth.q, UNITS, rng, noise)


def _detect(imus: SimulatedImus, **kwargs: np.ndarray | None) -> np.ndarray:
    acc = dict(zip(imus.segments, imus.acc))
    gyr = dict(zip(imus.segments, imus.gyr))
    feet = ("LeftFoot", "RightFoot")
    return detect_flight(RATE, kwargs.get("pelvis", acc["Pelvis"]), {f: acc[f] for f in feet},
                         {f: gyr[f] for f in feet}).airborne


@pytest.fixture(scope="module", params=["jump", "hop", "skip"])
def bouncing(request: pytest.FixtureRequest) -> TruthMotion:
    return generate_gait(HumanModel.default(), gait_preset(request.param, 5.0, stand=1.0),
                         rate=RATE)


@pytest.mark.parametrize("noise", [ImuNoise.none(), ImuNoise()], ids=["perfect", "noisy"])
def test_flights_match_the_generator_contact_phases(bouncing: TruthMotion, noise: ImuNoise,
                                                    rng: np.random.Generator) -> None:
    truth_air = ~bouncing.contacts.any(axis=1)
    airborne = _detect(_imus(bouncing, rng, noise))
    flights = _runs(truth_air)
    assert len(flights) >= 5
    for a, b in flights:  # every flight found whole but for the push-off and landing samples
        assert airborne[a + 2:b - 1].all(), (a, b)  # (central differences blur the kinks)
    # never in the air while the truth stands: at most the sample at each edge of a flight
    wrong = airborne & ~truth_air
    near_edge = np.zeros_like(wrong)
    for a, b in flights:
        near_edge[max(a - 1, 0):b + 1] = True
    assert not (wrong & ~near_edge).any()


def test_landings_are_the_first_samples_back_on_the_ground(bouncing: TruthMotion,
                                                           rng: np.random.Generator) -> None:
    imus = _imus(bouncing, rng, ImuNoise.none())
    acc = dict(zip(imus.segments, imus.acc))
    phases = detect_flight(RATE, acc["Pelvis"], {f: acc[f] for f in ("LeftFoot", "RightFoot")})
    n = len(bouncing.time)  # (a landing on the very last samples cannot show yet)
    truth_landings = np.array([b for _, b in _runs(~bouncing.contacts.any(axis=1))
                               if b < n - 2])
    assert len(phases.landings) == len(truth_landings)
    assert np.abs(phases.landings - truth_landings).max() <= 1


def test_walking_never_flies(rng: np.random.Generator) -> None:
    walk = generate_gait(HumanModel.default(), gait_preset("fast", 6.0, stand=1.0), rate=RATE)
    assert not _detect(_imus(walk, rng, ImuNoise())).any()


def test_without_a_pelvis_accelerometer_nothing_flies(bouncing: TruthMotion,
                                                      rng: np.random.Generator) -> None:
    imus = _imus(bouncing, rng, ImuNoise.none())
    assert not _detect(imus, pelvis=None).any()
    # a lost pelvis sample (NaN) is not free fall
    acc = imus.acc[imus.segments.index("Pelvis")].copy()
    acc[:] = np.nan
    assert not _detect(imus, pelvis=acc).any()


def test_the_detector_is_causal_with_its_stated_lag(bouncing: TruthMotion,
                                                    rng: np.random.Generator) -> None:
    imus = _imus(bouncing, rng, ImuNoise())
    acc = dict(zip(imus.segments, imus.acc))
    feet = {f: acc[f] for f in ("LeftFoot", "RightFoot")}
    evidence = flight_evidence(RATE, acc["Pelvis"], feet)
    detector = FlightDetector(RATE)
    assert detector.lag == 5  # 50 ms of free fall confirm, 50 ms reach back, at 60 Hz
    full = detect_flight(RATE, acc["Pelvis"], feet).airborne
    for end in range(40, len(full), 23):  # the future cannot change a decided sample
        cut = detect_flight(RATE, acc["Pelvis"][:end], {f: a[:end] for f, a in feet.items()})
        decided = end - detector.lag
        np.testing.assert_array_equal(cut.airborne[:decided], full[:decided])
    live = [d for f, li, i in zip(*evidence) if (d := detector.update(f, li, i)) is not None]
    assert [a for a, _ in live] == list(full[:len(live)])


def test_a_short_dip_is_no_flight() -> None:
    n = 60
    pelvis = np.tile([0.0, 0.0, 9.81], (n, 1))
    pelvis[30:32] = 0.0  # 33 ms of free fall: less than min_duration
    assert not detect_flight(RATE, pelvis, {}).airborne.any()
    pelvis[30:34] = 0.0  # 67 ms
    phases = detect_flight(RATE, pelvis, {}, thresholds=FlightThresholds())
    assert np.flatnonzero(phases.airborne).tolist() == [30, 31, 32, 33]
    assert phases.landings.tolist() == [34]


def test_world_acceleration_removes_gravity(rng: np.random.Generator) -> None:
    from ikfusion.rotations import random_rotations

    R = random_rotations(5, rng)
    a = rng.normal(size=(5, 3))
    f = np.einsum("nji,nj->ni", R, a - np.array([0.0, 0.0, -9.81]))
    np.testing.assert_allclose(world_acceleration(R, f), a, atol=1e-12)


def _detector_over(rate: float, evidence: FlightEvidence) -> FlightPhases:
    """The reference of :func:`detect_flight`: the causal detector over every sample."""
    detector = FlightDetector(rate)
    decisions = [d for f, li, i in zip(*evidence) if (d := detector.update(f, li, i))
                 is not None] + detector.flush()
    return FlightPhases(np.array([a for a, _ in decisions], dtype=bool),
                        np.flatnonzero([b for _, b in decisions]), detector.lag)


@pytest.mark.parametrize("n", [0, 3, 8, 400])
def test_grounded_recordings_decided_at_once_as_the_detector_decides_them(
        n: int, rng: np.random.Generator) -> None:
    """Without a run of free samples long enough (the usual walk) no sample is decided in the
    air: the shortcut's phases are the detector's, with and without flights."""
    for trial in range(60):
        # pelvis |f| around the thresholds: free dips of 1 to 4 samples, some flights
        pelvis = np.zeros((n, 3))
        pelvis[:, 2] = rng.choice([0.0, 4.0, 6.0, 9.81], n, p=[0.1, 0.1, 0.2, 0.6])
        if trial % 2:
            pelvis[::3, 2] = 9.81  # runs of at most two free samples: grounded throughout
        foot = np.tile([0.0, 0.0, 9.81], (n, 1))
        foot[rng.random(n) < 0.05, 2] = 50.0  # impacts
        gyr = np.where(rng.random((n, 1)) < 0.5, 0.1, 2.0) * np.ones((1, 3))
        acc, gyrs = {"LeftFoot": foot}, {"LeftFoot": gyr}
        phases = detect_flight(RATE, pelvis, acc, gyrs)
        expected = _detector_over(RATE, flight_evidence(RATE, pelvis, acc, gyrs))
        np.testing.assert_array_equal(phases.airborne, expected.airborne)
        assert phases.airborne.dtype == expected.airborne.dtype
        np.testing.assert_array_equal(phases.landings, expected.landings)
        assert phases.landings.dtype == expected.landings.dtype
        assert phases.lag == expected.lag


def test_held_for_is_the_running_count(rng: np.random.Generator) -> None:
    for n in (0, 1, 5, 300):
        mask = rng.random(n) < 0.7
        run, count = [], 0
        for value in mask.tolist():  # the reference: the run of True samples, one by one
            count = count + 1 if value else 0
            run.append(count)
        for samples in (0, 1, 2, 3, 6, n + 1):
            np.testing.assert_array_equal(_held_for(mask, samples),
                                          np.array(run, dtype=int) >= samples)
