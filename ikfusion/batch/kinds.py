"""Job kinds of ``ikfusion batch``: what one input is and how it is processed.

A job kind is three things: how command-line inputs expand into :class:`BatchInput` items (and
are validated), a function that turns one item into an output folder, and the options it takes.
Registering a kind is one line: add its module name to :data:`KIND_MODULES`; the module
``ikfusion.batch.jobs.<name>`` defines ``KIND`` (a :class:`JobKind`).
"""

from __future__ import annotations

import glob
import importlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError

#: Modules under ``ikfusion.batch.jobs`` that define a job kind, in the order ``--help`` lists.
KIND_MODULES: tuple[str, ...] = ("solve", "retarget")


@dataclass(frozen=True)
class Option:
    """One command-line option of a job kind.

    Args:
        flags: The option strings, e.g. ``("--map",)``.
        settings: Keywords of ``argparse.ArgumentParser.add_argument`` (help, default, ...).
        group: Options sharing a group name are mutually exclusive.
    """

    flags: tuple[str, ...]
    settings: Mapping[str, Any] = field(default_factory=dict)
    group: str | None = None

    @property
    def dest(self) -> str:
        """The attribute name argparse stores the value under."""
        if "dest" in self.settings:
            return str(self.settings["dest"])
        long = next((f for f in self.flags if f.startswith("--")), self.flags[0])
        return long.lstrip("-").replace("-", "_")


@dataclass(frozen=True)
class BatchInput:
    """One input of a batch, as a job kind expanded it.

    Args:
        label: The input as the report shows it (a path).
        stem: The preferred output folder name (made unique across the batch).
        files: The files whose contents identify the input (the resume fingerprint).
        source: What the kind's ``run`` receives (must pickle: it travels to Dask workers).
    """

    label: str
    stem: str
    files: tuple[Path, ...]
    source: Any


@dataclass(frozen=True)
class JobOutput:
    """What processing one input reports back (``run`` may also return ``None``).

    Args:
        frames: Frames written (0 when unknown).
        warnings: Warnings worth keeping in ``batch.json``.
    """

    frames: int = 0
    warnings: tuple[str, ...] = ()


#: Turns INPUTS (paths or globs) and the parsed options into batch items; raises InputError.
ExpandFn = Callable[[Sequence[str], Mapping[str, Any]], list[BatchInput]]
#: Processes one item's ``source`` into ``out_dir`` (an empty folder) with the options.
RunFn = Callable[[Any, Path, Mapping[str, Any]], "JobOutput | int | None"]
#: The file names ``run`` writes into an output folder with these options.
OutputsFn = Callable[[Mapping[str, Any]], tuple[str, ...]]


def no_outputs(options: Mapping[str, Any]) -> tuple[str, ...]:
    """The :data:`OutputsFn` of a kind that names no files (resume trusts ``batch.json``)."""
    return ()


@dataclass(frozen=True)
class JobKind:
    """A kind of batch job (``solve``, ``retarget``, ...).

    Args:
        name: The subcommand, ``ikfusion batch <name>``.
        help: One line for ``ikfusion batch --help``.
        description: The subcommand's ``--help`` text.
        options: The options it takes beyond INPUTS, --out, --workers, --scheduler.
        expand: How INPUTS expand into items (validating them).
        run: How one item becomes an output folder. Must be importable by name on the workers
            (a module-level function).
        outputs: The files ``run`` writes, given the options: a rerun skips an input only when
            its folder has them all (and the same fingerprint).
    """

    name: str
    help: str
    description: str
    options: tuple[Option, ...]
    expand: ExpandFn
    run: RunFn
    outputs: OutputsFn = no_outputs


def load_kind(name: str) -> JobKind:
    """The job kind registered as ``name`` (see :data:`KIND_MODULES`)."""
    if name not in KIND_MODULES:
        raise InputError(f"unknown batch job kind {name!r}; valid kinds: "
                         f"{', '.join(KIND_MODULES)}", field="kind")
    module = importlib.import_module(f"{__package__}.jobs.{name}")
    kind = module.KIND
    if not isinstance(kind, JobKind):
        raise TypeError(f"{module.__name__}.KIND is not a JobKind")
    return kind


def has_magic(pattern: str) -> bool:
    """Whether ``pattern`` holds glob wildcards (``*``, ``?``, ``[``)."""
    return glob.has_magic(pattern)


def expand_paths(patterns: Sequence[str]) -> list[Path]:
    """Expand paths and globs (``**`` allowed) into existing paths, in order, without repeats.

    A plain path that does not exist is kept as given (it may be an MT Manager trial prefix);
    the kind decides. A glob that matches nothing raises :class:`InputError`.
    """
    seen: set[Path] = set()
    out: list[Path] = []
    for pattern in patterns:
        if has_magic(pattern):
            matches = sorted(glob.glob(pattern, recursive=True))
            if not matches:
                raise InputError(f"no input matches the pattern {pattern!r}; check the path "
                                 "(quote globs so the shell does not expand them)",
                                 field="INPUTS")
            paths = [Path(m) for m in matches]
        else:
            paths = [Path(pattern)]
        for path in paths:
            key = path.resolve()
            if key not in seen:
                seen.add(key)
                out.append(path)
    return out


def files_under(folder: Path) -> list[Path]:
    """Every regular file under ``folder`` (recursively), sorted."""
    return sorted(p for p in folder.rglob("*") if p.is_file())
