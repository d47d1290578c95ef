"""Models built once per URDF and kept on disk, so a fresh process loads instead of building.

Building the model of a body (parsing its URDF, merging the revolute triplets into ball joints,
finding segments, sites and the N-pose) takes about 10 ms; loading it back takes about 1 ms. A
model is cached under ``<user cache>/human_models/<key>/`` (:func:`~ikfusion.paths.user_cache_dir`)
where ``key`` hashes what the URDF text is made from (every field of the body, exactly, and the
shipped ``configs/joints.yaml``), the source of :mod:`ikfusion.model`, :mod:`ikfusion.rotations`
and :mod:`ikfusion.yaml_files` (the code that writes the text and turns it into the model), and the
Pinocchio and Python versions: any change of them builds a new model instead of loading one
made otherwise, and a cached model is loaded without writing its URDF text at all.

A cache entry is a folder of three files, ``model.bin`` and ``revolute.bin`` (Pinocchio's binary
serialisation, exact to the bit) and ``tables.pickle`` (ball joints, name tables, the N-pose),
and ``sha256``, the hash of the three recorded when it was written. It is loaded only when the
files match that record; anything else (a missing, partial or damaged entry, an unwritable cache)
builds the model from the URDF as before, so the cache never changes a result. At most
:data:`MAX_ENTRIES` entries are kept, the least recently used removed first.

:func:`cached_model` does the same for any Pinocchio model built from files (a retarget robot's
reduced model under ``robot_models/``), keyed by what it is built from.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import shutil
import sys
from collections.abc import Callable
from dataclasses import fields
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pinocchio as pin

from .. import rotations, yaml_files
from ..atomic import is_leftover_name, remove_leftovers, temporary_name
from ..paths import shipped_config, user_cache_dir

if TYPE_CHECKING:
    from .body import Body

#: The Pinocchio models of a human model's entry (the ball-joint model, the revolute one) ...
HUMAN_MODEL_FILES = ("model.bin", "revolute.bin")
#: ... and its pickled tables.
TABLES_FILE = "tables.pickle"

#: Entries kept per kind (about 160 kB each for a human model); the least recently used go first.
MAX_ENTRIES = 200

#: ``HumanModel`` attributes kept in ``tables.pickle`` (the Pinocchio models are stored apart).
TABLE_ATTRIBUTES = ("body", "ball_joints", "joint_map", "_frames", "_segments", "_sites",
                    "_q_neutral")


@cache
def code_fingerprint() -> str:
    """SHA-256 of the code that turns a URDF text into a model and of its library versions.

    Read once per process (the code does not change under a running process).
    """
    digest = hashlib.sha256()
    folder = Path(__file__).resolve().parent
    for module in sorted(folder.glob("*.py")):
        digest.update(module.name.encode() + b"\0" + module.read_bytes())
    for other in (rotations, yaml_files):  # the rotations, and how configs/joints.yaml reads
        digest.update(Path(str(other.__file__)).read_bytes())
    digest.update(f"pinocchio {pin.__version__} python {sys.version_info[:3]}".encode())
    return digest.hexdigest()


def entry_folder(body: Body) -> Path:
    """The cache folder of the human model of ``body`` (whether or not it exists yet).

    Its key stands for the URDF text of ``body`` without writing it: the body's fields (floats
    by ``repr``, exact to the bit), the bytes of the shipped ``configs/joints.yaml`` (its
    ranges of motion are in the text), and :func:`code_fingerprint`. Equal bodies share an
    entry; bodies that differ in any field, even where the text would round them alike, do not.
    """
    digest = hashlib.sha256()
    digest.update(repr([(f.name, getattr(body, f.name)) for f in fields(body)]).encode())
    digest.update(b"\0" + shipped_config("joints.yaml").read_bytes())
    digest.update(b"\0" + code_fingerprint().encode())
    return user_cache_dir() / "human_models" / digest.hexdigest()[:32]


def _digest(contents: list[bytes]) -> str:
    digest = hashlib.sha256()
    for data in contents:
        digest.update(hashlib.sha256(data).digest())
    return digest.hexdigest()


def load_entry(folder: Path, model_files: tuple[str, ...] = HUMAN_MODEL_FILES,
               tables_file: str | None = TABLES_FILE
               ) -> tuple[list[pin.Model], dict[str, Any] | None] | None:
    """The Pinocchio models (and the tables) of an entry; None when it is missing or unusable.

    The files are checked against the entry's record first; the tables are unpickled from
    the very bytes checked.
    """
    files = (*model_files, *(() if tables_file is None else (tables_file,)))
    try:
        contents = [(folder / name).read_bytes() for name in files]
        if _digest(contents) != (folder / "sha256").read_text().strip():
            return None
        models = []
        for name in model_files:
            model = pin.Model()
            model.loadFromBinary(str(folder / name))
            models.append(model)
        tables = None if tables_file is None else pickle.loads(contents[-1])
    except (OSError, RuntimeError, ValueError, EOFError, pickle.UnpicklingError, AttributeError,
            ImportError):
        return None
    if tables_file is not None and (not isinstance(tables, dict)
                                    or set(tables) != set(TABLE_ATTRIBUTES)):
        return None
    with contextlib.suppress(OSError):  # used now: pruned last (a read-only cache still loads)
        os.utime(folder)
    return models, tables


def store_entry(folder: Path, models: dict[str, pin.Model],
                tables: dict[str, Any] | None = None) -> bool:
    """Write an entry whole (a temporary folder renamed into place); False when it cannot.

    Args:
        folder: The entry.
        models: File name -> Pinocchio model (binary serialisation).
        tables: Pickled to :data:`TABLES_FILE` when given.

    A concurrent writer of the same entry may win the rename: its entry is as good as ours.
    """
    partial = None
    try:
        folder.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        partial = temporary_name(folder)
        partial.mkdir(mode=0o700)
        for name, model in models.items():
            model.saveToBinary(str(partial / name))
        files = list(models)
        if tables is not None:
            (partial / TABLES_FILE).write_bytes(
                pickle.dumps(tables, protocol=pickle.HIGHEST_PROTOCOL))
            files.append(TABLES_FILE)
        contents = [(partial / name).read_bytes() for name in files]
        (partial / "sha256").write_text(_digest(contents) + "\n")
        if folder.exists():  # a damaged entry (a good one would have been loaded)
            shutil.rmtree(folder, ignore_errors=True)
        os.replace(partial, folder)
    except (OSError, RuntimeError, pickle.PicklingError):
        return False
    finally:
        if partial is not None and partial.exists():
            shutil.rmtree(partial, ignore_errors=True)
    with contextlib.suppress(OSError):
        _prune(folder.parent, MAX_ENTRIES)
    return True


def _prune(kind: Path, keep: int) -> None:
    """Remove all but the ``keep`` entries of ``kind`` used last (a cache never grows unbounded).

    Partial entries that killed writers left are removed too.
    """
    remove_leftovers(kind)
    entries = []
    for entry in kind.iterdir():
        if entry.is_dir() and not is_leftover_name(entry.name):
            with contextlib.suppress(OSError):
                entries.append((entry.stat().st_mtime_ns, entry))
    entries.sort(reverse=True)
    for _, entry in entries[keep:]:
        shutil.rmtree(entry, ignore_errors=True)


def cached_model(kind: str, key: str, build: Callable[[], pin.Model]) -> pin.Model:
    """The Pinocchio model ``build`` returns, loaded from the cache when built before.

    Args:
        kind: The cache's subfolder (``"robot_models"``).
        key: Everything the model depends on (the URDF's bytes, options), hashed here with
            the Pinocchio version.
        build: Builds the model (its errors propagate; a failed build is never cached).
    """
    digest = hashlib.sha256(f"{key}\0pinocchio {pin.__version__}".encode()).hexdigest()
    folder = user_cache_dir() / kind / digest[:32]
    loaded = load_entry(folder, ("model.bin",), None)
    if loaded is not None:
        return loaded[0][0]
    model = build()
    store_entry(folder, {"model.bin": model})
    return model
