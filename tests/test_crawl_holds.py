"""Crawling on hands and knees, IMU only: a knee is held while it rests and let go when it moves.

The DeepMimic crawl of the motion library, after the simulation's standing start (2 s N-pose
for the calibration, then getting down onto the crawl's first pose), is simulated with the
default sensor errors and solved without UWB. The knees carry the body; the knee and hand
sensors' accelerometers say when they rest (:mod:`ikfusion.imu.resting`).
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from ikfusion.app.evaluate import Evaluation, evaluate
from ikfusion.cli import main as cli
from ikfusion.sim.capture import Capture, truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise

CRAWL = Path(__file__).resolve().parents[1] / "benchmarks" / "motions" / "deepmimic_crawl.bvh.gz"


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Capture:
    """The crawl's simulated capture (seed 1)."""
    truth = truth_motion(str(CRAWL), 0.0, 60.0)
    return write_capture(tmp_path_factory.mktemp("crawl") / "capture", truth, ImuNoise(), 1)


def solved(capture: Capture, out: Path, *options: str) -> Evaluation:
    """The crawl solved IMU-only into ``out``, scored against its truth."""
    with contextlib.redirect_stdout(io.StringIO()):
        code = cli(["solve", "--imu", str(capture.folder / "imu"),
                    "--map", str(capture.folder / "sensors.yaml"),
                    "--body", str(capture.folder / "body.yaml"), "--out", str(out), "--quiet",
                    *options])
    assert code == 0
    return evaluate(out, capture.folder / "truth.npz")


def test_knees_held_only_while_they_rest(capture: Capture, tmp_path: Path) -> None:
    crawl = solved(capture, tmp_path / "offline")
    # held points agree with the truth's contacts (old code 89-91 % over seeds 1-3, now 95 %)
    assert crawl.contact_agreement_pct > 94.0


@pytest.mark.xfail(strict=True, reason=(
    "issue #19, open: since the simulated lead-in gets down onto the crawl's first pose "
    "(sim/lead_in), the IMU-only solve pops the spine (jL1T12_flex) by 37 deg in one frame at "
    "8.85 s, where the truth moves <= 4.5 deg a frame; with the old lead-in (a blend dragging "
    "the feet ~1 m) the largest jump was 19-27 deg"))
def test_a_crawl_has_no_pop(capture: Capture, tmp_path: Path) -> None:
    # a knee held while the true one moves on, then let go late, snaps the leg (old code
    # 40-41 deg, with the dragged lead-in 19-27 deg)
    assert solved(capture, tmp_path / "offline").joint_angle_jump_max_deg < 33.0


def test_knees_held_only_while_they_rest_from_the_past_only(capture: Capture,
                                                            tmp_path: Path) -> None:
    # solve --causal (as live): the rest of the knees and hands from past samples (old code
    # 89-93 % over seeds 1-2, now 96 %)
    assert solved(capture, tmp_path / "causal", "--causal").contact_agreement_pct > 94.0
