"""One exception root for ikfusion, with subclasses that carry what is needed to debug.

Messages say what was expected, what was found, and how to fix it. The command line maps
:class:`InputError` (bad files, bad options) to exit code 2 and any other error to exit code 1.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path


class IkfusionError(Exception):
    """Root of every error raised on purpose by ikfusion."""


class InputError(IkfusionError):
    """Bad user input: a file, a line of it, a field, or a command-line option.

    Args:
        message: What was expected and what was found.
        path: The file at fault, when there is one.
        line: 1-based line number in that file, when known.
        field: The column or key at fault, when known.
    """

    def __init__(
        self,
        message: str,
        path: str | Path | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.path = None if path is None else Path(path)
        self.line = line
        self.field = field
        self.reason = message
        where = []
        if path is not None:
            where.append(str(path))
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field {field!r}")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class ConfigError(InputError):
    """A YAML configuration (body, sensor map, constellation, joints) that does not hold."""


class NameNotFound(IkfusionError, KeyError):
    """A segment, joint, site or frame name that the model does not have.

    Args:
        kind: What was looked up ("segment", "site", "frame", ...).
        name: The name asked for.
        valid: The names that exist.
    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        super().__init__(f"unknown {kind} {name!r}; valid {kind} names: {', '.join(self.valid)}")

    def __str__(self) -> str:  # KeyError quotes its argument; keep the message readable
        return str(self.args[0])


class SolverError(IkfusionError):
    """A numerical solver failed in a way that cannot be relaxed (reported, never swallowed)."""
