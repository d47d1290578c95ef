"""One way to compile native code once, cache it on disk and check it before every load.

The solver's step functions (:mod:`ikfusion.ik.native`, CasADi-generated C) and the hand-written
kernels (:mod:`.kernel`) are all built here: with the machine's C compiler, into the cache
folder ``$IKFUSION_CACHE`` (default ``~/.cache/ikfusion``), announced on stderr the first time
(one line), written atomically with the SHA-256 of its content recorded beside it, and loaded
only from a private copy whose bytes match that record (a mismatch is rebuilt, never loaded). A
failed build is a warning and the caller's fallback is used. ``IKFUSION_NO_COMPILE`` (or no
compiler) turns it all off, silently.

The caller gives what differs: the library's name in the cache (its build key), the build step
and the loader (:class:`NativeLibrary`).
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

from ..atomic import atomic_path, atomic_write_text
from ..paths import user_cache_dir

#: What a library is loaded as (CasADi functions, a ctypes library).
Loaded = TypeVar("Loaded")


@dataclass(frozen=True)
class NativeLibrary(Generic[Loaded]):
    """What one native library is and how it is built and loaded.

    Attributes:
        what: Its name in messages ("solver's step function": "compiling the solver's step
            function").
        fallback: What is used when its build fails (the end of the warning).
        path: ``(cache folder, compiler) -> the library's path``; the name holds the build key.
        build: ``(compiler, output path) -> None``: writes the library (raises when it fails).
        load: ``(path of a private verified copy) -> the loaded library``.
    """

    what: str
    fallback: str
    path: Callable[[Path, str], Path]
    build: Callable[[str, Path], None]
    load: Callable[[Path], Loaded]


def cache_dir() -> Path:
    """Folder of compiled native code (:func:`~ikfusion.paths.user_cache_dir`)."""
    return user_cache_dir()


def find_compiler() -> str | None:
    """The C compiler of native code (``cc``, ``gcc`` or ``clang``), if any."""
    return shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


#: The options of every build: -O2 evaluates about a fifth faster than -O1 with the same
#: numbers (no fast-math: IEEE arithmetic) for a few more seconds of the one-time build (-O3
#: doubles it for nothing more); no product and sum fused into one multiply-add (GCC fuses by
#: default where the target has the instruction, e.g. ARM64), so the kernels that repeat NumPy's
#: operations round as NumPy does on every machine.
OPTIONS = ("-O2", "-ffp-contract=off")


@functools.cache
def compiler_identity(compiler: str) -> str:
    """The compiler's resolved path, the first line of its ``--version`` and :data:`OPTIONS`.

    What a cached library was built with (part of its cache key); asked once a process.
    """
    try:
        done = subprocess.run([compiler, "--version"], capture_output=True, text=True,
                              timeout=30, check=False)
        version = (done.stdout or done.stderr).strip().splitlines()[:1]
    except (OSError, subprocess.SubprocessError):
        version = []
    return f"{os.path.realpath(compiler)} {' '.join(version)} {' '.join(OPTIONS)}"


#: Lets the compiler inline a library's calls to its own functions (CasADi's ``casadi_sq``,
#: ``casadi_fabs`` and its ``fmin``/``fmax`` wrappers: 2800 calls in the walk's step function)
#: instead of each going through the PLT with every register spilled around it; the same IEEE
#: arithmetic (bit-identical outputs), a step function 4 % smaller and 7-15 % faster. Dropped
#: for a compiler without it.
INLINE_OWN_CALLS = "-fno-semantic-interposition"


def compile_shared(compiler: str, source: Path, output: Path) -> None:
    """Compile the C file ``source`` to the shared library ``output`` (raises on failure)."""
    command = [compiler, *OPTIONS, "-shared", "-fPIC", str(source), "-o", str(output), "-lm"]
    try:
        subprocess.run([*command, INLINE_OWN_CALLS], check=True, capture_output=True,
                       timeout=600)
    except subprocess.CalledProcessError:  # a compiler without the option: built without it
        subprocess.run(command, check=True, capture_output=True, timeout=600)


def usable_compiler() -> str | None:
    """The compiler to build with; None with ``IKFUSION_NO_COMPILE`` set or without one."""
    if os.environ.get("IKFUSION_NO_COMPILE"):
        return None
    return find_compiler()


def cached_library(spec: NativeLibrary[Loaded]) -> Loaded | None:
    """``spec``'s library when already built and verified, else None (nothing is built).

    None too without a C compiler or with ``IKFUSION_NO_COMPILE``.
    """
    compiler = usable_compiler()
    if compiler is None:
        return None
    try:
        return _load_verified(spec, spec.path(cache_dir(), compiler))
    except (OSError, RuntimeError):
        return None


def native_library(spec: NativeLibrary[Loaded]) -> tuple[Loaded | None, str | None]:
    """``spec``'s library, built once, cached and checked before loading.

    Returns:
        ``(the loaded library or None, warning or None)``: None without a C compiler or with
        ``IKFUSION_NO_COMPILE`` set (no warning), or when the build failed (with a warning
        naming why, also printed on stderr; the caller's fallback is used then).
    """
    compiler = usable_compiler()
    if compiler is None:
        return None, None
    folder = cache_dir()
    try:
        library = spec.path(folder, compiler)
        loaded = _load_verified(spec, library)
        if loaded is not None:
            return loaded, None
        print(f"ikfusion: compiling the {spec.what} once ({compiler}, cached in "
              f"{folder}) ...", file=sys.stderr, flush=True)
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        with atomic_path(library) as built:
            spec.build(compiler, built)
            digest = _sha256(built.read_bytes())
        atomic_write_text(_record(library), digest + "\n")
        loaded = _load_verified(spec, library)
        if loaded is None:
            raise RuntimeError("the library just built does not match its own record")
        return loaded, None
    except (OSError, subprocess.SubprocessError, RuntimeError) as err:
        warning = (f"compiling the {spec.what} failed ({_failure_reason(err)}); "
                   f"{spec.fallback}")
        print(f"ikfusion: warning: {warning}", file=sys.stderr, flush=True)
        return None, warning


def _record(library: Path) -> Path:
    """The file holding the SHA-256 of ``library``'s content, written when it was built."""
    return library.with_name(library.name + ".sha256")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _load_verified(spec: NativeLibrary[Loaded], library: Path) -> Loaded | None:
    """``library`` loaded when its content matches its build record, else None.

    The bytes checked are the bytes loaded: they are copied to a private temporary folder and
    loaded from there, so the cache file cannot change between the check and the load.
    """
    record = _record(library)
    if not (library.is_file() and record.is_file()):
        return None
    data = library.read_bytes()
    if _sha256(data) != record.read_text().strip():
        print(f"ikfusion: the cached {spec.what} {library} does not match the hash recorded "
              "when it was built; it is rebuilt, not loaded", file=sys.stderr)
        return None
    with tempfile.TemporaryDirectory(prefix="ikfusion_native_") as private:
        copy = Path(private) / library.name
        copy.write_bytes(data)
        return spec.load(copy)


def _failure_reason(err: BaseException) -> str:
    """A short reason for a failed build (the compiler's first error line when it has one)."""
    if isinstance(err, subprocess.CalledProcessError):
        text = err.stderr.decode(errors="replace") if isinstance(err.stderr, bytes) \
            else str(err.stderr or "")
        lines = [line for line in text.splitlines() if line.strip()]
        return f"{Path(str(err.cmd[0])).name} exit code {err.returncode}" + (
            f": {lines[0][:200]}" if lines else "")
    return str(err)[:200] or type(err).__name__
