"""The benchmark's motion library: complete index, files present and attributed, one clip solved.

``benchmarks/bench_motions.py`` runs every clip in every mode; here the index is checked against
the issue's list of motions and one short clip goes through the benchmark's own code path.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import evaluate
from ikfusion.io.bvh import read_bvh
from ikfusion.sim.gait import GAIT_PRESETS

ROOT = Path(__file__).resolve().parents[2]
MOTIONS = ROOT / "benchmarks" / "motions"

#: The motions the issue asks the library to cover (one key per kind).
ISSUE_CATEGORIES = {
    "walking", "start-stop", "backwards", "side-steps", "turn-on-spot", "running",
    "two-foot-jumps", "hop-one-leg", "skipping", "dance-spins", "kicks", "crouch-kneel",
    "sit-to-stand", "hands-on-floor",
}


def _bench():
    """``benchmarks/bench_motions.py`` as a module (benchmarks/ is not a package)."""
    name = "bench_motions_under_test"
    if name not in sys.modules:
        path = ROOT / "benchmarks" / "bench_motions.py"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def test_index_covers_the_issue_list_or_says_what_is_missing() -> None:
    library = _bench().load_library()
    assert set(library.categories) == ISSUE_CATEGORIES
    covered = {c for clip in library.clips for c in clip.categories}
    assert covered <= ISSUE_CATEGORIES, covered - ISSUE_CATEGORIES
    assert covered | set(library.missing) == ISSUE_CATEGORIES, "a category is neither covered " \
        "by a clip nor listed under missing"
    assert not covered & set(library.missing), "a covered category is still listed as missing"
    assert all(reason.strip() for reason in library.missing.values())
    assert len(library.clips) >= 20
    assert len({c.name for c in library.clips}) == len(library.clips), "clip names repeat"


def test_every_clip_is_present_short_attributed_and_small_in_all() -> None:
    library = _bench().load_library()
    attribution = (MOTIONS / "ATTRIBUTION.md").read_text()
    files = []
    for clip in library.clips:
        if clip.motion.startswith("gait"):
            assert clip.motion.split(":", 1)[1] in GAIT_PRESETS, clip.motion
            assert clip.seconds is not None and 0.0 < clip.seconds <= 30.0
            continue
        path = Path(clip.motion)
        assert path.is_file(), f"{clip.name}: {path} is missing"
        assert path.parent == MOTIONS and path.name.endswith(".bvh.gz")
        assert f"`{path.name}`" in attribution, f"{path.name} has no entry in ATTRIBUTION.md"
        bvh = read_bvh(path)
        assert math.isclose(bvh.frame_rate, 60.0, rel_tol=1e-6)
        assert 1.0 <= bvh.duration <= 30.0, f"{path.name} lasts {bvh.duration:.1f} s"
        files.append(path)
    # every file of the folder is a clip of the index (nothing unlisted, nothing unattributed)
    assert sorted(p.name for p in MOTIONS.glob("*.bvh*")) == sorted(p.name for p in files)
    total = sum(p.stat().st_size for p in MOTIONS.iterdir())
    assert total <= 15e6, f"the motion library holds {total / 1e6:.1f} MB"
    assert "NSF EIA-0196217" in attribution


def test_a_short_clip_simulates_and_solves_through_the_benchmark(tmp_path: Path) -> None:
    bench = _bench()
    clip = next(c for c in bench.load_library().clips if c.name == "amp-run")
    rows = bench.run_clip(clip, tmp_path, ["imu-only", "slide"], None, seed=3, noise="none")
    assert [r.mode for r in rows] == ["imu-only", "slide"]
    truth = np.load(tmp_path / clip.name / "capture" / "truth.npz")
    # the lead-in (a 2 s N-pose, then a step into the run) + the 81 frames of the clip, at
    # 60 Hz, inside the room
    lead_in = bench.clip_truth(clip, None).info["lead_in_s"]
    assert 2.0 < lead_in < 5.0
    assert len(truth["time"]) == round(lead_in * 60.0) + 81
    pelvis = truth["p_world_segment"][:, 0, :2]
    assert pelvis.min() > 0.0 and pelvis[:, 0].max() < 6.0 and pelvis[:, 1].max() < 8.0
    for row in rows:
        values = [row.head_cm, row.slide_mm, row.slide_max_mm, row.angle_rms_deg,
                  row.jump_deg, row.fps]
        assert all(np.isfinite(values)) and row.fps > 0.0
        # the row reports the evaluation of that mode's own result folder, in cm and mm
        ev = evaluate(tmp_path / clip.name / row.mode, tmp_path / clip.name / "capture" /
                      "truth.npz")
        assert row.head_cm == pytest.approx(100.0 * ev.head_position_rms_m)
        assert row.slide_max_mm == pytest.approx(ev.foot_slide_max_mm)
        assert row.jump_deg == pytest.approx(ev.joint_angle_jump_max_deg)
        # perfect sensors: the body's joint angles follow the truth (a wrong map, frame or
        # mode would put them tens of degrees off)
        assert row.angle_rms_deg < 10.0
    imu_only, slide = rows
    assert slide.head_cm < imu_only.head_cm  # the tags hold the body where it runs
    worst = bench.worst(rows)
    assert worst.head_cm == max(r.head_cm for r in rows)
    assert worst.fps == min(r.fps for r in rows)


@pytest.mark.parametrize("pattern", ["nothing-matches-*"])
def test_a_pattern_that_matches_no_clip_is_a_usage_error(pattern: str) -> None:
    with pytest.raises(SystemExit) as info:
        _bench().main(["--clips", pattern])
    assert info.value.code == 2
