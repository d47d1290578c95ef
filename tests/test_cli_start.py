"""The start of a command loads what that command needs, not every command's modules."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ikfusion.cli import COMMAND_MODULES, build_parser, main

ROOT = Path(__file__).resolve().parents[1]

#: Modules a solve without UWB never uses: the simulator, the UWB package (and with it SciPy's
#: statistics, about a second to import), the viewer, the batch runner.
NOT_FOR_SOLVE = ("ikfusion.sim", "ikfusion.uwb", "ikfusion.view", "ikfusion.batch",
                 "ikfusion.app.demo", "scipy.stats")

LOADED = """
import contextlib, io, json, sys
from ikfusion.cli import main
with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):
    main(sys.argv[1:])
import ikfusion.app.session  # what `solve` runs
print(json.dumps(sorted(sys.modules)))
"""


def loaded_modules(argv: list[str]) -> set[str]:
    """The modules a fresh interpreter holds after ``ikfusion ARGV`` (e.g. ``solve --help``)."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    child = subprocess.run([sys.executable, "-c", LOADED, *argv], capture_output=True,
                           text=True, check=True, env=dict(os.environ, PYTHONPATH=path),
                           timeout=120)
    return set(json.loads(child.stdout))


def test_solve_loads_neither_simulator_nor_uwb() -> None:
    modules = loaded_modules(["solve", "--help"])
    assert "ikfusion.cli.solve" in modules
    loaded = [m for m in modules for heavy in NOT_FOR_SOLVE
              if m == heavy or m.startswith(heavy + ".")]
    assert loaded == []


def test_every_command_is_listed_without_a_command_name(capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0
    text = capsys.readouterr().out
    for module in COMMAND_MODULES:
        assert module.replace("_", "-") in text


def test_a_misspelt_command_lists_every_command(capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["calibrate_uwb"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'calibrate_uwb'" in err and "'calibrate-uwb'" in err
    assert "'solve'" in err and "'demo'" in err


def test_a_named_command_parses_as_before() -> None:
    args = build_parser(["calibrate-uwb", "log.csv", "--heights", "h.yaml", "--out", "r.yaml"]) \
        .parse_args(["calibrate-uwb", "log.csv", "--heights", "h.yaml", "--out", "r.yaml"])
    assert args.command == "calibrate-uwb" and args.out == "r.yaml"
