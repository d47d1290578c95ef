"""Every clip of the motion library, simulated in a UWB room and solved in four modes.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_motions.py [--seconds S] [--clips PATTERN...]
[--modes imu-only slide no-slide no-slide-causal] [--seed N] [--noise default|none] [--shared]
[--out DIR]``

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
percentage of the distance travelled (``evaluate``'s ``drift_percent``; '-' below 2 m travelled).
The last row holds the worst of each column over all rows.

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
from collections.abc import Sequence
from dataclasses import dataclass, field
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
RATE = 60.0  # [Hz]


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

    def text(self) -> str:
        """The row as printed."""
        return (f"{self.clip:<24s} {self.mode:<16s} {self.head_cm:8.1f} {self.slide_mm:8.1f} "
                f"{self.slide_max_mm:8.1f} {self.truth_mm:8.1f} {self.held_mm:8.1f} "
                f"{self.held_max_mm:8.1f} {self.held_truth_mm:8.1f} {self.agree_pct:7.1f} "
                f"{self.angle_rms_deg:8.2f} {self.jump_deg:8.2f} {self.fps:7.0f} "
                + (f"{self.drift_pct:7.2f}" if self.drift_pct is not None else f"{'-':>7s}"))


HEADER = (f"{'clip':<24s} {'mode':<16s} {'head cm':>8s} {'slide mm':>8s} {'max mm':>8s} "
          f"{'truth mm':>8s} {'held mm':>8s} {'held max':>8s} {'held tru':>8s} "
          f"{'agree %':>7s} {'ang deg':>8s} {'jump deg':>8s} {'frame/s':>7s} {'drift %':>7s}")


def run_clip(clip: Clip, root: Path, modes: Sequence[str], seconds: float | None, seed: int,
             noise: str) -> list[Row]:
    """Simulate one clip and score every mode."""
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
                        ev.joint_angle_jump_max_deg, ev.frames / wall, ev.drift_percent))
    return rows


def worst(rows: Sequence[Row]) -> Row:
    """The worst of each column (the largest error, the fewest frames per second)."""
    return Row("worst", "-", max(r.head_cm for r in rows), max(r.slide_mm for r in rows),
               max(r.slide_max_mm for r in rows), max(r.truth_mm for r in rows),
               max(r.held_mm for r in rows),
               max(r.held_max_mm for r in rows), max(r.held_truth_mm for r in rows),
               min(r.agree_pct for r in rows),
               max(r.angle_rms_deg for r in rows),
               max(r.jump_deg for r in rows), min(r.fps for r in rows),
               max((r.drift_pct for r in rows if r.drift_pct is not None), default=None))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
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
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="keep captures and results in DIR (default: a temporary folder)")
    args = parser.parse_args(argv)
    if args.seconds is not None and args.seconds <= 3.5:
        parser.error("--seconds must exceed 3.5 (2 s of N-pose come first)")
    clips = load_library().clips + (shared_clips() if args.shared else [])
    clips = [c for c in clips if any(fnmatch.fnmatch(c.name, p) for p in args.clips)]
    if not clips:
        parser.error(f"no clip matches {' '.join(args.clips)!r}")
    span = "whole clips" if args.seconds is None else f"first {args.seconds:g} s"
    print(f"{len(clips)} clips ({span}), room_6x8 UWB, "
          f"{'default sensor errors' if args.noise == 'default' else 'perfect sensors'}, "
          f"seed {args.seed}", flush=True)
    print(HEADER, flush=True)
    start = time.perf_counter()
    rows: list[Row] = []
    with contextlib.ExitStack() as stack:
        root = args.out or Path(stack.enter_context(tempfile.TemporaryDirectory(
            prefix="bench_motions_")))
        for clip in clips:
            for row in run_clip(clip, Path(root), args.modes, args.seconds, args.seed,
                                args.noise):
                rows.append(row)
                print(row.text(), flush=True)
    print(worst(rows).text())
    print(f"total {time.perf_counter() - start:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
