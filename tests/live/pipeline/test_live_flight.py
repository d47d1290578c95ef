"""Issue #22: the causal solve (``solve --causal``, ``live``) knows when the body flies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.imu.flight import FlightDetector


@pytest.fixture(scope="module")
def hops(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """8 s of hops on one foot (2 s N-pose first) at 60 Hz, IMUs only."""
    folder = tmp_path_factory.mktemp("hops") / "capture"
    assert main(["simulate", "--motion", "gait:hop", "--seconds", "8", "--seed", "2",
                 "--out", str(folder), "--quiet"]) == 0
    return folder


def _flights(airborne: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.r_[0, airborne.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def test_no_foot_is_planted_in_the_air(hops: Path, tmp_path: Path) -> None:
    """Before, every frame of a flight kept a foot planted in the air (the causal frames had
    no flight); now the body is airborne from at most the detector's lag after the take-off
    (a live frame cannot wait for the decision) to the landing."""
    out = tmp_path / "causal"
    assert main(["solve", "--imu", str(hops / "imu"), "--map", str(hops / "sensors.yaml"),
                 "--body", str(hops / "body.yaml"), "--causal", "--out", str(out),
                 "--quiet"]) == 0
    contacts = np.loadtxt(out / "contacts.csv", delimiter=",", skiprows=1)[:, 1:] > 0.5
    truth = np.load(hops / "truth.npz")
    flights = _flights(~truth["contacts"].any(axis=1))
    assert len(flights) >= 5
    lag = FlightDetector(60.0).lag
    inner = np.zeros(len(contacts), dtype=bool)
    for a, b in flights:  # (the push-off sample is blurred by the sensors' filters)
        inner[a + 2 + lag:b - 1] = True
    assert inner.sum() >= 30
    assert not contacts[inner].any()
