"""Every clip of the motion library, simulated in a UWB room and solved in four modes.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_motions.py [--seconds S] [--clips PATTERN...]
[--modes imu-only slide no-slide no-slide-causal] [--seed N] [--noise default|none] [--shared]
[--acceptance] [--out DIR]``

The library is ``benchmarks/motions/library.yaml`` (clips and their origins in
``benchmarks/motions/ATTRIBUTION.md``): CMU motion capture, DeepMimic clips and walks of the
procedural generator.
Each clip is simulated as ``ikfusion simulate --readers configs/constellations/room_6x8.yaml``
does it (17 IMUs with the default errors or perfect ones, UWB tags on the head and both feet,
10 readers, sigma 3 cm, 10 % NLOS receptions; the motion placed inside the room), cut to
``--seconds`` when given, and solved with ``ikfusion solve``:

* ``imu-only``: no UWB (scored after ``evaluate``'s start alignment);
* ``slide`` and ``no-slide``: ``--correction slide|no-slide`` with the tag tracks smoothed over
  the recording;
* ``no-slide-causal``: ``--correction no-slide --causal`` (tag tracks from the past only).

Columns (``ikfusion.app.evaluate`` against the truth, whole capture): head (HeadTop) 3-D RMS [cm];
``slide``/``max``: slide of the contact points per contact phase of the truth, mean and max [mm]
(detection misses and slides mixed); ``truth``: the true points' own mean slide over those phases
(the truth's phases are loose, its points move in them: the floor of ``slide``); ``held``/``held
max``: slide of the points the solver holds per contact phase of the solver, mean and max [mm];
``held tru``: the true points' mean slide over the solver's phases (a point held while the true
one moves shifts the body); ``agree``: the solver's contact states equal to the truth's [%];
joint-angle RMS [deg]; the largest error of a frame-to-frame joint-angle change against the
truth's [deg] (``joint_angle_jump_max_deg``, toes left out); frames solved per second of wall
time (tag tracking included); ``drift %``: the pelvis's horizontal error at the end as a
percentage of the distance travelled (``evaluate``'s ``drift_percent``; '-' below 2 m travelled);
``jump-ref``: ``jump deg`` minus the same clip's reference row's (``--acceptance``; '-' without);
``step deg``: the largest turn of a joint of the solve in one frame, the solve alone
(``joint_angle_step_max_deg``, toes left out) [deg]; ``beyond mm``: per contact phase of the
truth, how much further the solved point slid than the true one, mean (``foot_slide_excess_mm``:
the skating the solve adds, free of the truth's loose phases) [mm]; ``floor mm``: the same where
the truth is a body on the floor (``foot_slide_excess_on_floor_mm``: the steps in which the solver
holds a trunk point the truth has sunk more than 2 cm under the floor are left out, the solved
points moving there as the true ones do; ``ikfusion.app.slide_excess``) [mm]; ``stride %``:
step by step (from one foot strike of the truth to the next), how far the solved pelvis's
travel along the true one falls short of the true travel, summed over the steps, as a
percentage (``stride_loss_percent``, ``ikfusion.app.stride_loss``; negative: the solve
overshoots; '-' with fewer than 4 steps or under 1 m): the loss of a walk that ``drift %`` cannot
see on a closed path, where the solved circle is a smaller copy of the true one and closes on
itself. An extra figure, not an acceptance criterion: a straight walk's end error is its
stride loss, which ``drift %`` judges on the straight clips.
The last row holds the worst of each column over the rows of the chosen ``--noise`` (reference
rows left out).

``--acceptance`` (issue #19) judges the selected clips on the issue's acceptance list. Each clip
is also simulated with perfect sensors (same truth, same seed) and solved IMU-only: the
reference row ``imu-only perfect``, printed before the clip's rows. After the table comes one
row per criterion: its limit, how many rows it judged, the worst clip (and mode) with its
value, and PASS, FAIL or n/a (nothing to judge, e.g. its mode was not run); the exit code is 1
when a criterion fails. With the default sensor errors (``--noise none`` is refused):

1. IMU only, walking drifts at most 1 %: ``drift %`` of the ``imu-only`` rows of the clips whose
   ``categories`` in library.yaml include ``walking`` (the library's data, not clip names; the
   shared clips have none). The distance walked is ``evaluate``'s: the true pelvis's horizontal
   track sampled once a second, over the whole capture; the drift is the pelvis's horizontal
   error averaged over the last second, after the start alignment. A walking clip that travels
   less than 2 m has no figure and is not judged (the count says how many were).
2. IMU only, head RMS at most 50 cm, every clip.
3. no-slide, head RMS at most 5 cm.
4. no-slide, planted points slide at most 1 mm: ``held max``, the largest slide of a point over
   a contact phase of the solver (the points the solver holds planted; ``slide`` also counts
   detection misses and the truth's own motion in its loose phases, which no solve can bring
   to 1 mm).
5. slide, head RMS at most 4 cm. 6. no-slide-causal, head RMS at most 8 cm.
7. No pops: ``jump-ref`` at most 1 deg on every row (all modes run): the correction and the
   sensor errors add no pop to what the same clip solved from perfect orientations without UWB
   has. One-sided: a solve smoother than the reference passes.
8. No flips: ``step deg`` at most 60 deg on every row, the references included. 60 deg in a
   60 Hz frame is 3600 deg/s, beyond any human joint (the library's truths turn a joint by at
   most about 35 deg in a frame: dm-crawl's ankle; most clips 10 to 25), while a joint that
   flips to another solution (twists the other way round, bends backwards) turns by 90 deg or
   more at once. The solve alone is measured, so a flip counts whatever the truth does.
9. Perfect sensors, no UWB: planted points slide at most 5 mm on every clip with stance:
   ``floor mm`` of the reference rows (clips whose truth has no contact phase are not judged).
   A truth read from motion capture onto our body may sink the points of a lying body's back
   centimetres under the floor (dm-getup-faceup: a shoulder blade 7 cm deep, sliding 5 cm
   there); a solve holds such a point on the floor, and the whole solved body falls behind the
   true one by the sunk point's motion, which no solve on a floor can follow. ``floor mm``
   leaves those steps out, and only those (trunk points only: the truth lifts its limb points
   onto the floor, within its fit's scatter); ``beyond mm`` counts them. On the library's
   perfect rows (first 12 s) the two differ on dm-getup-faceup alone.
   Not ``held`` (the solver holds its points by construction: 0.0 mm everywhere), nor ``held
   tru`` or ``slide``, which measure the truth's loose phases (a point below 3 cm moving at up
   to 0.3 m/s counts as planted; the truths' points slide up to 22 mm there) as much as the
   solve: the excess counts the skating the solve adds in the truth's stance phases, detection
   misses included (a released point that moves while the true one stands).

Nothing is written outside a temporary folder unless ``--out DIR`` keeps the captures and
results there.
"""

from __future__ import annotations

import argparse
import contextlib
import fnmatch
import io
import math
import sys
import tempfile
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from ikfusion.app.evaluate import evaluate
from ikfusion.cli import main as ikfusion_main
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.paths import shipped_config
from ikfusion.sim.area_fit import DEFAULT_MARGIN, place_in_area
from ikfusion.sim.capture import truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation
from ikfusion.uwb.dop import capture_area

LIBRARY = Path(__file__).resolve().parent / "motions" / "library.yaml"
SHARED_MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
MODES = ("imu-only", "slide", "no-slide", "no-slide-causal")
REFERENCE = "imu-only perfect"  # the mode column of ``--acceptance``'s reference rows
RATE = 60.0  # [Hz]
WALKING = "walking"  # the library category whose clips the drift criterion judges
FLIP_DEG = 60.0  # [deg] a joint turning further in one 60 Hz frame has flipped


@dataclass(frozen=True)
class Clip:
    """One entry of the library.

    Attributes:
        name: Short name (``--clips`` matches it).
        motion: ``gait:<walk>`` or the path of a BVH file.
        seconds: Length of a generated walk [s] (None for a file: its own length).
        categories: What it covers (keys of the library's ``categories``).
        description: One line for people.
    """

    name: str
    motion: str
    seconds: float | None = None
    categories: tuple[str, ...] = ()
    description: str = ""


@dataclass(frozen=True)
class Library:
    """The library file: category names, the categories not covered yet, the clips."""

    categories: dict[str, str]
    missing: dict[str, str]
    clips: list[Clip] = field(default_factory=list)


def load_library(path: Path = LIBRARY) -> Library:
    """Read ``library.yaml``; file motions become paths beside it."""
    data = yaml.safe_load(path.read_text())
    clips = []
    for item in data["clips"]:
        motion = str(item["motion"])
        if not motion.startswith("gait"):
            motion = str(path.parent / motion)
        seconds = item.get("seconds")
        clips.append(Clip(str(item["name"]), motion, None if seconds is None else float(seconds),
                          tuple(item.get("categories") or ()), str(item.get("description", ""))))
    return Library(dict(data["categories"]), dict(data.get("missing") or {}), clips)


def shared_clips(folder: Path = SHARED_MOCAP) -> list[Clip]:
    """The shared BVH clips (``--shared``), used by path: they are not part of the library."""
    return [Clip(f"shared-{p.stem}", str(p), description=f"shared/data/mocap/{p.name}")
            for p in sorted(folder.glob("*.bvh"))]


def clip_truth(clip: Clip, seconds: float | None) -> TruthMotion:
    """The clip's ground truth at 60 Hz, cut to its first ``seconds`` [s] when given."""
    length = clip.seconds if clip.seconds is not None else 30.0
    if seconds is not None:
        length = min(length, seconds)
    truth = truth_motion(clip.motion, length, RATE)
    if seconds is not None and truth.time[-1] > seconds:
        n = int(math.floor(seconds * RATE)) + 1
        truth = TruthMotion(truth.model, truth.time[:n].copy(), truth.q[:n].copy(),
                            list(truth.contact_names), truth.contacts[:n].copy(), truth.source,
                            dict(truth.info))
    return truth


def simulate_clip(clip: Clip, folder: Path, seconds: float | None, seed: int,
                  noise: str) -> Path:
    """Write the clip's capture in the UWB room (as ``ikfusion simulate --readers`` does)."""
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    truth, _ = place_in_area(clip_truth(clip, seconds), capture_area(room), DEFAULT_MARGIN)
    imu_noise = ImuNoise() if noise == "default" else ImuNoise.none()
    write_capture(folder, truth, imu_noise, seed, constellation=room, force=True)
    return folder


def solve(capture: Path, out: Path, mode: str) -> float:
    """Solve a capture in one mode; returns the wall time [s]."""
    args = ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml"), "--out", str(out), "--force", "--quiet"]
    if mode != "imu-only":
        args += ["--toa", str(capture / "toa.csv"), "--readers", str(capture / "readers.yaml"),
                 "--tags", str(capture / "tags.yaml"),
                 "--correction", mode.removesuffix("-causal")]
    if mode.endswith("-causal"):
        args.append("--causal")
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = ikfusion_main(args)
    if code != 0:
        raise RuntimeError(f"ikfusion solve ({mode}) of {capture} failed with exit code {code}")
    return time.perf_counter() - start


@dataclass(frozen=True)
class Row:
    """One line of the table."""

    clip: str
    mode: str
    head_cm: float
    slide_mm: float
    slide_max_mm: float
    truth_mm: float
    held_mm: float
    held_max_mm: float
    held_truth_mm: float
    agree_pct: float
    angle_rms_deg: float
    jump_deg: float
    fps: float
    drift_pct: float | None = None
    step_deg: float = 0.0
    beyond_mm: float | None = None
    jump_vs_ref_deg: float | None = None
    beyond_floor_mm: float | None = None
    stride_pct: float | None = None

    def text(self) -> str:
        """The row as printed."""
        return (f"{self.clip:<24s} {self.mode:<16s} {self.head_cm:8.1f} {self.slide_mm:8.1f} "
                f"{self.slide_max_mm:8.1f} {self.truth_mm:8.1f} {self.held_mm:8.1f} "
                f"{self.held_max_mm:8.1f} {self.held_truth_mm:8.1f} {self.agree_pct:7.1f} "
                f"{self.angle_rms_deg:8.2f} {self.jump_deg:8.2f} {self.fps:7.0f} "
                f"{_cell(self.drift_pct, 7, 2)} {_cell(self.jump_vs_ref_deg, 8, 2)} "
                f"{self.step_deg:8.2f} {_cell(self.beyond_mm, 9, 1)} "
                f"{_cell(self.beyond_floor_mm, 8, 1)} {_cell(self.stride_pct, 8, 2)}")


def _cell(value: float | None, width: int, decimals: int) -> str:
    """A number right-aligned in ``width`` characters, '-' for None."""
    return f"{'-':>{width}s}" if value is None else f"{value:{width}.{decimals}f}"


HEADER = (f"{'clip':<24s} {'mode':<16s} {'head cm':>8s} {'slide mm':>8s} {'max mm':>8s} "
          f"{'truth mm':>8s} {'held mm':>8s} {'held max':>8s} {'held tru':>8s} "
          f"{'agree %':>7s} {'ang deg':>8s} {'jump deg':>8s} {'frame/s':>7s} {'drift %':>7s} "
          f"{'jump-ref':>8s} {'step deg':>8s} {'beyond mm':>9s} {'floor mm':>8s} {'stride %':>8s}")


def run_clip(clip: Clip, root: Path, modes: Sequence[str], seconds: float | None, seed: int,
             noise: str, ref_jump_deg: float | None = None) -> list[Row]:
    """Simulate one clip and score every mode (``ref_jump_deg``: the reference's jump [deg])."""
    capture = simulate_clip(clip, root / clip.name / "capture", seconds, seed, noise)
    rows = []
    for mode in modes:
        result = root / clip.name / mode
        wall = solve(capture, result, mode)
        ev = evaluate(result, capture / "truth.npz", align="auto")
        rows.append(Row(clip.name, mode, 100.0 * ev.head_position_rms_m, ev.foot_slide_mm,
                        ev.foot_slide_max_mm, ev.truth_slide_mm, ev.held_slide_mm,
                        ev.held_slide_max_mm, ev.held_truth_slide_mm,
                        ev.contact_agreement_pct, ev.joint_angle_rms_deg,
                        ev.joint_angle_jump_max_deg, ev.frames / wall, ev.drift_percent,
                        ev.joint_angle_step_max_deg, ev.foot_slide_excess_mm,
                        None if ref_jump_deg is None
                        else ev.joint_angle_jump_max_deg - ref_jump_deg,
                        ev.foot_slide_excess_on_floor_mm, ev.stride_loss_percent))
    return rows


def run_reference(clip: Clip, root: Path, seconds: float | None, seed: int) -> Row:
    """The clip with perfect sensors (same truth, same seed), solved IMU-only: ``--acceptance``'s
    reference row (its files under ``root/perfect``)."""
    row = run_clip(clip, root / "perfect", ["imu-only"], seconds, seed, "none")[0]
    return replace(row, mode=REFERENCE)


def worst(rows: Sequence[Row]) -> Row:
    """The worst of each column (the largest error, the fewest frames per second; ``stride %``:
    the largest in size, signed)."""
    return Row("worst", "-", max(r.head_cm for r in rows), max(r.slide_mm for r in rows),
               max(r.slide_max_mm for r in rows), max(r.truth_mm for r in rows),
               max(r.held_mm for r in rows),
               max(r.held_max_mm for r in rows), max(r.held_truth_mm for r in rows),
               min(r.agree_pct for r in rows),
               max(r.angle_rms_deg for r in rows),
               max(r.jump_deg for r in rows), min(r.fps for r in rows),
               max((r.drift_pct for r in rows if r.drift_pct is not None), default=None),
               max(r.step_deg for r in rows),
               max((r.beyond_mm for r in rows if r.beyond_mm is not None), default=None),
               max((r.jump_vs_ref_deg for r in rows if r.jump_vs_ref_deg is not None),
                   default=None),
               max((r.beyond_floor_mm for r in rows if r.beyond_floor_mm is not None),
                   default=None),
               max((r.stride_pct for r in rows if r.stride_pct is not None), key=abs,
                   default=None))


@dataclass(frozen=True)
class Verdict:
    """One criterion of ``--acceptance`` judged on the rows.

    Attributes:
        criterion: What is judged, for people.
        limit: The largest value that passes, in ``unit``.
        unit: ``cm``, ``mm``, ``deg`` or ``%``.
        judged: How many rows were judged.
        worst: ``"<clip> <mode>"`` of the largest value ('-' when nothing was judged).
        value: The largest value (None when nothing was judged; NaN fails).
    """

    criterion: str
    limit: float
    unit: str
    judged: int
    worst: str
    value: float | None

    @property
    def status(self) -> str:
        """``PASS`` (the worst value within the limit), ``FAIL`` or ``n/a`` (nothing judged)."""
        if self.value is None:
            return "n/a"
        return "PASS" if self.value <= self.limit else "FAIL"

    def text(self) -> str:
        """The verdict as printed."""
        value = "-" if self.value is None else f"{self.value:.2f}"
        return (f"{self.criterion:<46s} {f'<= {self.limit:g} {self.unit}':>10s} "
                f"{self.judged:5d}  {self.worst:<38s} {value:>8s}  {self.status}")


VERDICT_HEADER = (f"{'criterion':<46s} {'limit':>10s} {'rows':>5s}  {'worst':<38s} "
                  f"{'value':>8s}  verdict")


def judge(criterion: str, limit: float, unit: str,
          values: Sequence[tuple[Row, float]]) -> Verdict:
    """The verdict of one criterion on ``(row, value)`` pairs: the largest value (a NaN first)."""
    if not values:
        return Verdict(criterion, limit, unit, 0, "-", None)
    row, value = max(values, key=lambda rv: (math.isnan(rv[1]), rv[1]))
    return Verdict(criterion, limit, unit, len(values), f"{row.clip} {row.mode}", value)


def acceptance(rows: Sequence[Row], references: Mapping[str, Row],
               walking: Collection[str]) -> list[Verdict]:
    """Issue #19's acceptance list judged on a run (the criteria: the module docstring).

    Args:
        rows: The rows of the four modes with the default sensor errors.
        references: Per clip name, its ``imu-only perfect`` row (perfect sensors, no UWB).
        walking: The names of the clips that count as walking (library category ``walking``).

    Returns:
        One verdict per criterion, in the docstring's order.
    """
    def of(mode: str, figure: str) -> list[tuple[Row, float]]:
        return [(r, float(getattr(r, figure))) for r in rows if r.mode == mode]

    drifts = [(r, r.drift_pct) for r in rows
              if r.mode == "imu-only" and r.clip in walking and r.drift_pct is not None]
    jumps = [(r, r.jump_deg - references[r.clip].jump_deg) for r in rows if r.clip in references]
    steps = [(r, r.step_deg) for r in [*rows, *references.values()]]
    beyond = [(r, r.beyond_floor_mm) for r in references.values()
              if r.beyond_floor_mm is not None]
    return [
        judge("IMU only: drift of walking clips", 1.0, "%", drifts),
        judge("IMU only: head RMS", 50.0, "cm", of("imu-only", "head_cm")),
        judge("no-slide: head RMS", 5.0, "cm", of("no-slide", "head_cm")),
        judge("no-slide: held points' slide (held max)", 1.0, "mm",
              of("no-slide", "held_max_mm")),
        judge("slide: head RMS", 4.0, "cm", of("slide", "head_cm")),
        judge("no-slide-causal: head RMS", 8.0, "cm", of("no-slide-causal", "head_cm")),
        judge("no pops: jump - perfect IMU-only jump", 1.0, "deg", jumps),
        judge("no flips: joint turn in one frame (step)", FLIP_DEG, "deg", steps),
        judge("perfect, no UWB: slide beyond the truth's (floor)", 5.0, "mm", beyond),
    ]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=None, metavar="S",
                        help="simulate only the first S s of each clip (standing start "
                        "included; default: whole clips, at most 30 s)")
    parser.add_argument("--clips", nargs="+", default=["*"], metavar="PATTERN",
                        help="clip names to run (shell patterns, e.g. 'gen-*' amp-walk; "
                        "default all)")
    parser.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES))
    parser.add_argument("--seed", type=int, default=1, help="random seed of the simulations")
    parser.add_argument("--noise", choices=["default", "none"], default="default",
                        help="sensor errors (none: perfect sensors)")
    parser.add_argument("--shared", action="store_true",
                        help="also run the shared BVH clips of ../shared/data/mocap by path")
    parser.add_argument("--acceptance", action="store_true",
                        help="also solve each clip IMU-only with perfect sensors (the "
                        "reference) and judge issue #19's acceptance list after the table "
                        "(the criteria above); exit code 1 when one fails")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="keep captures and results in DIR (default: a temporary folder)")
    args = parser.parse_args(argv)
    if args.seconds is not None and args.seconds <= 3.5:
        parser.error("--seconds must exceed 3.5 (2 s of N-pose come first)")
    clips = load_library().clips + (shared_clips() if args.shared else [])
    clips = [c for c in clips if any(fnmatch.fnmatch(c.name, p) for p in args.clips)]
    if not clips:
        parser.error(f"no clip matches {' '.join(args.clips)!r}")
    if args.acceptance and args.noise != "default":
        parser.error("--acceptance judges the default sensor errors (drop --noise none)")
    span = "whole clips" if args.seconds is None else f"first {args.seconds:g} s"
    print(f"{len(clips)} clips ({span}), room_6x8 UWB, "
          f"{'default sensor errors' if args.noise == 'default' else 'perfect sensors'}, "
          f"seed {args.seed}", flush=True)
    print(HEADER, flush=True)
    start = time.perf_counter()
    rows: list[Row] = []
    references: dict[str, Row] = {}
    with contextlib.ExitStack() as stack:
        root = args.out or Path(stack.enter_context(tempfile.TemporaryDirectory(
            prefix="bench_motions_")))
        for clip in clips:
            if args.acceptance:
                references[clip.name] = run_reference(clip, Path(root), args.seconds, args.seed)
                print(references[clip.name].text(), flush=True)
            reference = references.get(clip.name)
            for row in run_clip(clip, Path(root), args.modes, args.seconds, args.seed,
                                args.noise, None if reference is None else reference.jump_deg):
                rows.append(row)
                print(row.text(), flush=True)
    print(worst(rows).text())
    print(f"total {time.perf_counter() - start:.0f} s", flush=True)
    if not args.acceptance:
        return 0
    verdicts = acceptance(rows, references, {c.name for c in clips if WALKING in c.categories})
    print(f"\nacceptance (issue #19; {len(clips)} clips, default sensor errors, seed {args.seed})")
    print(VERDICT_HEADER)
    for verdict in verdicts:
        print(verdict.text())
    return 1 if any(v.status == "FAIL" for v in verdicts) else 0


if __name__ == "__main__":
    sys.exit(main())
