"""Resume stamps of ``ikfusion batch``: which input, options and version made an output folder.

Every finished output folder holds ``batch.json``; its ``fingerprint`` is the SHA-256 of the job
kind, the ikfusion version, the options and the contents of the input's files. A rerun skips an
input whose output folder carries the same fingerprint, and recomputes it otherwise.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

#: The stamp file in every finished output folder.
STAMP_NAME = "batch.json"

_CHUNK = 1 << 20


def _update_with_file(digest: Any, path: Path) -> None:
    """Feed a file's name, size and contents to ``digest``."""
    size = path.stat().st_size
    digest.update(f"file:{path.name}:{size}\n".encode())
    with path.open("rb") as f:
        while chunk := f.read(_CHUNK):
            digest.update(chunk)


def fingerprint(kind: str, version: str, options: Mapping[str, Any],
                files: Sequence[Path]) -> str:
    """The hex SHA-256 that identifies one job: kind, version, options, input contents.

    Args:
        kind: The job kind name.
        version: The ikfusion version (a new version recomputes everything).
        options: The kind's options (JSON-serialisable values).
        files: The input's files, in a stable order.
    """
    digest = hashlib.sha256()
    header = {"kind": kind, "version": version, "options": dict(options)}
    digest.update(json.dumps(header, sort_keys=True, default=str).encode())
    for path in files:
        _update_with_file(digest, path)
    return digest.hexdigest()


def read_stamp(folder: Path) -> dict[str, Any] | None:
    """The ``batch.json`` of a finished output folder, or ``None`` (absent or unreadable)."""
    path = folder / STAMP_NAME
    try:
        stamp = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return stamp if isinstance(stamp, dict) else None


def is_complete(folder: Path, expected: str, outputs: Sequence[str] = ()) -> bool:
    """Whether ``folder`` is a finished output made with fingerprint ``expected``.

    Args:
        folder: The output folder.
        expected: The fingerprint of the job now.
        outputs: File names the job kind writes; a folder missing one of them is unfinished.
    """
    stamp = read_stamp(folder)
    if stamp is None or stamp.get("fingerprint") != expected:
        return False
    return all((folder / name).is_file() for name in outputs)


def write_stamp(folder: Path, stamp: Mapping[str, Any]) -> None:
    """Write ``batch.json`` into ``folder`` (still the partial folder: it appears with it)."""
    (folder / STAMP_NAME).write_text(json.dumps(dict(stamp), indent=2, default=str))
