"""Issue #19: a body the head's tag let go is not planted in the air again.

In a jumping spin kick the pelvis spins, so its accelerometer never reads free fall at the
take-off and the flight goes unflagged for 0.25 s: the solver held the take-off toe, the head's
tag let the false hold go (:class:`ikfusion.app.tag_release.BodyRelease`) and the tags flew the
body back to them. Once the gap had closed, nothing was planted and nothing hinted, and the
solver planted the body's lowest point where it was: the kicking foot's toe, 28 cm up and
rising at 5 m/s. The hold dragged the whole body 37 cm from its tags (no-slide head RMS
5.37 cm, issue limit 5). Now, until a point is held again, only a foot near the floor lands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from room_captures import room_capture

from ikfusion.app.evaluate import evaluate
from ikfusion.app.tag_release import BodyRelease
from ikfusion.cli import main
from ikfusion.sim.capture import truth_motion

MOTIONS = Path(__file__).resolve().parents[1] / "benchmarks" / "motions"


def test_a_release_lands_only_once_a_point_is_held_again() -> None:
    """A false hold let go (the tag ran 10 cm away), the tags close the gap: the release
    ends, but the body is landing, not landed, until the solver holds a point again."""
    release = BodyRelease(distance=0.10, jump_speed=20.0)
    cov, dt, site = np.eye(3) * 0.01**2, 1 / 60, np.array([1.0, 2.0, 1.7])
    for k in range(60):  # held while the tag runs away at 1 m/s
        release.update(True, site + np.array([1.0 * k * dt, 0.0, 0.0]), cov, site, dt)
        if release.released:
            break
    assert release.released and not release.landing
    fix = site + np.array([1.0 * k * dt, 0.0, 0.0])
    release.update(False, fix, cov, fix - np.array([0.08, 0.0, 0.0]), dt)  # closing
    assert release.released and not release.landing
    for _ in range(5):  # closed: not released any more, nothing held yet
        release.update(False, fix, cov, fix, dt)
        assert not release.released and release.landing
    release.update(True, fix, cov, fix, dt)  # a point reached the floor and is held
    assert not release.released and not release.landing


def test_a_fix_missing_as_the_body_lands_still_ends_the_landing() -> None:
    """The hold that ends the landing counts without a fix in that frame."""
    release = BodyRelease(distance=0.10, jump_speed=20.0, released=False, landing=True)
    nan = np.full(3, np.nan)
    release.update(True, nan, np.full((3, 3), np.nan), np.zeros(3), 1 / 60)
    assert not release.landing


@pytest.fixture(scope="module")
def spin_kick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The DeepMimic jumping spin kick (whole clip) in the library's UWB room, seed 1."""
    truth = truth_motion(str(MOTIONS / "deepmimic_spinkick.bvh.gz"), 30.0, 60.0)
    return room_capture(truth, tmp_path_factory.mktemp("spin_kick") / "capture")


@pytest.mark.parametrize("causal", [False, True], ids=["offline", "causal"])
def test_no_slide_plants_no_foot_in_the_air_after_a_release(spin_kick: Path, tmp_path: Path,
                                                            causal: bool) -> None:
    """The spin kick's head stays within the late release's reach of the truth (the toe held
    0.1 s past the take-off: 14 cm; the toe planted in the air had taken it to 37 cm) and
    within the issue's 5 cm RMS; the held points still never slide."""
    out = _solve(spin_kick, tmp_path / "no-slide", "no-slide", causal)
    result = evaluate(out, spin_kick / "truth.npz", align="none")
    assert result.head_position_rms_m < 0.05
    assert result.held_slide_max_mm < 1.0
    assert _head_errors(out, spin_kick).max() < 0.25


def test_slide_lets_the_take_off_toe_go_as_the_head_rises(spin_kick: Path,
                                                          tmp_path: Path) -> None:
    """slide: the toe held past the take-off pins the body down while the head's fix rises.
    Horizontally the slides close most of the gap it opens, so only the fix's rise lets the
    hold go in time: the head fell 27 cm under the truth (RMS 3.8 cm, issue limit 4); now
    within 20 cm and 3 cm RMS."""
    out = _solve(spin_kick, tmp_path / "slide", "slide", False)
    error = _head_errors(out, spin_kick)
    assert float(np.sqrt(np.mean(error**2))) < 0.03
    assert error.max() < 0.20


def test_a_head_rising_above_the_held_body_lets_the_hold_go() -> None:
    """The head's fix rising 10 cm above the solved head (held, not moving) is a false
    hold; sinking under it is not (the legs' shape), nor is a rise closing a gap the fix
    started below the site; a smaller rise counts with the horizontal change."""
    cov, dt, site = np.eye(3) * 0.01**2, 1 / 60, np.array([1.0, 2.0, 1.7])

    def moved(to: np.ndarray, start: np.ndarray | None = None) -> BodyRelease:
        start = np.zeros(3) if start is None else start
        release = BodyRelease(distance=0.10, jump_speed=20.0)
        release.update(True, site + start, cov, site, dt)  # the hold begins
        for w in np.linspace(0.0, 1.0, 31)[1:]:  # 0.5 s of a held body
            release.update(True, site + start + w * (to - start), cov, site, dt)
            if release.released:
                break
        return release

    assert moved(np.array([0.0, 0.0, 0.12])).released
    assert not moved(np.array([0.0, 0.0, 0.08])).released
    assert not moved(np.array([0.0, 0.0, -0.30])).released
    assert not moved(np.array([0.0, 0.0, 0.06]), start=np.array([0.0, 0.0, -0.08])).released
    assert not moved(np.array([0.07, 0.0, 0.0])).released
    assert moved(np.array([0.07, 0.0, 0.08])).released


def _solve(capture: Path, out: Path, correction: str, causal: bool) -> Path:
    """Solve the capture with UWB and ``--correction``; returns the result folder."""
    args = ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml"), "--toa", str(capture / "toa.csv"),
            "--readers", str(capture / "readers.yaml"), "--tags", str(capture / "tags.yaml"),
            "--correction", correction, "--out", str(out), "--quiet"]
    assert main(args + (["--causal"] if causal else [])) == 0
    return out


def _head_errors(out: Path, capture: Path) -> np.ndarray:
    """(N,) 3-D distance [m] of the solved HeadTop to the truth's, per frame."""
    truth = np.load(capture / "truth.npz")
    head = list(truth["site_names"]).index("HeadTop")
    solved = _site_track(out / "sites.csv", "HeadTop")
    return np.asarray(np.linalg.norm(solved - truth["p_world_site"][:, head], axis=1))


def _site_track(path: Path, site: str) -> np.ndarray:
    """(N, 3) positions [m] of one site from a result folder's ``sites.csv``."""
    rows = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
    mine = rows[rows["site"] == site]
    return np.column_stack([mine["x"], mine["y"], mine["z"]]).astype(float)
