"""`ikfusion batch solve`: bad inputs in a batch, interrupt and resume, an external scheduler.

One short capture (1 s at 30 Hz, perfect sensors) is simulated once per module and copied into
as many input folders as a test needs.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from ikfusion.atomic import temporary_name  # noqa: E402
from ikfusion.batch import (  # noqa: E402
    REPORT_NAME,
    STAMP_NAME,
    BatchInput,
    JobKind,
    JobOutput,
    expand_paths,
    load_kind,
    output_names,
)
from ikfusion.batch.fingerprint import fingerprint  # noqa: E402
from ikfusion.batch.report import JobResult, exit_code  # noqa: E402
from ikfusion.batch.runner import run_batch  # noqa: E402
from ikfusion.cli import build_parser, main  # noqa: E402
from ikfusion.errors import InputError  # noqa: E402
from ikfusion.output_folders import MARKER_NAME  # noqa: E402

#: The MT Manager file made corrupt, and the line cut short in it.
CORRUPT_FILE = "SIM_00B50003.txt"
CORRUPT_LINE = 13


@pytest.fixture(scope="module")
def capture(tmp_path_factory) -> Path:
    """One simulated capture folder (imu/, sensors.yaml, body.yaml), without the truth."""
    from ikfusion.sim.capture import truth_motion, write_capture

    folder = tmp_path_factory.mktemp("capture") / "capture"
    write_capture(folder, truth_motion("gait:straight", seconds=1.0, rate=30), None, seed=3)
    (folder / "truth.npz").unlink()
    return folder


def make_inputs(capture: Path, root: Path, count: int, corrupt: int | None = None) -> list[Path]:
    """``count`` copies of the capture as ``root/capNN``; copy ``corrupt`` gets a cut line."""
    root.mkdir(parents=True)
    folders = []
    for i in range(count):
        folder = root / f"cap{i:02d}"
        shutil.copytree(capture, folder)
        folders.append(folder)
    if corrupt is not None:
        path = folders[corrupt] / "imu" / CORRUPT_FILE
        lines = path.read_text().split("\n")
        lines[CORRUPT_LINE - 1] = lines[CORRUPT_LINE - 1][:20]
        path.write_text("\n".join(lines))
    return folders


def read_report(out: Path) -> dict[str, dict[str, str]]:
    """The report rows keyed by input folder name."""
    with (out / REPORT_NAME).open() as f:
        rows = list(csv.DictReader(f))
    assert rows and list(rows[0]) == ["input", "status", "error", "frames", "seconds"]
    return {Path(r["input"]).name: r for r in rows}


def hidden_entries(out: Path) -> list[str]:
    """Partial or stale folders left in the batch folder (its marker aside)."""
    return [p.name for p in out.iterdir() if p.name.startswith(".") and p.name != MARKER_NAME]


def assert_complete(folder: Path, frames: int) -> None:
    """A whole solve output with its resume stamp."""
    for name in ("motion.bvh", "joint_angles.csv", "segments.csv", "summary.json", STAMP_NAME):
        assert (folder / name).is_file(), f"{folder / name} missing"
    assert json.loads((folder / "summary.json").read_text())["frames"] == frames
    assert json.loads((folder / STAMP_NAME).read_text())["frames"] == frames


def mtimes(folder: Path) -> dict[str, int]:
    """Modification times of the files of an output folder [ns]."""
    return {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}


def test_output_names_are_unique_and_readable(tmp_path: Path) -> None:
    items = [BatchInput(str(tmp_path / d / "imu" / "SIM_"), "SIM", (), None) for d in "ab"]
    items.append(BatchInput(str(tmp_path / "c"), "c", (), None))
    assert output_names(items) == ["a-imu-SIM", "b-imu-SIM", "c"]
    same = [BatchInput(str(tmp_path / "x.csv"), "x", (), None),
            BatchInput(str(tmp_path / "x.mvnx"), "x", (), None)]
    first, second = output_names(same)
    assert first != second and first.startswith("x-") and second.startswith("x-")


def test_fingerprint_follows_contents_and_options(tmp_path: Path) -> None:
    path = tmp_path / "a.txt"
    path.write_text("1\n")
    base = fingerprint("solve", "0.1.0", {"bvh_up": "z"}, [path])
    assert fingerprint("solve", "0.1.0", {"bvh_up": "z"}, [path]) == base
    assert fingerprint("solve", "0.1.0", {"bvh_up": "y"}, [path]) != base
    assert fingerprint("solve", "0.2.0", {"bvh_up": "z"}, [path]) != base
    path.write_text("2\n")
    assert fingerprint("solve", "0.1.0", {"bvh_up": "z"}, [path]) != base


def test_exit_code_bad_input_2_internal_1() -> None:
    ok = JobResult("a", "a", "ok")
    bad = JobResult("b", "b", "failed", "b.txt, line 3: bad", bad_input=True)
    broken = JobResult("c", "c", "failed", "RuntimeError: boom")
    assert exit_code([ok, JobResult("s", "s", "skipped")]) == 0
    assert exit_code([ok, bad]) == 2
    assert exit_code([ok, bad, broken]) == 1


def _expand_text_files(inputs, options) -> list[BatchInput]:
    return [BatchInput(str(p), p.stem, (p,), str(p.resolve())) for p in expand_paths(inputs)]


def _count_lines(source: str, out_dir: Path, options) -> JobOutput:
    text = Path(source).read_text()
    if text.startswith("bad"):
        raise InputError("expected a number", path=source, line=1, field="value")
    if text.startswith("boom"):
        raise RuntimeError("boom")
    lines = text.splitlines() * options["repeat"]
    (out_dir / "copy.txt").write_text("\n".join(lines))
    return JobOutput(frames=len(lines))


def test_a_new_job_kind_plugs_in(tmp_path: Path) -> None:
    """A kind is (expand, run, options): here a toy one, run through the same machinery."""
    kind = JobKind("count", "count lines", "count lines", (), _expand_text_files, _count_lines)
    (tmp_path / "in").mkdir()
    for name, text in [("one", "1\n2\n"), ("two", "bad\n"), ("three", "boom\n")]:
        (tmp_path / "in" / f"{name}.txt").write_text(text)
    out = tmp_path / "out"
    outcome = run_batch(kind, [str(tmp_path / "in" / "*.txt")], out, {"repeat": 2},
                        workers=1, progress=False)
    assert outcome.exit_code == 1
    rows = read_report(out)
    assert (rows["one.txt"]["status"], rows["one.txt"]["frames"]) == ("ok", "4")
    assert rows["two.txt"]["status"] == "failed"
    assert "two.txt, line 1, field 'value'" in rows["two.txt"]["error"]
    assert rows["three.txt"]["error"] == "RuntimeError: boom"
    assert sorted(p.name for p in out.iterdir()) == [MARKER_NAME, "batch_report.csv", "one"]


def test_the_largest_inputs_go_first(tmp_path: Path) -> None:
    """One worker takes the inputs largest first, whatever their order on the command line."""
    from probe_kind import PROBE

    sizes = {"a_small": 10, "b_large": 5000, "c_medium": 800, "d_tiny": 1, "e_big": 3000}
    (tmp_path / "in").mkdir()
    for name, size in sizes.items():
        (tmp_path / "in" / f"{name}.txt").write_text("x" * size)
    log = tmp_path / "order.txt"
    outcome = run_batch(PROBE, [str(tmp_path / "in" / "*.txt")], tmp_path / "out",
                        {"log": str(log)}, workers=1, progress=False)
    assert outcome.exit_code == 0
    assert [r.input for r in outcome.results] == sorted(str(p) for p in (tmp_path / "in").iterdir())
    assert log.read_text().split() == sorted(sizes, key=lambda name: -sizes[name])


def test_bad_input_is_reported_and_the_others_run(capture: Path, tmp_path: Path,
                                                  capsys) -> None:
    make_inputs(capture, tmp_path / "in", 20, corrupt=7)
    out = tmp_path / "out"
    start = time.perf_counter()
    code = main(["batch", "solve", str(tmp_path / "in" / "cap*"), "--out", str(out),
                 "--workers", "2", "--quiet"])
    print(f"20 inputs in {time.perf_counter() - start:.1f} s")
    assert code == 2
    report = read_report(out)
    assert len(report) == 20
    bad = report.pop("cap07")
    assert bad["status"] == "failed"
    assert CORRUPT_FILE in bad["error"] and f"line {CORRUPT_LINE}" in bad["error"]
    assert not (out / "cap07").exists()
    assert {r["status"] for r in report.values()} == {"ok"}
    for name, row in report.items():
        assert int(row["frames"]) == 30
        assert_complete(out / name, 30)
    assert hidden_entries(out) == []
    assert "cap07" in capsys.readouterr().err


def test_interrupted_batch_resumes_without_recomputing(capture: Path, tmp_path: Path) -> None:
    make_inputs(capture, tmp_path / "in", 5)
    out = tmp_path / "out"
    pattern = str(tmp_path / "in" / "cap*")
    kind = load_kind("solve")
    args = build_parser().parse_args(["batch", "solve", pattern, "--out", str(out)])
    options = {o.dest: getattr(args, o.dest) for o in kind.options}
    finished = []

    def interrupt_after_two(result) -> None:
        finished.append(result)
        if len(finished) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(kind, [pattern], out, options, workers=1, progress=False,
                  on_result=interrupt_after_two)
    # The report lists what finished: the two seen, and any the worker completed before the
    # cluster stopped (whole, with their stamp).
    report = read_report(out)
    done = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert 2 <= len(done) < 5 and sorted(report) == done
    assert {r["status"] for r in report.values()} == {"ok"}
    assert hidden_entries(out) == []
    for name in done:
        assert_complete(out / name, 30)
    before = {name: mtimes(out / name) for name in done}
    stale = temporary_name(out / "cap04")  # what a killed run leaves behind
    stale.mkdir()
    (stale / "motion.bvh").write_text("half")

    assert main(["batch", "solve", pattern, "--out", str(out), "--workers", "1",
                 "--quiet"]) == 0
    report = read_report(out)
    assert len(report) == 5
    assert {n for n, r in report.items() if r["status"] == "skipped"} == set(done)
    assert {r["status"] for n, r in report.items() if n not in done} == {"ok"}
    assert all(int(r["frames"]) == 30 for r in report.values())
    assert {name: mtimes(out / name) for name in done} == before
    assert hidden_entries(out) == []

    assert main(["batch", "solve", pattern, "--out", str(out), "--workers", "1", "--quiet",
                 "--bvh-up", "y"]) == 0
    assert {r["status"] for r in read_report(out).values()} == {"ok"}


#: Runs ``python ARGS...`` with SIGINT at its default and unblocked (exec keeps both).
AS_FROM_A_TERMINAL = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
                      "signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT}); "
                      "os.execv(sys.executable, [sys.executable, *sys.argv[1:]])")


def _signal_state(pid: int) -> str:
    """The process's blocked and ignored signal masks (Linux), for a failure's message."""
    try:
        lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    except OSError:
        return "unknown"
    return ", ".join(line for line in lines if line.startswith(("SigBlk", "SigIgn")))


def test_ctrl_c_stops_cleanly(capture: Path, tmp_path: Path) -> None:
    """SIGINT to the whole process group, as a terminal's Ctrl-C sends it."""
    count = 40  # enough that the run is still busy when the signal comes, even on a loaded host
    make_inputs(capture, tmp_path / "in", count)
    out = tmp_path / "out"
    command = ["-m", "ikfusion", "batch", "solve", str(tmp_path / "in" / "cap*"),
               "--out", str(out), "--workers", "1", "--quiet"]
    process = subprocess.Popen(
        # started as from a terminal: SIGINT neither ignored nor blocked, whatever the tests
        # before left in this process (both are inherited, and Python then keeps them)
        [sys.executable, "-c", AS_FROM_A_TERMINAL, *command],
        cwd=tmp_path, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        deadline = time.monotonic() + 90
        while not (out.is_dir() and any(p.name.startswith("cap") for p in out.iterdir())):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        state = _signal_state(process.pid)
        os.killpg(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=10)
    assert process.returncode == 130, f"{err}\n(its signal state before SIGINT: {state})"
    assert "Traceback" not in err and "interrupted" in err
    report = read_report(out)
    done = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert 1 <= len(done) < count and sorted(report) == done
    for name in done:
        assert_complete(out / name, 30)
    assert hidden_entries(out) == []


def _wait_for(path: Path, process: subprocess.Popen, seconds: float) -> None:
    """Wait until ``path`` exists (bounded); fail early if ``process`` died."""
    deadline = time.monotonic() + seconds
    while not path.exists():
        if process.poll() is not None:
            raise RuntimeError(f"{process.args[2]} exited with {process.returncode}")
        if time.monotonic() > deadline:
            raise TimeoutError(f"{path} did not appear within {seconds} s")
        time.sleep(0.2)


def _stop(process: subprocess.Popen) -> None:
    """Terminate a process, killing it if it does not stop within 10 s."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=10)


def test_batch_on_an_external_scheduler(capture: Path, tmp_path: Path) -> None:
    make_inputs(capture, tmp_path / "in", 3)
    out = tmp_path / "out"
    scheduler_file = tmp_path / "scheduler.json"
    logs = (tmp_path / "scheduler.log").open("w"), (tmp_path / "worker.log").open("w")
    processes: list[subprocess.Popen] = []
    try:
        processes.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(scheduler_file)],
            cwd=tmp_path, stdout=logs[0], stderr=subprocess.STDOUT))
        _wait_for(scheduler_file, processes[0], 60)
        address = json.loads(scheduler_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        processes.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
             "--nworkers", "1", "--host", "127.0.0.1", "--no-dashboard", "--no-nanny",
             "--local-directory", str(tmp_path / "worker"), "--death-timeout", "60"],
            cwd=tmp_path, stdout=logs[1], stderr=subprocess.STDOUT))
        code = main(["batch", "solve", str(tmp_path / "in" / "cap*"), "--out", str(out),
                     "--scheduler", address, "--quiet"])
        assert code == 0
        report = read_report(out)
        assert sorted(report) == ["cap00", "cap01", "cap02"]
        assert {r["status"] for r in report.values()} == {"ok"}
        for name in report:
            assert_complete(out / name, 30)
    finally:
        for process in reversed(processes):
            _stop(process)
        for log in logs:
            log.close()


def test_resume_redoes_an_output_whose_files_are_gone(capture: Path, tmp_path: Path) -> None:
    """batch.json alone does not make an input done: the kind's files must be there too."""
    make_inputs(capture, tmp_path / "in", 3)
    out = tmp_path / "out"
    argv = ["batch", "solve", str(tmp_path / "in" / "cap*"), "--out", str(out), "--workers",
            "1", "--quiet"]
    assert main(argv) == 0
    (out / "cap00" / "summary.json").unlink()
    (out / "cap01" / "joint_angles.csv").unlink()
    assert main(argv) == 0
    report = read_report(out)
    assert {n: r["status"] for n, r in report.items()} == {
        "cap00": "ok", "cap01": "ok", "cap02": "skipped"}
    for name in report:
        assert_complete(out / name, 30)


def test_batch_refuses_folders_it_did_not_write(capture: Path, tmp_path: Path,
                                                capsys) -> None:
    make_inputs(capture, tmp_path / "in", 2)
    pattern = str(tmp_path / "in" / "cap*")
    out = tmp_path / "out"
    (out / "docs").mkdir(parents=True)
    (out / "docs" / "thesis.txt").write_text("mine")
    assert main(["batch", "solve", pattern, "--out", str(out), "--quiet"]) == 2
    assert "not written by ikfusion" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["docs"]
    # a batch folder of ours where a user put a folder named like an output
    out = tmp_path / "out2"
    assert main(["batch", "solve", pattern, "--out", str(out), "--workers", "1",
                 "--quiet"]) == 0
    shutil.rmtree(out / "cap01")
    (out / "cap01" / "docs").mkdir(parents=True)
    (out / "cap01" / "docs" / "thesis.txt").write_text("mine")
    assert main(["batch", "solve", pattern, "--out", str(out), "--workers", "1",
                 "--quiet"]) == 2
    assert (out / "cap01" / "docs" / "thesis.txt").read_text() == "mine"
    assert main(["batch", "solve", pattern, "--out", str(out), "--workers", "1", "--quiet",
                 "--force"]) == 0
    assert_complete(out / "cap01", 30)


def _short_clip(source: Path, target: Path, frames: int) -> Path:
    """The first ``frames`` frames of a BVH clip."""
    lines = source.read_text().splitlines()
    motion = next(i for i, line in enumerate(lines) if line.strip() == "MOTION")
    lines = lines[:motion + 3 + frames]
    lines[motion + 1] = f"Frames: {frames}"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text("\n".join(lines) + "\n")
    return target


def test_batch_retarget_of_a_folder_of_clips(shared_data: Path, tmp_path: Path) -> None:
    """A folder of BVH files was refused ("expected a solve result folder"); it expands to its
    clips, nested folders included, and a result folder inside stays one input."""
    clips = tmp_path / "clips"
    walk = _short_clip(shared_data / "mocap" / "cmu_02_01_walk.bvh", clips / "walk.bvh", 90)
    jog = _short_clip(shared_data / "mocap" / "sfu_0005_Jogging001.bvh",
                      clips / "sfu" / "jog.bvh", 60)
    result = clips / "solved"
    result.mkdir()
    (result / "segments.csv").write_text("time,segment,px,py,pz,qw,qx,qy,qz\n")
    (result / "contacts.csv").write_text("time\n")
    (result / "motion.bvh").write_text("part of the result folder, not a clip\n")
    (clips / "notes.txt").write_text("not a clip\n")
    kind = load_kind("retarget")
    items = kind.expand([str(clips)], {"robot": "human", "height": 1.6})
    assert [Path(i.source) for i in items] == [jog.resolve(), result.resolve(), walk.resolve()]
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="holds no") as info:
        kind.expand([str(empty)], {"robot": "human", "height": 1.6})
    assert info.value.path == empty
    shutil.rmtree(result)
    out = tmp_path / "batch"
    assert main(["batch", "retarget", str(clips), "--robot", "human", "--height", "1.6",
                 "--workers", "1", "--out", str(out)]) == 0
    report = read_report(out)
    assert sorted(report) == ["jog.bvh", "walk.bvh"]
    assert all(row["status"] == "ok" for row in report.values())
    assert len(list(out.glob("*/robot_motion.npz"))) == 2
