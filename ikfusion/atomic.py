"""Files and folders that appear whole or not at all: the one place ikfusion writes outputs.

An output is written under a temporary name beside its target and renamed over it on success;
on any exception (Ctrl-C and SIGTERM included, see :mod:`ikfusion.cli`) the temporary is
removed and an existing target is left untouched. Temporary names are
``.<target name>.partial-<pid>-<host>-<random>`` (and ``.old-`` for a folder being replaced),
so a later write of the same target removes what a killed process (whose pid is gone) left.
Outputs get the user's normal permissions (the umask), not the private mode of ``mkstemp``.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import secrets
import shutil
import signal
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from .output_folders import check_output_folder, write_marker

_TEMP_NAME = re.compile(
    r"^\.(?P<target>.+)\.(?P<kind>partial|old)-(?P<pid>\d+)-(?P<host>[0-9a-f]{6})-[0-9a-z]{8}$")


def _host_tag() -> str:
    """Six hex digits naming this machine (pids of other machines cannot be checked here)."""
    return hashlib.sha1(socket.gethostname().encode()).hexdigest()[:6]


def temporary_name(target: Path, kind: str = "partial") -> Path:
    """A fresh temporary path beside ``target`` (``kind`` is ``partial`` or ``old``)."""
    tag = secrets.token_hex(4)
    return target.parent / f".{target.name}.{kind}-{os.getpid()}-{_host_tag()}-{tag}"


def is_leftover_name(name: str) -> bool:
    """Whether ``name`` is a temporary name of this module (of any target, pid and host)."""
    return _TEMP_NAME.match(name) is not None


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _remove(path: Path) -> None:
    """Remove a file, link or folder tree; errors are ignored (best effort clean-up)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def remove_leftovers(folder: Path, target: str | None = None,
                     only_dead: bool = True) -> list[Path]:
    """Remove the temporaries that interrupted writes left in ``folder``.

    Args:
        folder: Where to look.
        target: Only leftovers of this target name (None: of any target).
        only_dead: Only those whose writing process (on this machine) is gone. With False, every
            leftover is removed (a caller that knows no other writer uses ``folder``).

    Returns:
        The paths removed. An ``.old-`` folder whose target is missing (the writer died between
        its two renames) is renamed back into place instead, and not listed.
    """
    removed: list[Path] = []
    try:
        entries = list(folder.iterdir())
    except OSError:
        return removed
    host = _host_tag()
    for entry in entries:
        match = _TEMP_NAME.match(entry.name)
        if match is None or (target is not None and match["target"] != target):
            continue
        if only_dead and (match["host"] != host or _pid_alive(int(match["pid"]))):
            continue
        final = folder / match["target"]
        if match["kind"] == "old" and not final.exists() and not final.is_symlink():
            with contextlib.suppress(OSError):
                os.replace(entry, final)
                continue
        _remove(entry)
        removed.append(entry)
    return removed


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back (main thread only) so two renames are not split apart."""
    if not hasattr(signal, "pthread_sigmask") \
            or threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a fresh temporary path beside ``target``; on success it is renamed onto ``target``.

    The caller (or a tool it runs) creates the file at the yielded path. The parent folder is
    created when missing; stale leftovers of ``target`` are removed first.
    """
    final = Path(target)
    final.parent.mkdir(parents=True, exist_ok=True)
    remove_leftovers(final.parent, final.name)
    temporary = temporary_name(final)
    try:
        yield temporary
        os.replace(temporary, final)
    except BaseException:
        _remove(temporary)
        raise


@contextlib.contextmanager
def atomic_write(target: str | Path, mode: str = "w", **open_args: Any) -> Iterator[IO[Any]]:
    """Open a file that replaces ``target`` whole when the block ends without an exception.

    Args:
        target: The file.
        mode: ``"w"`` (text, UTF-8 unless ``encoding`` is given) or ``"wb"``.
        **open_args: More arguments of :func:`open` (``newline``, ``encoding``).

    The file gets the umask's permissions and is flushed to disk before the rename.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', not {mode!r}")
    if mode == "w":
        open_args.setdefault("encoding", "utf-8")
    with atomic_path(target) as temporary:
        fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        with os.fdopen(fd, mode, **open_args) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8, newlines as given) to ``path`` whole or not at all; return it."""
    with atomic_write(path, "w", newline="") as handle:
        handle.write(text)
    return Path(path)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` whole or not at all; return it."""
    with atomic_write(path, "wb") as handle:
        handle.write(data)
    return Path(path)


def _replace_folder(partial: Path, final: Path) -> None:
    """Rename ``partial`` onto ``final``, moving an existing ``final`` aside first."""
    with _signals_deferred():
        old = None
        if final.exists() or final.is_symlink():
            old = temporary_name(final, "old")
            os.replace(final, old)
        try:
            os.replace(partial, final)
        except BaseException:
            if old is not None:
                os.replace(old, final)
            raise
    if old is not None:
        _remove(old)


@contextlib.contextmanager
def atomic_folder(target: str | Path, command: str, force: bool = False) -> Iterator[Path]:
    """Yield an empty temporary folder beside ``target``; on success it replaces ``target``.

    The folder gets the marker of :mod:`ikfusion.output_folders` (``command`` in it) and the
    umask's permissions. An existing ``target`` is replaced only when ikfusion wrote it (or it
    is empty), or with ``force``; it is checked before and again just before the rename.

    Raises:
        InputError: ``target`` is refused (see :func:`.output_folders.check_output_folder`).
    """
    final = Path(target)
    check_output_folder(final, force)
    final.parent.mkdir(parents=True, exist_ok=True)
    remove_leftovers(final.parent, final.name)
    partial = temporary_name(final)
    os.mkdir(partial, 0o777)  # the umask applies, as for any folder the user makes
    try:
        yield partial
        write_marker(partial, command)
        check_output_folder(final, force)
        _replace_folder(partial, final)
    except BaseException:
        _remove(partial)
        raise
