"""How the command line stops: SIGTERM, Ctrl-C while it loads, a reader that closes the pipe.

Each case runs ``python -m ikfusion`` (or ``ikfusion.cli.main``) in a child process and checks
its exit code, its one-line message, that no traceback is printed and that no temporary folder
is left behind.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from ikfusion.cli import main

ROOT = Path(__file__).resolve().parents[1]


def child_env() -> dict[str, str]:
    """The environment of a child ``python -m ikfusion``: this checkout first on the path."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return dict(os.environ, PYTHONPATH=path)


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from ikfusion.sim.capture import truth_motion, write_capture

    folder = tmp_path_factory.mktemp("capture") / "capture"
    write_capture(folder, truth_motion("gait:straight", seconds=3.0, rate=30), None, seed=3)
    return folder


def test_sigterm_while_writing_removes_the_partial_folder(tmp_path: Path) -> None:
    """SIGTERM in the write phase of ``simulate`` (held there by a slow truth file)."""
    script = textwrap.dedent("""
        import sys, time
        import ikfusion.sim.capture as capture
        from ikfusion.cli import main

        write_truth = capture.write_truth

        def slow_truth(path, truth):
            write_truth(path, truth)
            time.sleep(120)  # the signal comes while the capture is half written

        capture.write_truth = slow_truth
        sys.exit(main(["simulate", "--seconds", "3", "--rate", "30", "--noise", "none",
                       "--out", "cap", "--quiet"]))
    """)
    child = subprocess.Popen([sys.executable, "-c", script], cwd=tmp_path, env=child_env(),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while not any((p / "truth.npz").is_file() for p in tmp_path.glob(".cap.partial-*")):
            assert child.poll() is None, child.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        child.send_signal(signal.SIGTERM)
        _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 143, err
    assert "ikfusion simulate: terminated" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


INTERRUPT_ON_NUMPY = """
import sys

class CtrlC:
    \"\"\"Raise KeyboardInterrupt when numpy starts loading, as a Ctrl-C at that moment.\"\"\"

    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            raise KeyboardInterrupt
        return None

sys.meta_path.insert(0, CtrlC())
"""


@pytest.mark.parametrize("entry", [
    "import runpy; sys.argv = ['ikfusion', 'inspect', 'x']; "
    "runpy.run_module('ikfusion', run_name='__main__', alter_sys=True)",
    "from ikfusion.cli import main; sys.exit(main(['inspect', 'x']))",
])
def test_ctrl_c_while_loading_exits_130_without_traceback(entry: str, tmp_path: Path) -> None:
    child = subprocess.run([sys.executable, "-c", INTERRUPT_ON_NUMPY + entry], cwd=tmp_path,
                           env=child_env(), capture_output=True, text=True, timeout=120)
    assert child.returncode == 130, child.stderr
    assert "interrupted" in child.stderr and "Traceback" not in child.stderr
    assert child.stderr.count("\n") == 1


def test_ctrl_c_while_building_the_parser(monkeypatch, capsys) -> None:
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("ikfusion.cli.build_parser", interrupted)
    try:
        code = main(["inspect", "x"])
    except KeyboardInterrupt:
        pytest.fail("KeyboardInterrupt escaped ikfusion.cli.main")
    assert code == 130
    assert capsys.readouterr().err == "ikfusion: interrupted\n"


@pytest.mark.parametrize("command", [["inspect", "{imu}", "--json"], ["inspect", "{imu}"]])
def test_a_closed_stdout_is_quiet(command: list[str], capture: Path, tmp_path: Path) -> None:
    """``ikfusion inspect ... | head``: the reader is gone before ikfusion writes."""
    argv = [a.format(imu=capture / "imu") for a in command]
    child = subprocess.Popen([sys.executable, "-m", "ikfusion", *argv], cwd=tmp_path,
                             env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    assert child.stdout is not None and child.stderr is not None
    child.stdout.close()
    err = child.stderr.read()
    child.wait(timeout=120)
    assert child.returncode == 141, err
    assert err == ""
