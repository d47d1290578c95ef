"""Reading the NumPy archives ikfusion writes (``truth.npz``, ``robot_motion.npz``) safely.

A damaged archive (truncated, not a zip, a bad checksum, an array that is not plain numbers) or
one without the arrays a command needs is bad input: an :class:`~ikfusion.errors.InputError`
naming the file and the array, never a traceback. Pickled objects are never loaded.
"""

from __future__ import annotations

import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["read_npz"]


def read_npz(path: str | Path, need: Iterable[str], what: str) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` archive, checked for the ones a reader needs.

    Args:
        path: The archive.
        need: Names of the arrays that must be present.
        what: What the file is, for messages (``"truth.npz"``, ...).

    Raises:
        InputError: The file is missing, unreadable, damaged, or lacks a needed array
            (file and array named).
    """
    file = Path(path)
    if not file.is_file():
        raise InputError(f"{what} not found", path=file)
    try:
        with np.load(file, allow_pickle=False) as archive:
            data = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as err:
        raise InputError(f"not a readable {what}: {err}", path=file) from None
    missing = [name for name in need if name not in data]
    if missing:
        raise InputError(f"not a {what}: missing the array(s) {', '.join(missing)}", path=file,
                         field=missing[0])
    return data
