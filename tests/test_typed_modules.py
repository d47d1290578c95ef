"""The solver's modules compiled by mypyc (:mod:`ikfusion.native.typed_modules`).

Their build key and loader, and (when they are built for these sources: ``make test`` builds
them) solves by the compiled modules compared file by file with the Python modules' solves of
the same input: the real walk, a simulated walk corrected by UWB (``no-slide``: tag hints, the
correction's world moves) and simulated jumps (flights on the ballistic path, landings).
"""

from __future__ import annotations

import filecmp
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ikfusion.native import typed_modules as typed
from ikfusion.paths import module_source

ROOM = Path(__file__).resolve().parents[1] / "configs" / "constellations" / "room_6x8.yaml"
#: What differs between two solves of the same input by nature (wall-clock timings).
TIMED = {"solve_time.csv", "summary.json"}


def test_every_module_compiled_has_its_source() -> None:
    assert len(set(typed.MODULES)) == len(typed.MODULES)
    for module in typed.MODULES:
        assert module_source(module).is_file(), module


def test_the_build_key_follows_each_source(monkeypatch: pytest.MonkeyPatch,
                                           tmp_path: Path) -> None:
    modules = typed.MODULES[:3]
    copies = {m: tmp_path / f"{m}.py" for m in modules}
    for m, copy in copies.items():
        copy.write_bytes(module_source(m).read_bytes())
    monkeypatch.setattr(typed, "module_source", copies.__getitem__)
    key = typed.build_key(modules)
    assert typed.build_key(modules) == key
    copies[modules[1]].write_bytes(copies[modules[1]].read_bytes() + b"\n")
    assert typed.build_key(modules) != key  # an edited source: another build, never the stale one


def test_only_the_newest_builds_are_kept(tmp_path: Path) -> None:
    folders = [tmp_path / f"typed_{n}" for n in range(6)]
    for age, folder in enumerate(folders):  # typed_0 the newest
        (folder / "ikfusion").mkdir(parents=True)
        os.utime(folder, (1e9 - age, 1e9 - age))
    (tmp_path / "typed_other.so").write_bytes(b"")  # not a build folder
    kept = folders[4]  # the one just built (an older mtime than two others)
    removed = typed.prune_builds(kept, keep=3)
    assert sorted(removed) == sorted(folders[2:4] + folders[5:])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["typed_0", "typed_1", "typed_4",
                                                          "typed_other.so"]


def _child_env(typed_on: bool) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != typed.DISABLE}
    if not typed_on:
        env[typed.DISABLE] = "1"
    return env


def test_without_a_build_the_python_modules_are_used(tmp_path: Path) -> None:
    env = {**_child_env(True), "IKFUSION_CACHE": str(tmp_path)}
    script = ("import ikfusion, ikfusion.ik.solver as s, ikfusion.native.typed_modules as t;"
              "print(t.enabled(), s.__file__)")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out[0] == "False" and out[1].endswith(".py")


@pytest.fixture(scope="module")
def built() -> Path:
    """The build of these sources, when there is one (else the compiled solves skip)."""
    folder = typed.build_folder()
    if not (folder / typed.MANIFEST).is_file():
        pytest.skip(f"the compiled modules are not built for these sources ({folder}): "
                    "python -m ikfusion.native.compile_typed builds them")
    return folder


def _loaded_file(typed_on: bool) -> str:
    script = "import ikfusion, ikfusion.ik.contact_tracker as m; print(m.__file__)"
    return subprocess.run([sys.executable, "-c", script], env=_child_env(typed_on),
                          capture_output=True, text=True, check=True).stdout.strip()


def _solve(argv: list[str], out: Path, typed_on: bool) -> Path:
    done = subprocess.run([sys.executable, "-m", "ikfusion", *argv, "--out", str(out),
                           "--quiet"], env=_child_env(typed_on), capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return out


def _result_files(folder: Path) -> list[str]:
    """The result files of ``folder`` but the timings and the marker (it names its writer)."""
    return sorted(p.name for p in folder.iterdir()
                  if p.is_file() and p.name not in TIMED and not p.name.startswith("."))


def _assert_same_results(a: Path, b: Path) -> None:
    names = _result_files(a)
    assert names and names == _result_files(b)
    _, differ, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert not differ and not errors, f"files differ: {differ + errors}"
    summaries = [json.loads((d / "summary.json").read_text()) for d in (a, b)]
    for s in summaries:  # the timings differ by nature
        for key in ("solve_time_ms_mean", "solve_time_ms_p95"):
            s.pop(key, None)
    assert summaries[0] == summaries[1]


def test_the_compiled_modules_are_the_ones_loaded(built: Path) -> None:
    assert _loaded_file(True).startswith(str(built))
    assert _loaded_file(False).endswith(".py")


def test_the_real_walk_solves_bit_for_bit_as_the_python_modules(
        built: Path, shared_data: Path, tmp_path: Path) -> None:
    walk = shared_data / "xsens" / "opensense_walk"
    argv = ["solve", "--imu", str(walk), "--map", str(walk / "myIMUMappings.xml")]
    _assert_same_results(_solve(argv, tmp_path / "typed", True),
                         _solve(argv, tmp_path / "python", False))


@pytest.mark.parametrize("motion, seconds, correction", [
    ("gait", "12", "no-slide"),  # tag hints, the correction's world moves
    ("gait:jump", "8", None),  # flights: the ballistic path, landings
])
def test_a_simulated_capture_solves_bit_for_bit_as_the_python_modules(
        built: Path, tmp_path: Path, motion: str, seconds: str, correction: str | None) -> None:
    capture = tmp_path / "capture"
    subprocess.run([sys.executable, "-m", "ikfusion", "simulate", "--motion", motion,
                    "--seconds", seconds, "--readers", str(ROOM), "--seed", "4", "--out",
                    str(capture), "--quiet"], env=_child_env(False), check=True)
    argv = ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml")]
    if correction is not None:
        argv += ["--toa", str(capture / "toa.csv"), "--readers", str(capture / "readers.yaml"),
                 "--tags", str(capture / "tags.yaml"), "--correction", correction]
    _assert_same_results(_solve(argv, tmp_path / "typed", True),
                         _solve(argv, tmp_path / "python", False))
