"""The benchmark's motion library: complete index, files present and attributed, one clip solved.

``benchmarks/bench_motions.py`` runs every clip in every mode; here the index is checked against
the issue's list of motions and one short clip goes through the benchmark's own code path.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from benchmark_scripts import benchmark_script

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


def _bench() -> ModuleType:
    """``benchmarks/bench_motions.py`` as a module."""
    return benchmark_script("bench_motions.py")


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


# --- issue #19's acceptance list (--acceptance), judged on synthetic rows ----------------------

#: The verdicts in acceptance()'s order: drift, IMU-only head, no-slide head, held, slide head,
#: causal head, pops, flips, perfect-sensor slide.
DRIFT, HEAD_IMU, HEAD_NO_SLIDE, HELD, HEAD_SLIDE, HEAD_CAUSAL, POPS, FLIPS, PERFECT_SLIDE = range(9)


def _row(clip: str, mode: str, **figures):
    """A row within every limit unless ``figures`` says otherwise."""
    values = dict(head_cm=1.0, slide_mm=10.0, slide_max_mm=30.0, truth_mm=8.0, held_mm=0.0,
                  held_max_mm=0.0, held_truth_mm=5.0, agree_pct=90.0, angle_rms_deg=2.0,
                  jump_deg=2.0, fps=300.0, drift_pct=0.5, step_deg=10.0, beyond_mm=1.0,
                  beyond_floor_mm=1.0)
    values.update(figures)
    return _bench().Row(clip, mode, **values)


def _run(**changes):
    """Rows of a walking clip and a jumping clip in the four modes, and their references;
    ``changes`` maps ``"<clip> <mode>"`` to the figures that differ."""
    bench = _bench()
    rows = [_row(clip, mode, **changes.get(f"{clip} {mode}", {}))
            for clip in ("walk", "jumps") for mode in bench.MODES]
    references = {clip: _row(clip, bench.REFERENCE,
                             **changes.get(f"{clip} {bench.REFERENCE}", {}))
                  for clip in ("walk", "jumps")}
    return bench.acceptance(rows, references, walking={"walk"})


def test_acceptance_passes_every_criterion_at_its_limit() -> None:
    verdicts = _run(**{"walk imu-only": dict(drift_pct=1.0, head_cm=50.0),
                       "jumps no-slide": dict(head_cm=5.0, held_max_mm=1.0),
                       "jumps slide": dict(head_cm=4.0, jump_deg=3.0),
                       "walk no-slide-causal": dict(head_cm=8.0, step_deg=60.0),
                       "jumps imu-only perfect": dict(beyond_floor_mm=5.0)})
    assert [v.status for v in verdicts] == ["PASS"] * 9
    assert [v.judged for v in verdicts] == [1, 2, 2, 2, 2, 2, 8, 10, 2]
    assert verdicts[POPS].value == pytest.approx(1.0) and verdicts[POPS].worst == "jumps slide"


@pytest.mark.parametrize(("index", "where", "figures", "value"), [
    (DRIFT, "walk imu-only", dict(drift_pct=1.01), 1.01),
    (HEAD_IMU, "jumps imu-only", dict(head_cm=50.1), 50.1),
    (HEAD_IMU, "jumps imu-only", dict(head_cm=float("nan")), float("nan")),
    (HEAD_NO_SLIDE, "walk no-slide", dict(head_cm=5.1), 5.1),
    (HELD, "jumps no-slide", dict(held_max_mm=1.1), 1.1),
    (HEAD_SLIDE, "walk slide", dict(head_cm=4.1), 4.1),
    (HEAD_CAUSAL, "jumps no-slide-causal", dict(head_cm=8.1), 8.1),
    (POPS, "walk no-slide", dict(jump_deg=3.1), 1.1),  # the reference jumps 2.0 deg
    (POPS, "jumps imu-only", dict(jump_deg=3.1), 1.1),  # sensor errors may not pop either
    (FLIPS, "walk no-slide-causal", dict(step_deg=61.0), 61.0),
    (FLIPS, "jumps imu-only perfect", dict(step_deg=61.0), 61.0),  # the reference flips
    (PERFECT_SLIDE, "walk imu-only perfect", dict(beyond_floor_mm=5.1), 5.1),
])
def test_each_criterion_fails_on_its_own_figure_alone(index: int, where: str, figures: dict,
                                                      value: float) -> None:
    verdicts = _run(**{where: figures})
    assert [v.status for v in verdicts] == ["FAIL" if k == index else "PASS" for k in range(9)]
    assert verdicts[index].worst == where
    assert verdicts[index].value == pytest.approx(value, nan_ok=True)


def test_what_a_criterion_does_not_judge() -> None:
    verdicts = _run(**{
        "jumps imu-only": dict(drift_pct=5.0),  # not a walking clip
        "walk no-slide": dict(drift_pct=5.0),  # the drift criterion is about IMU only
        "walk slide": dict(held_max_mm=30.0),  # slide mode moves its held points on purpose
        "walk imu-only": dict(head_cm=30.0),  # within IMU only's 50 cm
        "jumps no-slide": dict(jump_deg=0.5),  # smoother than the reference: no pop
        "walk imu-only perfect": dict(beyond_mm=None, beyond_floor_mm=None),  # no stance
        # a truth whose back sinks into the floor: its steps are judged as the truth moves
        "jumps imu-only perfect": dict(beyond_mm=7.0, beyond_floor_mm=4.0),
    })
    assert all(v.status == "PASS" for v in verdicts)
    assert verdicts[PERFECT_SLIDE].judged == 1
    # a walking clip too short for a drift figure, and modes not run: nothing to judge
    bench = _bench()
    rows = [_row("walk", "imu-only", drift_pct=None)]
    verdicts = bench.acceptance(rows, {}, walking={"walk"})
    assert [v.status for v in verdicts] == ["n/a", "PASS", "n/a", "n/a", "n/a", "n/a", "n/a",
                                            "PASS", "n/a"]


def test_acceptance_judges_the_default_sensor_errors_only() -> None:
    with pytest.raises(SystemExit) as info:
        _bench().main(["--acceptance", "--noise", "none", "--clips", "amp-run"])
    assert info.value.code == 2


def test_acceptance_run_prints_the_reference_and_the_verdicts(capsys) -> None:
    """One short clip, IMU only: its perfect-sensor reference row comes first, the IMU-only row's
    ``jump-ref`` is measured against it, the criteria of modes not run have nothing to judge,
    and the exit code says whether one failed."""
    bench = _bench()
    code = bench.main(["--acceptance", "--clips", "amp-run", "--modes", "imu-only"])
    out = capsys.readouterr().out.splitlines()
    header = out.index(bench.HEADER)
    reference, imu_only = out[header + 1].split(), out[header + 2].split()
    assert reference[:3] == ["amp-run", "imu-only", "perfect"]
    assert imu_only[:2] == ["amp-run", "imu-only"] and len(imu_only) == 2 + 17
    # the 17 figures end a row; jump deg is the 10th, jump-ref the 13th ('-' for the reference)
    assert reference[-17:][12] == "-"
    jump, reference_jump = float(imu_only[-17:][9]), float(reference[-17:][9])
    assert float(imu_only[-17:][12]) == pytest.approx(jump - reference_jump, abs=0.011)
    verdicts = out[out.index(bench.VERDICT_HEADER) + 1:]
    assert len(verdicts) == 9
    statuses = [line.split()[-1] for line in verdicts]
    assert statuses[2:6] == ["n/a"] * 4  # no UWB mode was run
    assert statuses[0] == "n/a"  # amp-run is not a walking clip
    assert code == (1 if "FAIL" in statuses else 0)
