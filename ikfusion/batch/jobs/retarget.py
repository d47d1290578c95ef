"""The ``retarget`` job kind: ``ikfusion batch retarget INPUTS... --robot human --height M``.

An input is a ``solve`` result folder (its ``segments.csv`` and ``contacts.csv`` identify it) or
a BVH file; each is retargeted as ``ikfusion retarget`` does.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ...errors import InputError
from ...retarget import ROBOTS, retarget
from ..kinds import BatchInput, JobKind, JobOutput, Option, expand_paths


def _input(path: Path) -> BatchInput:
    if path.is_dir() and (path / "segments.csv").is_file():
        files = (path / "segments.csv", path / "contacts.csv")
        return BatchInput(str(path), path.name, files, str(path.resolve()))
    if path.is_file() and path.suffix.lower() == ".bvh":
        return BatchInput(str(path), path.stem, (path,), str(path.resolve()))
    raise InputError("expected a solve result folder (with segments.csv) or a .bvh file",
                     path=path)


def expand(inputs: Sequence[str], options: Mapping[str, Any]) -> list[BatchInput]:
    """Result folders and BVH files among INPUTS (files, folders, globs)."""
    if options.get("height") is None:
        raise InputError("a human target needs --height in metres", field="height")
    return [_input(p) for p in expand_paths(inputs)]


def run(source: str, out_dir: Path, options: Mapping[str, Any]) -> JobOutput:
    """Retarget one input into ``out_dir``."""
    _, metrics = retarget(source, str(options.get("robot") or "human"),
                          height=float(options["height"]), out=out_dir,
                          gmr=options.get("format") == "gmr")
    return JobOutput(frames=int(metrics["frames"]), warnings=tuple(metrics["warnings"]))


KIND = JobKind(
    name="retarget",
    help="retarget many solve results or BVH clips in parallel",
    description="Retarget every input (a `solve` result folder or a BVH file) into its own "
    "folder under --out, as `ikfusion retarget` does, in parallel on Dask; reruns skip inputs "
    "already done with the same files and options.",
    options=(
        Option(("--robot",), {"choices": list(ROBOTS), "default": "human",
                              "help": "target body"}),
        Option(("--height",), {"type": float, "metavar": "M",
                               "help": "body height of a human target [m]"}),
        Option(("--format",), {"choices": ["gmr"], "help": "also write robot_motion.pkl"}),
    ),
    expand=expand,
    run=run,
)
