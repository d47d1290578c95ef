"""Which output folders ikfusion may replace or write into, and the marker that says it wrote one.

Every folder ikfusion creates as an output (a ``solve`` result, a ``retarget`` output, a
``simulate`` capture, the folder of a ``demo``, a ``batch`` or a session) holds a small hidden
file, :data:`MARKER_NAME`, naming the command, the ikfusion version and the time. An existing
folder is replaced or written into only when it holds that marker or is empty; any other folder
is refused (exit 2) unless the user passes ``--force``. The current folder, its ancestors, the
file-system root and the home folder are never replaced or written into, even with ``--force``.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from .errors import InputError

#: The marker file inside every output folder ikfusion creates.
MARKER_NAME = ".ikfusion.json"


def write_marker(folder: Path, command: str) -> Path:
    """Write the marker into ``folder``: the ``command`` that wrote it, the version, the time."""
    from . import __version__

    marker: dict[str, Any] = {
        "written_by": "ikfusion", "command": command, "version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    path = folder / MARKER_NAME
    path.write_text(json.dumps(marker, indent=2) + "\n")
    return path


def is_ikfusion_folder(folder: Path) -> bool:
    """Whether ``folder`` holds the marker ikfusion writes into its output folders."""
    try:
        marker = json.loads((folder / MARKER_NAME).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(marker, dict) and marker.get("written_by") == "ikfusion"


def _never_replaced(folder: Path) -> str | None:
    """Why ``folder`` may never be an output folder (None when it may)."""
    resolved = folder.resolve()
    cwd = Path.cwd().resolve()
    if resolved == Path(resolved.anchor):
        return "the file-system root"
    if resolved == Path.home().resolve():
        return "the home folder"
    if resolved == cwd:
        return "the current folder"
    if resolved in cwd.parents:
        return "a folder that holds the current folder"
    return None


def _is_empty(folder: Path) -> bool:
    with os.scandir(folder) as entries:
        return next(entries, None) is None


def check_output_folder(folder: str | Path, force: bool = False) -> None:
    """Refuse an output folder that would destroy or mix with files ikfusion did not write.

    Allowed: a path that does not exist, an empty folder, a folder holding :data:`MARKER_NAME`,
    and with ``force`` anything else except the folders of :func:`_never_replaced`.

    Raises:
        InputError: The folder is refused (the message says why and what to do; exit 2).
    """
    path = Path(folder)
    never = _never_replaced(path)
    if never is not None:
        raise InputError(f"refusing to use {never} as an output folder (it would be replaced "
                         "or filled with outputs); name a new folder", path=path, field="out")
    if not path.exists() and not path.is_symlink():
        return
    if force:
        return
    if not path.is_dir():
        raise InputError("exists and is not a folder; name a new folder, or add --force to "
                         "replace it", path=path, field="out")
    if is_ikfusion_folder(path) or _is_empty(path):
        return
    raise InputError(f"exists and was not written by ikfusion (it has no {MARKER_NAME}), so "
                     "its files would be lost; name a new or empty folder, or add --force to "
                     "replace it", path=path, field="out")


def prepare_output_folder(folder: str | Path, command: str, force: bool = False) -> Path:
    """Check and create a folder that ikfusion fills with output folders and files.

    Used for folders that are written into rather than replaced (``demo``, ``batch``,
    ``solve --session``). The marker is written when the folder is new or empty; a folder taken
    with ``force`` gets none, so a later run without ``--force`` is refused again.

    Raises:
        InputError: The folder is refused (see :func:`check_output_folder`).
    """
    path = Path(folder)
    check_output_folder(path, force)
    path.mkdir(parents=True, exist_ok=True)
    if not is_ikfusion_folder(path) and _is_empty(path):
        write_marker(path, command)
    return path


def folder_name_problem(name: str) -> str | None:
    """Why ``name`` cannot be one folder name under an output folder (None when it can).

    A name must be one path component: not empty, printable, without path separators or
    control characters, not starting with a dot (``.``, ``..`` and hidden names).
    """
    if not name:
        return "it is empty"
    if name.startswith("."):
        return "it starts with a dot"
    if "/" in name or "\\" in name or (os.altsep and os.altsep in name):
        return "it holds a path separator"
    if not name.isprintable():
        return "it holds control or unprintable characters"
    return None
