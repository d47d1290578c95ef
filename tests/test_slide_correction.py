"""Issue #19: the ``slide`` correction keeps the head within a few centimetres on any motion.

``slide`` lets planted points slide toward the tags; before, that was all it did. A foot held
in the air (a spin kick's supporting foot as the body takes off) stayed held while its tag ran
away, and in flight nothing moved the body toward its tags: the head trailed them by up to
66 cm. It now couples the tags to the whole body as ``no-slide`` does (feet whose tags run away
let go, swing feet pulled toward their tags, the ballistic path pulled in flight).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from room_captures import room_capture

from ikfusion.app.evaluate import evaluate
from ikfusion.app.tag_tasks import TagTaskSettings, flight_pull
from ikfusion.cli import main
from ikfusion.sim.capture import truth_motion

MOTIONS = Path(__file__).resolve().parents[1] / "benchmarks" / "motions"


def _capture(clip: str, folder: Path) -> Path:
    """The clip in the library's UWB room, default sensor errors, seed 1 (as the benchmark)."""
    return room_capture(truth_motion(str(MOTIONS / clip), 30.0, 60.0), folder)


def _solve(capture: Path, out: Path, mode: str) -> Path:
    args = ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml"), "--out", str(out), "--quiet",
            "--toa", str(capture / "toa.csv"), "--readers", str(capture / "readers.yaml"),
            "--tags", str(capture / "tags.yaml"), "--correction", mode]
    assert main(args) == 0
    return out


@pytest.fixture(scope="module")
def spin_kick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The DeepMimic spin kick (4.8 s: a stand, a spin, a kick in flight, a landing)."""
    return _capture("deepmimic_spinkick.bvh.gz", tmp_path_factory.mktemp("spin") / "capture")


def test_slide_keeps_the_head_with_its_tag_through_a_spin_kick(spin_kick: Path,
                                                                tmp_path: Path) -> None:
    """Before: head RMS 12.3 cm (no-slide 4.0), the supporting foot held 46 cm up in the air.
    Now within the issue's 4 cm, as close as no-slide, and no pop at the landing."""
    slide = evaluate(_solve(spin_kick, tmp_path / "slide", "slide"), spin_kick / "truth.npz",
                     align="none")
    assert slide.head_position_rms_m <= 0.04
    assert slide.held_slide_max_mm < 200.0  # slides on purpose, but never flies with a foot


def _head_track(result: Path) -> np.ndarray:
    """(N, 3) the solved HeadTop [m] from the result folder's ``sites.csv``."""
    rows = np.genfromtxt(result / "sites.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")
    head = rows[rows["site"] == "HeadTop"]
    return np.stack([head["x"], head["y"], head["z"]], axis=1)


def test_slide_keeps_the_head_with_its_tag_in_flight(tmp_path: Path) -> None:
    """Forward jumps (CMU 01_01, 26 s, eight two-foot jumps): in flight nothing planted can
    slide, and the body flew on its inertial path: the head trailed its tag by up to 14 cm
    (RMS 8.4 cm over the flights). The tags now pull the ballistic path in flight."""
    capture = _capture("cmu_01_01_forward_jumps.bvh.gz", tmp_path / "capture")
    truth = np.load(capture / "truth.npz")
    head = _head_track(_solve(capture, tmp_path / "slide", "slide"))
    n = min(len(head), len(truth["time"]))
    flight = ~truth["contacts"][:n].any(axis=1)
    true_head = truth["p_world_site"][:n, list(truth["site_names"]).index("HeadTop")]
    error = np.linalg.norm(head[:n, :2] - true_head[:, :2], axis=1)
    assert flight.sum() > 30  # the jumps are there
    assert np.sqrt(np.mean(error[flight] ** 2)) < 0.04


def test_in_flight_the_head_tag_moves_the_path_in_height_too() -> None:
    """The sensed take-off alone put the apex of a jump 16 cm below the head's tag (cmu 02_04:
    head RMS 5.0 cm): with ``flight_vertical`` the head's tag moves the path's height as well
    (by the same lag and bound); the feet's alone never do (a foot's height is its leg's)."""
    settings = TagTaskSettings(1.0, 0.1, 0.05, False, 0.05, flight_speed=2.0,
                               flight_vertical=True)
    dt = 1 / 60
    sites = np.array([[1.0, 2.0, 1.8], [1.1, 2.1, 0.1], [0.9, 1.9, 0.3]])
    body = [True, False, False]
    cov = np.tile(0.03**2 * np.eye(3), (3, 1, 1))
    gap = np.array([0.01, -0.01, 0.05])
    pull = flight_pull(sites, body, sites + gap, cov, dt, settings)
    assert pull == pytest.approx(gap * dt / 0.05)
    far = sites + [0.0, 0.0, 1.0]
    pull = flight_pull(sites, body, far, cov, dt, settings)
    assert pull == pytest.approx([0.0, 0.0, 2.0 * dt])
    no_head = sites + gap
    no_head[0] = np.nan
    pull = flight_pull(sites, body, no_head, cov, dt, settings)
    assert pull is not None and pull[2] == 0.0


def test_slide_keeps_the_head_with_its_tag_over_a_jump(tmp_path: Path) -> None:
    """CMU 02_04 (a jump and balancing on one foot, 12 s): before, head RMS 5.0 cm (no-slide
    4.7), the head 10-16 cm low at the apex. Now within the issue's 4 cm in both modes."""
    capture = _capture("cmu_02_04_jump_balance.bvh.gz", tmp_path / "capture")
    for mode in ("slide", "no-slide"):
        result = evaluate(_solve(capture, tmp_path / mode, mode), capture / "truth.npz",
                          align="none")
        assert result.head_position_rms_m <= 0.04, mode
