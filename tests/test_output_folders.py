"""Output folders: only folders ikfusion wrote are replaced or written into without --force.

One short capture (3 s at 30 Hz, perfect sensors) and its solve result serve every test; a
"foreign" folder is one a user made, holding ``docs/thesis.txt``.
"""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ikfusion.app.session import load_session
from ikfusion.cli import main
from ikfusion.errors import ConfigError, InputError

MARKER_NAME = ".ikfusion.json"


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from ikfusion.sim.capture import truth_motion, write_capture

    folder = tmp_path_factory.mktemp("capture") / "capture"
    write_capture(folder, truth_motion("gait:straight", seconds=3.0, rate=30), None, seed=3)
    return folder


@pytest.fixture(scope="module")
def result(capture: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("solved") / "result"
    assert main(solve_args(capture, out)) == 0
    return out


def solve_args(capture: Path, out: Path | str, *more: str) -> list[str]:
    return ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml"), "--out", str(out), "--quiet", *more]


def foreign(folder: Path) -> Path:
    """A user's folder with a file that must survive: returns that file."""
    thesis = folder / "docs" / "thesis.txt"
    thesis.parent.mkdir(parents=True)
    thesis.write_text("three years of work")
    return thesis


def assert_refused(code: int, capsys: pytest.CaptureFixture[str], thesis: Path) -> None:
    """Exit 2 naming the marker and --force, and the user's file untouched."""
    err = capsys.readouterr().err
    assert code == 2, err
    assert "not written by ikfusion" in err and "--force" in err
    assert thesis.read_text() == "three years of work"
    assert not [p for p in thesis.parents[1].parent.iterdir() if ".partial-" in p.name]


def test_solve_keeps_a_folder_it_did_not_write(capture: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "mine"
    thesis = foreign(out)
    assert_refused(main(solve_args(capture, out)), capsys, thesis)
    # an empty folder may be used, and a folder ikfusion wrote is replaced
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(solve_args(capture, empty)) == 0
    marker = json.loads((empty / MARKER_NAME).read_text())
    assert marker["written_by"] == "ikfusion" and marker["command"] == "solve"
    assert main(solve_args(capture, empty)) == 0
    # --force replaces the foreign folder
    assert main(solve_args(capture, out, "--force")) == 0
    assert not thesis.exists() and (out / "summary.json").is_file()


def test_solve_never_replaces_the_current_or_home_folder(capture: Path, tmp_path: Path,
                                                         monkeypatch, capsys) -> None:
    work = tmp_path / "work" / "here"
    work.mkdir(parents=True)
    (work / "notes.txt").write_text("keep")
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(work)
    for out, why in ((".", "the current folder"), ("..", "holds the current folder"),
                     (str(home), "the home folder"), ("/", "file-system root")):
        for force in ((), ("--force",)):
            assert main(solve_args(capture, out, *force)) == 2
            assert why in capsys.readouterr().err
    assert sorted(p.name for p in work.iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in work.parent.iterdir()) == ["here"]


def test_every_folder_writer_refuses_a_foreign_folder(capture: Path, result: Path,
                                                      tmp_path: Path, capsys) -> None:
    out = tmp_path / "mine"
    thesis = foreign(out)
    assert_refused(main(["simulate", "--seconds", "3", "--out", str(out), "--quiet"]), capsys,
                   thesis)
    assert_refused(main(["retarget", str(result), "--height", "1.6", "--out", str(out),
                         "--quiet"]), capsys, thesis)
    assert_refused(main(["demo", "--seconds", "5", "--out", str(out), "--quiet"]), capsys,
                   thesis)
    # a demo folder of ours whose capture/ a user made
    from ikfusion.output_folders import write_marker

    demo = tmp_path / "demo"
    thesis = foreign(demo / "capture")
    write_marker(demo, "demo")
    assert_refused(main(["demo", "--seconds", "5", "--out", str(demo), "--quiet"]), capsys,
                   thesis)


def test_retarget_replaces_its_own_output(result: Path, tmp_path: Path) -> None:
    out = tmp_path / "robot"
    for _ in range(2):
        assert main(["retarget", str(result), "--height", "1.6", "--out", str(out),
                     "--quiet"]) == 0
    assert json.loads((out / MARKER_NAME).read_text())["command"] == "retarget"


def write_session(capture: Path, folder: Path, actor: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "session.yaml"
    path.write_text(yaml.safe_dump({"actors": {actor: {
        "imu": str(capture / "imu"), "map": str(capture / "sensors.yaml")}}}))
    return path


@pytest.mark.parametrize("actor", ["../../esc_actor", "../victim", "/tmp/absolute_actor", ".",
                                   "..", "a/b", "tab\there", ""])
def test_session_actor_names_stay_inside_out(capture: Path, tmp_path: Path, actor: str) -> None:
    session = write_session(capture, tmp_path / "s", actor)
    with pytest.raises(ConfigError) as err:
        load_session(session)
    assert str(session) in str(err.value) and repr(actor) in str(err.value)


def test_session_actor_cannot_empty_a_neighbour(capture: Path, tmp_path: Path, capsys) -> None:
    victim = tmp_path / "victim"
    thesis = foreign(victim)
    session = write_session(capture, tmp_path / "s", "../victim")
    assert main(["solve", "--session", str(session), "--out", str(tmp_path / "out"),
                 "--quiet"]) == 2
    assert "'../victim'" in capsys.readouterr().err
    assert thesis.read_text() == "three years of work"


def test_session_out_and_actor_folders_are_guarded(capture: Path, tmp_path: Path,
                                                   capsys) -> None:
    session = write_session(capture, tmp_path / "s", "alice")
    out = tmp_path / "out"
    thesis = foreign(out)
    assert_refused(main(["solve", "--session", str(session), "--out", str(out), "--quiet"]),
                   capsys, thesis)
    out2 = tmp_path / "out2"
    out2.mkdir()
    thesis2 = foreign(out2 / "alice")
    assert main(["solve", "--session", str(session), "--out", str(out2), "--quiet"]) == 2
    assert thesis2.read_text() == "three years of work"
    capsys.readouterr()
    assert main(["solve", "--session", str(session), "--out", str(tmp_path / "new"),
                 "--quiet"]) == 0
    assert (tmp_path / "new" / MARKER_NAME).is_file()
    assert (tmp_path / "new" / "alice" / "summary.json").is_file()


def test_outputs_get_the_users_permissions(capture: Path, tmp_path: Path) -> None:
    previous = os.umask(0o022)
    try:
        assert main(solve_args(capture, tmp_path / "r")) == 0
        assert main(["simulate", "--seconds", "3", "--rate", "30", "--noise", "none",
                     "--out", str(tmp_path / "c"), "--quiet"]) == 0
    finally:
        os.umask(previous)
    folders = [tmp_path / "r", tmp_path / "c", tmp_path / "c" / "imu"]
    files = [tmp_path / "r" / "summary.json", tmp_path / "c" / "truth.npz",
             *sorted((tmp_path / "c" / "imu").iterdir())[:2]]
    for path in folders:
        assert stat.S_IMODE(path.stat().st_mode) == 0o755, path
    for path in files:
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path


def dead_pid() -> int:
    """The pid of a process that has exited."""
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                           capture_output=True, text=True, check=True)
    return int(child.stdout)


def test_a_later_write_removes_what_a_killed_writer_left(tmp_path: Path) -> None:
    from ikfusion.atomic import atomic_folder, atomic_write_text, temporary_name

    target = tmp_path / "out"
    ours = temporary_name(target)  # this process is alive: kept
    pid = dead_pid()
    dead = Path(str(ours).replace(f"-{os.getpid()}-", f"-{pid}-"))
    dead_file = Path(str(temporary_name(tmp_path / "t.txt")).replace(f"-{os.getpid()}-",
                                                                     f"-{pid}-"))
    other = tmp_path / ".out.partial-killed"  # not our pattern: never touched
    for folder in (ours, dead, other):
        folder.mkdir()
        (folder / "motion.bvh").write_text("half")
    dead_file.write_text("half")
    with atomic_folder(target, "test") as tmp:
        (tmp / "a.txt").write_text("whole")
    atomic_write_text(tmp_path / "t.txt", "whole")
    assert not dead.exists() and not dead_file.exists()
    assert ours.is_dir() and other.is_dir()
    assert (target / "a.txt").read_text() == "whole"


def test_an_old_folder_of_a_killed_replace_is_put_back(tmp_path: Path) -> None:
    """Killed between its two renames: the previous output comes back, it is not deleted."""
    from ikfusion.atomic import remove_leftovers, temporary_name

    old = Path(str(temporary_name(tmp_path / "out", "old")).replace(f"-{os.getpid()}-",
                                                                    f"-{dead_pid()}-"))
    old.mkdir()
    (old / "summary.json").write_text("{}")
    assert remove_leftovers(tmp_path, "out") == []
    assert (tmp_path / "out" / "summary.json").read_text() == "{}"


def test_atomic_folder_refuses_before_and_leaves_no_partial(tmp_path: Path) -> None:
    from ikfusion.atomic import atomic_folder

    thesis = foreign(tmp_path / "out")
    with pytest.raises(InputError), atomic_folder(tmp_path / "out", "test"):
        pass
    assert thesis.is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
