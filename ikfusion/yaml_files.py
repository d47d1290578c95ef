"""Reading the YAML files users write (sensor maps, bodies, constellations, tags, configs).

One reader, so that every such file fails the same way: an unreadable file or invalid YAML is a
:class:`~ikfusion.errors.ConfigError` naming the file and, for YAML errors, the line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError


def read_yaml(path: str | Path, what: str = "file",
              loader: type[yaml.SafeLoader] = yaml.SafeLoader) -> Any:
    """The parsed content of a YAML file.

    Args:
        path: The file.
        what: What the file is, for the message (``"sensor map"``, ``"tags file"``, ...).
        loader: A ``yaml.SafeLoader`` subclass (e.g. one that keeps ids as text).

    Raises:
        ConfigError: The file cannot be read, or is not valid YAML (with its line).
    """
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"cannot read {what}: {err.strerror}", path=file) from err
    try:
        return yaml.load(text, Loader=loader)  # noqa: S506 - a SafeLoader (sub)class
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        raise ConfigError(f"not valid YAML: {getattr(err, 'problem', None) or err}", path=file,
                          line=None if mark is None else mark.line + 1) from err
