"""The ``retarget`` job kind: ``ikfusion batch retarget INPUTS... --robot g1``.

An input is a ``solve`` result folder (its ``segments.csv`` and ``contacts.csv`` identify it),
a BVH or an MVNX file; each is retargeted as ``ikfusion retarget`` does.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ...errors import InputError
from ...retarget import ROBOTS, retarget
from ...retarget.robot_config import load_retarget_config
from ..kinds import BatchInput, JobKind, JobOutput, Option, expand_paths


def _input(path: Path) -> BatchInput:
    if path.is_dir() and (path / "segments.csv").is_file():
        files = (path / "segments.csv", path / "contacts.csv")
        return BatchInput(str(path), path.name, files, str(path.resolve()))
    if path.is_file() and path.suffix.lower() in (".bvh", ".mvnx"):
        return BatchInput(str(path), path.stem, (path,), str(path.resolve()))
    raise InputError("expected a solve result folder (with segments.csv), a .bvh or an .mvnx "
                     "file", path=path)


def expand(inputs: Sequence[str], options: Mapping[str, Any]) -> list[BatchInput]:
    """Result folders, BVH and MVNX files among INPUTS (files, folders, globs)."""
    robot = str(options.get("robot") or "human")
    if robot == "human" and options.get("height") is None:
        raise InputError("a human target needs --height in metres", field="height")
    if robot != "human":
        load_retarget_config(robot, options.get("config"))  # a bad config fails at once
    return [_input(p) for p in expand_paths(inputs)]


def run(source: str, out_dir: Path, options: Mapping[str, Any]) -> JobOutput:
    """Retarget one input into ``out_dir``."""
    height = options.get("height")
    _, metrics = retarget(source, str(options.get("robot") or "human"),
                          height=None if height is None else float(height), out=out_dir,
                          gmr=options.get("format") == "gmr", config=options.get("config"))
    return JobOutput(frames=int(metrics["frames"]),
                     warnings=tuple(metrics.get("warnings", ())))


def outputs(options: Mapping[str, Any]) -> tuple[str, ...]:
    """The files a retarget writes (``robot_motion.pkl`` too with ``--format gmr``)."""
    files = ("robot_motion.npz", "robot_motion.csv", "summary.json")
    return (*files, "robot_motion.pkl") if options.get("format") == "gmr" else files


KIND = JobKind(
    name="retarget",
    help="retarget many solve results, BVH or MVNX clips in parallel",
    description="Retarget every input (a `solve` result folder, a BVH or an MVNX file) into its "
    "own "
    "folder under --out, as `ikfusion retarget` does, in parallel on Dask; reruns skip inputs "
    "already done with the same files and options.",
    options=(
        Option(("--robot",), {"default": "human", "metavar": "|".join(ROBOTS) + "|PATH.urdf",
                              "help": "target body"}),
        Option(("--config",), {"metavar": "FILE", "help": "retarget config (needed for a URDF)"}),
        Option(("--height",), {"type": float, "metavar": "M",
                               "help": "body height of a human target [m]"}),
        Option(("--format",), {"choices": ["gmr"], "help": "also write robot_motion.pkl"}),
    ),
    expand=expand,
    run=run,
    outputs=outputs,
)
