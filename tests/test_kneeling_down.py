"""Getting down onto the knees, IMU only, perfect sensors: the landing toe takes the body.

The DeepMimic get-up from lying face down (benchmarks/motions) starts, after the simulation's
2 s N-pose, by getting down onto its first pose: the body leans forward on its left toe, the
right foot swings back and lands on its toe, the left toe lifts and the right knee goes down.
While the body pivots on the lifting left toe, the right toe, solved relative to it, moves at
0.5-0.9 m/s where the true toe stands, so the touch-down's speed test kept it off the floor
until the left toe rose 6 cm: 0.2 s during which the unheld toe slid 15 cm (issue #19: 13 mm of
``beyond mm`` averaged over the clip's phases, the limit is 5). The left foot's IMU says its
toe moves: the solved speeds relative to it say nothing, and the right toe, as low as the
planted toe in the sensed pose, touches down.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import evaluate, phase_slides, read_truth
from ikfusion.cli import main as cli
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.paths import shipped_config
from ikfusion.sim.area_fit import DEFAULT_MARGIN, place_in_area
from ikfusion.sim.capture import Capture, truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation
from ikfusion.uwb.dop import capture_area

FACEDOWN = (Path(__file__).resolve().parents[1] / "benchmarks" / "motions"
            / "deepmimic_getup_facedown.bvh.gz")
# [s] the N-pose, the way down onto the right knee (its toe lands at 3.17 s, the knee at 3.42 s)
# and the kneel (a window that ends sooner leaves the feet still to the end of the recording,
# where their IMUs' stance, looking ahead, reads otherwise)
SECONDS = 4.5


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Capture:
    """The first ``SECONDS`` of the get-up with perfect sensors (seed 1), placed in the shipped
    6 x 8 m room as ``benchmarks/bench_motions.py`` does."""
    full = truth_motion(str(FACEDOWN), 0.0, 60.0)
    n = int(np.floor(SECONDS * 60.0)) + 1
    cut = TruthMotion(full.model, full.time[:n].copy(), full.q[:n].copy(),
                      list(full.contact_names), full.contacts[:n].copy(), full.source,
                      dict(full.info))
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    truth, _ = place_in_area(cut, capture_area(room), DEFAULT_MARGIN)
    return write_capture(tmp_path_factory.mktemp("kneel") / "capture", truth, ImuNoise.none(), 1,
                         constellation=room)


def test_the_landing_toe_is_held_while_the_other_toe_lifts(capture: Capture,
                                                            tmp_path: Path) -> None:
    out = tmp_path / "out"
    with contextlib.redirect_stdout(io.StringIO()):
        code = cli(["solve", "--imu", str(capture.folder / "imu"),
                    "--map", str(capture.folder / "sensors.yaml"),
                    "--body", str(capture.folder / "body.yaml"), "--out", str(out), "--quiet"])
    assert code == 0
    truth = read_truth(capture.folder / "truth.npz")
    names = [str(n) for n in truth["contact_names"]]
    sites = [str(n) for n in truth["site_names"]]
    right_toe = names.index("RightToe")
    contacts = np.asarray(truth["contacts"], dtype=bool)[:, [right_toe]]
    landing = contacts & (truth["time"] > 3.0)[:, None]  # the toe's landing, not the N-pose
    assert landing.any()
    true_slide = phase_slides(truth["p_world_site"][:, [sites.index("RightToe")]], landing)
    solved = _site_track(out / "sites.csv", "RightToe")
    assert len(solved) == len(landing)  # one solved frame per true sample
    solved_slide = phase_slides(solved[:, None, :], landing)
    # the true toe slides 9 mm while it stands; the solved one slid 153 mm (old code), now
    # about as much as the true one
    assert true_slide[0] < 0.015
    assert solved_slide[0] - true_slide[0] < 0.005
    # and over every stance phase of the window the solve adds little skating (old code: 25
    # mm; now 1.3 mm)
    result = evaluate(out, capture.folder / "truth.npz")
    assert result.foot_slide_excess_mm is not None
    assert result.foot_slide_excess_mm < 5.0


def _site_track(path: Path, site: str) -> np.ndarray:
    """(N, 3) positions [m] of one site from a result folder's ``sites.csv``."""
    rows = [line.split(",") for line in path.read_text().splitlines()[1:]]
    return np.array([[float(v) for v in r[2:5]] for r in rows if r[1] == site])
