"""End-to-end speed of ``ikfusion solve`` and ``ikfusion batch solve`` (issue #20), with peers.

1. Warm process: ``ikfusion.cli.main(["solve", ...])`` of the real 8-sensor walk
   (``../shared/data/xsens/opensense_walk``, 2505 frames) after one warm-up run; best and median
   of ``--repeat`` runs, split into stages (read, model, solver setup, calibrate, bridge,
   frames, solve loop, write, other = the rest of the command: sensor map, checks) and frames
   per second (wall clock, and by CPU time, which other work on a shared machine inflates
   least). Reading and calibration are included; interpreter start and the one-time compile
   are not.
2. Fresh process: what ``python -m ikfusion solve`` spends before and beyond the warm figure:
   interpreter start, imports (the heaviest packages named) and the first run's one-time cost
   (loading the solver's native step function, building its CasADi graph, first calls);
   ``--cold`` also times the compile of that function, paid once per machine (cache folder).
3. Peer: OpenSense (OpenSim's IMU inverse kinematics) on the same file in the same run, in a
   subprocess (OpenSim ships its own CasADi, which clashes with ours). It needs OpenSim's
   ``Rajagopal_2015.osim`` (``--opensim-model``; from opensim-core
   ``Bindings/Java/Matlab/OpenSenseExample/``); without OpenSim or the model the published
   figure (114 frames/s) is printed and marked so. OpenSense refuses trials whose files differ
   in length, so it reads a copy cut to the shortest file (2432 rows).
4. Batch: ``--copies`` copies of the first ``--batch-seconds`` of the walk through
   ``batch solve`` on 1 and 2 local Dask workers (the speed-up with the cluster's start
   included, and after it: the throughput once the workers run; CPU seconds of all processes
   beside the wall time).
5. ``--compare DIR_A DIR_B``: two result folders file by file (identical bytes, or the lines
   that differ and the largest difference of their numbers), to check that a speed-up left the
   results alone (``solve_time.csv`` and the timings in ``summary.json`` differ by nature).

Run: .venv/bin/python benchmarks/bench_solve.py [--repeat 5] [--no-fresh] [--cold] [--no-peer]
     [--no-batch] [--opensim-model PATH] | --compare DIR_A DIR_B
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

WALK = Path(__file__).resolve().parents[2] / "shared" / "data" / "xsens" / "opensense_walk"
MAPPING = "myIMUMappings.xml"
PUBLISHED_OPENSENSE_FPS = 114.0
TARGET_FACTOR = 30.0

#: Stage name -> (module, attribute) timed around every call during a solve.
STAGES: dict[str, tuple[str, str]] = {
    "read": ("ikfusion.app.session", "read_imu"),
    "model": ("ikfusion.app.session", "ActorInputs.model"),
    "solver setup": ("ikfusion.app.session", "Solver"),
    "calibrate": ("ikfusion.app.session", "calibrate_recording"),
    "bridge": ("ikfusion.app.pipeline", "bridged_segments"),
    "frames": ("ikfusion.app.pipeline", "frames_from_recording"),
    "solve loop": ("ikfusion.ik.solver", "Solver.solve"),
    "write": ("ikfusion.app.session", "write_result_folder"),
}


def solve_args(out: Path, imu: Path = WALK) -> list[str]:
    """The ``ikfusion solve`` command line of the benchmark."""
    return ["solve", "--imu", str(imu), "--map", str(WALK / MAPPING), "--out", str(out),
            "--quiet", "--force"]


@contextlib.contextmanager
def stage_timer() -> Iterator[dict[str, float]]:
    """Time the :data:`STAGES` functions (seconds summed per stage) while the block runs."""
    import importlib

    spent = dict.fromkeys(STAGES, 0.0)
    restore: list[tuple[Any, str, Any]] = []

    def timed(stage: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[stage] += time.perf_counter() - start
        return wrapper

    for stage, (module, attr) in STAGES.items():
        owner: Any = importlib.import_module(module)
        *path, name = attr.split(".")
        for part in path:
            owner = getattr(owner, part)
        original = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
        restore.append((owner, name, original))
        setattr(owner, name, timed(stage, original))
    try:
        yield spent
    finally:
        for owner, name, original in restore:
            setattr(owner, name, original)


def timed_solve(out: Path) -> dict[str, float]:
    """One in-process ``ikfusion solve`` of the walk: seconds per stage, ``total`` and
    ``other`` (the command's time outside the stages), ``cpu`` (CPU seconds of this process:
    on a busy machine the figure other work inflates least) and ``n_frames``."""
    from ikfusion.cli import main

    with stage_timer() as spent, contextlib.redirect_stderr(io.StringIO()), \
            contextlib.redirect_stdout(io.StringIO()):
        start, cpu = time.perf_counter(), time.process_time()
        code = main(solve_args(out))
        total, cpu = time.perf_counter() - start, time.process_time() - cpu
    if code != 0:
        raise SystemExit(f"ikfusion solve failed with exit code {code}")
    frames = json.loads((out / "summary.json").read_text())["frames"]
    return {**spent, "other": total - sum(spent.values()), "total": total, "cpu": cpu,
            "n_frames": float(frames)}


def warm_table(repeat: int) -> float:
    """Stages of ``repeat`` warm runs (after one warm-up); returns the best frames/s."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        timed_solve(out)  # warm-up: imports, native step functions, first calls
        runs = [timed_solve(out) for _ in range(repeat)]
    frames = int(runs[0]["n_frames"])
    from ikfusion.native.typed_modules import enabled

    modules = "compiled by mypyc" if enabled() else "Python (make typed compiles them)"
    print(f"ikfusion solve of opensense_walk ({frames} frames), warm process, {repeat} runs "
          f"after one warm-up; the solver's modules: {modules}")
    print(f"{'stage':12} {'best s':>8} {'median s':>8} {'share':>6}")
    best_total = min(r["total"] for r in runs)
    for stage in [*STAGES, "other", "total"]:
        values = [r[stage] for r in runs]
        share = statistics.median(values) / statistics.median(r["total"] for r in runs)
        print(f"{stage:12} {min(values):8.3f} {statistics.median(values):8.3f} {share:6.1%}")
    fps = frames / best_total
    median_fps = frames / statistics.median(r["total"] for r in runs)
    cpu_fps = frames / min(r["cpu"] for r in runs)
    print(f"frames/s end to end: best {fps:.0f}, median {median_fps:.0f}, by CPU time "
          f"{cpu_fps:.0f}; without the solve loop: "
          f"{frames / min(r['total'] - r['solve loop'] for r in runs):.0f}")
    load = os.getloadavg()[0]
    if load > 0.5 * (os.cpu_count() or 1):
        print(f"(load average {load:.1f} on {os.cpu_count()} cores: other work shares the "
              "machine; the CPU-time figure is the steadier one)")
    return fps


FRESH_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
import ikfusion.cli
t1 = time.perf_counter()
sys.path.insert(0, sys.argv[1])
from bench_solve import timed_solve
from pathlib import Path
first = timed_solve(Path(sys.argv[2]))
second = timed_solve(Path(sys.argv[2]))
print(json.dumps({"import": t1 - t0, "first": first, "second": second}))
"""


COLD_CHILD = r"""
import json, time
start = time.perf_counter()
from ikfusion.ik import Solver
from ikfusion.model import HumanModel
model = HumanModel.default()
imported = time.perf_counter()
Solver(model)
print(json.dumps({"import": imported - start, "solver": time.perf_counter() - imported}))
"""


def cold_compile_row(env: dict[str, str]) -> None:
    """The once-per-machine compile of the solver's step function (an empty cache)."""
    with tempfile.TemporaryDirectory() as cache:
        done = subprocess.run([sys.executable, "-c", COLD_CHILD], check=True, text=True,
                              capture_output=True, env={**env, "IKFUSION_CACHE": cache},
                              cwd=cache)
    r = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"  once per machine (empty IKFUSION_CACHE): Solver() compiles its step function in "
          f"{r['solver']:.1f} s (cached afterwards under ~/.cache/ikfusion)")


def heaviest_imports(stderr: str, top: int = 8) -> list[tuple[str, float]]:
    """The packages of ``-X importtime`` output that took longest to import [s].

    A package's time is the cumulative time of its outermost imports (those not made while
    importing the same package), so ``scipy`` pulled in by an ikfusion module counts for scipy;
    ikfusion's own figure excludes the packages it pulls in.
    """
    entries = []  # (depth, package, cumulative [s], self [s]) in the order imports finish
    for line in stderr.splitlines():
        if not line.startswith("import time:") or line.count("|") != 2:
            continue
        own, cumulative, name = line[len("import time:"):].split("|")
        if not cumulative.strip().isdigit():
            continue  # the header line
        depth = (len(name) - len(name.lstrip())) // 2
        entries.append((depth, name.strip().split(".")[0], int(cumulative) * 1e-6,
                        int(own) * 1e-6))
    per_package: dict[str, float] = {}
    # an import finishes after the imports it made: walk backwards to know each one's parents
    stack: list[tuple[int, str]] = []
    for depth, package, cumulative, own in reversed(entries):
        while stack and stack[-1][0] >= depth:
            stack.pop()
        if package == "ikfusion":
            per_package[package] = per_package.get(package, 0.0) + own
        elif all(p != package for _, p in stack):
            per_package[package] = per_package.get(package, 0.0) + cumulative
        stack.append((depth, package))
    return sorted(per_package.items(), key=lambda kv: -kv[1])[:top]


def fresh_table(cold: bool) -> None:
    """What a fresh ``python -m ikfusion solve`` spends beyond the warm run (and, with
    ``cold``, the compile a machine's first solve pays)."""
    import ikfusion

    package_root = str(Path(ikfusion.__file__).resolve().parents[1])  # the ikfusion measured
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [package_root, *filter(None, [os.environ.get("PYTHONPATH")])])}
    with tempfile.TemporaryDirectory() as tmp:
        # run in an empty folder: `python -c` puts the current folder first on the path, which
        # would shadow the ikfusion of PYTHONPATH with a checkout's
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], check=True, env=env, cwd=tmp)
        interpreter = time.perf_counter() - start
        done = subprocess.run([sys.executable, "-X", "importtime", "-c", FRESH_CHILD,
                               str(Path(__file__).parent), str(Path(tmp) / "out")],
                              check=True, env=env, capture_output=True, text=True, cwd=tmp)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    first, second = result["first"], result["second"]
    print("\nfresh process (python -m ikfusion solve): where the start-up time goes")
    print(f"  interpreter start                 {interpreter:6.2f} s")
    print(f"  import ikfusion.cli               {result['import']:6.2f} s")
    print(f"  first solve                       {first['total']:6.2f} s "
          f"(second, warm: {second['total']:.2f} s)")
    extra = {s: first[s] - second[s] for s in [*STAGES, "other"]}
    for stage, seconds in sorted(extra.items(), key=lambda kv: -kv[1])[:4]:
        print(f"    one-time in {stage:12}         {seconds:6.2f} s")
    print("  heaviest imports (cumulative, -X importtime; imports made inside the first solve "
          "included):")
    for package, seconds in heaviest_imports(done.stderr):
        print(f"    {package:30} {seconds:6.2f} s")
    if cold:
        cold_compile_row(env)


PEER_CHILD = r"""
import json, sys, time
from pathlib import Path
import opensim as osim
trial, model, work = (Path(a) for a in sys.argv[1:4])
osim.Logger.setLevelString("error")
t0 = time.perf_counter()
settings = osim.XsensDataReaderSettings(str(trial / "myIMUMappings.xml"))
reader = osim.XsensDataReader(settings)
tables = reader.read(str(trial) + "/")  # kept alive: the table below points into it
quat = reader.getOrientationsTable(tables)
orientations = str(work / "orientations.sto")
osim.STOFileAdapterQuaternion.write(quat, orientations)
t1 = time.perf_counter()
to_opensim = osim.Vec3(-1.5707963267948966, 0, 0)  # as in the OpenSense example
placer = osim.IMUPlacer()
placer.set_model_file(str(model))
placer.set_orientation_file_for_calibration(orientations)
placer.set_sensor_to_opensim_rotations(to_opensim)
placer.set_base_imu_label("pelvis_imu")
placer.set_base_heading_axis("z")
placer.run(False)
calibrated = str(work / "calibrated.osim")
placer.getCalibratedModel().printToXML(calibrated)
t2 = time.perf_counter()
times = quat.getIndependentColumn()
ik = osim.IMUInverseKinematicsTool()
ik.set_model_file(calibrated)
ik.set_orientations_file(orientations)
ik.set_sensor_to_opensim_rotations(to_opensim)
ik.set_time_range(0, times[0])
ik.set_time_range(1, times[-1])
ik.set_results_directory(str(work / "ik"))
ik.run(False)
t3 = time.perf_counter()
print(json.dumps({"frames": len(times), "read": t1 - t0, "calibrate": t2 - t1, "ik": t3 - t2}))
"""


def equal_length_copy(trial: Path, folder: Path, rows: int | None = None) -> int:
    """Copy the walk's MT Manager files cut to the shortest file (or ``rows``) data rows."""
    split = {}
    for path in sorted(trial.glob("*.txt")):
        lines = path.read_text().splitlines()
        header = next(k for k, line in enumerate(lines) if line.startswith("PacketCounter"))
        split[path.name] = (lines[:header + 1], [ln for ln in lines[header + 1:] if ln.strip()])
    n = min(len(data) for _, data in split.values())
    n = n if rows is None else min(n, rows)
    folder.mkdir(parents=True, exist_ok=True)
    for name, (head, data) in split.items():
        (folder / name).write_text("\n".join(head + data[:n]) + "\n")
    return n


def peer_row(model: Path | None) -> float:
    """OpenSense's IMU IK frames/s on the walk, measured in a subprocess when possible."""
    found = subprocess.run([sys.executable, "-c", "import opensim"], capture_output=True)
    reason = None
    if found.returncode != 0:
        reason = "opensim is not importable (pip install '.[opensim]')"
    elif model is None or not model.is_file():
        reason = (f"no OpenSim model at {model} (Rajagopal_2015.osim of opensim-core "
                  "Bindings/Java/Matlab/OpenSenseExample; give --opensim-model)")
    if reason is not None:
        print(f"\nOpenSense peer: published {PUBLISHED_OPENSENSE_FPS:.0f} frames/s "
              f"(not measured: {reason})")
        return PUBLISHED_OPENSENSE_FPS
    with tempfile.TemporaryDirectory() as tmp:
        trial = Path(tmp) / "trial"
        equal_length_copy(WALK, trial)
        (trial / MAPPING).write_text((WALK / MAPPING).read_text())
        done = subprocess.run([sys.executable, "-c", PEER_CHILD, str(trial), str(model), tmp],
                              check=True, capture_output=True, text=True, cwd=tmp)
    r = json.loads(done.stdout.strip().splitlines()[-1])
    fps = r["frames"] / r["ik"]
    print(f"\nOpenSense peer (measured now, OpenSim IMU IK on the same walk, {r['frames']} "
          f"frames cut to equal length): read {r['read']:.2f} s, IMUPlacer {r['calibrate']:.2f} "
          f"s, IMU IK {r['ik']:.2f} s = {fps:.0f} frames/s (published: "
          f"{PUBLISHED_OPENSENSE_FPS:.0f})")
    return fps


def batch_table(copies: int, seconds: float) -> None:
    """``batch solve`` of ``copies`` copies of the walk's first ``seconds`` on 1 and 2 workers."""
    from batch_timing import batch_rows, print_batch_rows  # Dask: not in the fresh process

    with tempfile.TemporaryDirectory() as tmp:
        inputs = []
        for k in range(copies):
            folder = Path(tmp) / f"walk{k:02d}"
            rows = equal_length_copy(WALK, folder, round(100 * seconds))
            inputs.append(str(folder))
        print(f"\nbatch solve: {copies} copies of the walk's first {rows} frames, 1 vs 2 local "
              f"workers (speed-up with the cluster start and after it; {os.cpu_count()} cores)")
        print_batch_rows(batch_rows("solve", inputs, {"map": str(WALK / MAPPING)}))


NUMBER = re.compile(r"-?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|nan|inf)")


def compare_folders(a: Path, b: Path) -> None:
    """Print, per file of ``a``, whether ``b`` holds the same bytes or how far apart they are."""
    for file in sorted(p for p in a.iterdir() if p.is_file()):
        other = b / file.name
        if not other.is_file():
            print(f"{file.name:18} missing in {b}")
            continue
        if file.read_bytes() == other.read_bytes():
            print(f"{file.name:18} identical")
            continue
        lines_a, lines_b = file.read_text().splitlines(), other.read_text().splitlines()
        differing = [(x, y) for x, y in zip(lines_a, lines_b) if x != y]
        worst = 0.0
        for x, y in differing:
            nx, ny = NUMBER.findall(x), NUMBER.findall(y)
            if len(nx) != len(ny):
                worst = math.inf
                continue
            for u, v in zip(nx, ny):
                if u != v:
                    worst = max(worst, abs(float(u) - float(v)))
        print(f"{file.name:18} {len(differing)} of {len(lines_a)} lines differ "
              f"(line count {len(lines_a)} vs {len(lines_b)}), largest number difference "
              f"{worst:.3g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="warm runs after the warm-up")
    parser.add_argument("--no-fresh", action="store_true", help="skip the fresh process")
    parser.add_argument("--cold", action="store_true",
                        help="also time the once-per-machine compile (an empty cache; 10-30 s)")
    parser.add_argument("--no-peer", action="store_true", help="skip OpenSense")
    parser.add_argument("--no-batch", action="store_true", help="skip the batch throughput")
    parser.add_argument("--opensim-model", type=Path, default=WALK / "Rajagopal_2015.osim",
                        help="OpenSim's Rajagopal_2015.osim for the OpenSense peer")
    parser.add_argument("--copies", type=int, default=8, help="batch inputs")
    parser.add_argument("--batch-seconds", type=float, default=30.0,
                        help="length of each batch input [s] (the walk is 24 s long)")
    parser.add_argument("--compare", nargs=2, type=Path, metavar="DIR",
                        help="compare two result folders and stop")
    args = parser.parse_args()
    if args.compare:
        compare_folders(*args.compare)
        return
    if not WALK.is_dir():
        raise SystemExit(f"no recording at {WALK} (../shared/data beside the repository)")
    fps = warm_table(args.repeat)
    if not args.no_fresh:
        fresh_table(args.cold)
    peer = PUBLISHED_OPENSENSE_FPS if args.no_peer else peer_row(args.opensim_model)
    print(f"\nikfusion {fps:.0f} frames/s = {fps / peer:.1f}x OpenSense "
          f"(issue #20 asks {TARGET_FACTOR:.0f}x = {TARGET_FACTOR * peer:.0f} frames/s)")
    if not args.no_batch:
        batch_table(args.copies, args.batch_seconds)


if __name__ == "__main__":
    main()
