"""The ``retarget`` job kind: ``ikfusion batch retarget INPUTS... --robot g1``.

An input is a ``solve`` result folder (its ``segments.csv`` and ``contacts.csv`` identify it),
a BVH or an MVNX file; each is retargeted as ``ikfusion retarget`` does. Any other folder
expands to the result folders, BVH and MVNX files under it (a result folder's own files, such as
its ``motion.bvh``, are part of it, not clips of their own).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ...errors import InputError
from ...retarget import ROBOTS, retarget
from ...retarget.robot_config import load_retarget_config
from ..kinds import BatchInput, JobKind, JobOutput, Option, expand_paths

#: File suffixes of motion clips.
CLIP_SUFFIXES = (".bvh", ".mvnx")


def _is_result_folder(path: Path) -> bool:
    return path.is_dir() and (path / "segments.csv").is_file()


def _input(path: Path) -> BatchInput:
    if _is_result_folder(path):
        files = (path / "segments.csv", path / "contacts.csv")
        return BatchInput(str(path), path.name, files, str(path.resolve()))
    if path.is_file() and path.suffix.lower() in CLIP_SUFFIXES:
        return BatchInput(str(path), path.stem, (path,), str(path.resolve()))
    raise InputError("expected a solve result folder (with segments.csv), a .bvh or an .mvnx "
                     "file, or a folder holding them", path=path)


def sources_under(folder: Path) -> list[Path]:
    """Result folders and clip files under ``folder``, depth first in name order.

    A result folder is one source (nothing inside it is looked at); hidden entries are skipped.
    """
    found: list[Path] = []
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith("."):
            continue
        if _is_result_folder(entry):
            found.append(entry)
        elif entry.is_dir():
            found.extend(sources_under(entry))
        elif entry.is_file() and entry.suffix.lower() in CLIP_SUFFIXES:
            found.append(entry)
    return found


def _inputs(path: Path) -> list[BatchInput]:
    """One input, or every source under a folder that is not a result folder itself."""
    if path.is_dir() and not _is_result_folder(path):
        sources = sources_under(path)
        if not sources:
            raise InputError("the folder holds no solve result folder (with segments.csv), "
                             ".bvh or .mvnx file", path=path, field="INPUTS")
        return [_input(p) for p in sources]
    return [_input(path)]


def expand(inputs: Sequence[str], options: Mapping[str, Any]) -> list[BatchInput]:
    """Result folders, BVH and MVNX files among INPUTS (files, folders of them, globs)."""
    robot = str(options.get("robot") or "human")
    if robot == "human" and options.get("height") is None:
        raise InputError("a human target needs --height in metres", field="height")
    if robot != "human":
        load_retarget_config(robot, options.get("config"))  # a bad config fails at once
    return [item for p in expand_paths(inputs) for item in _inputs(p)]


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
    description="Retarget every input (a `solve` result folder, a BVH or an MVNX file; a folder "
    "of them expands to every one under it) into its own folder under --out, as `ikfusion "
    "retarget` does, in parallel on Dask; reruns skip inputs already done with the same files "
    "and options.",
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
