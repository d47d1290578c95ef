"""The solver's per-frame Python compiled to C by mypyc, once per machine and source version.

A frame of the solve is mostly Python glue between small native calls (the contact tracking, the
targets, the assembly of the QP): about 300 us of interpreter work on the real walk. mypyc
compiles the same typed modules (:data:`MODULES`) to C extension modules: a warm solve of the
real walk takes 11 % fewer instructions (the whole command, reading and writing included), and
the results are bit for bit the same (IEEE
double arithmetic either way, the same operations in the same order; the tests compare both).

Opt-in for now: ``make typed`` (``python -m ikfusion.native.compile_typed``) builds them (about
two minutes, with the machine's C compiler and mypyc from the ``typed`` extra) into the cache
folder (:func:`ikfusion.paths.user_cache_dir`), in a folder named by the hash of the Python version,
the platform and the modules' sources. Each later ``import ikfusion`` loads them in place of the
Python modules when that folder exists (:func:`enable`): an edited source changes the hash, so
stale compiled code is never loaded (the Python modules are, until the next build).
``IKFUSION_NO_TYPED`` (or ``IKFUSION_NO_COMPILE``) keeps the Python modules; the test suite sets
it, so that its checks that replace functions of these modules see their replacements.

What mypyc needs of a module (each learnt from a build or a compiled solve that failed):
no ``ctypes.Structure`` subclass (the kernels' are in :mod:`ikfusion.ik.kernel_arguments`,
which stays Python), no guarded import of a name (:mod:`ikfusion.ik.fast_math` finds its
function by a function), no ``cls.__new__``, class constants marked ``ClassVar``, no
interpreted subclass of a compiled class (retarget's :class:`CompiledConfiguration` is compiled
with its base), no descriptor class (mypyc compiles ``__get__``/``__set__`` of a native class as
plain methods: the attribute would silently stop being one), no file found from ``__file__``
(a compiled module's is in the cache: :func:`ikfusion.paths.module_source`), and annotations
that hold: compiled, an ``int``, ``float`` or ``bool`` refuses NumPy's scalars (``Any`` where a
NumPy scalar comes). Left out: :mod:`ikfusion.ik.settings` (a dataclass derived from an
interpreted one), :mod:`ikfusion.ik.native` (run once per process), and
:mod:`ikfusion.ik.pose` with :mod:`ikfusion.rotations`, which compile and keep the results but
save 0.2 % of a solve's instructions (not worth their use everywhere). A module is added to
:data:`MODULES` once the compiled solves are bit for bit the Python ones
(``tests/test_typed_modules.py``, the motion clips of ``benchmarks/bench_motions.py``).
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from ..paths import module_source, user_cache_dir

#: The modules compiled (each compiles and keeps its results bit for bit, checked by the tests).
MODULES: tuple[str, ...] = tuple(f"ikfusion.ik.{name}" for name in (
    "active_set", "anchor_carry", "anchor_settling", "assumed", "ballistic", "bound_function",
    "casadi_kinematics", "compiled", "compiled_blocks", "compiled_inputs", "compiled_joint_tasks",
    "compiled_key", "compiled_points", "compiled_ranges", "compiled_sensed", "configuration",
    "contact_clocks", "contact_flags", "contact_projection", "contact_thresholds",
    "contact_tracker", "contacts", "equality_qp", "fast_math", "foot_pairs", "foot_pitch", "frame",
    "frame_problem", "frame_stance", "frame_targets", "handover", "landing_lag", "landing_rules",
    "least_distance", "limits.base", "limits.contact", "limits.joint_range",
    "limits.shared_segment", "limits.soft_wall", "limits.velocity", "point_bits", "point_evidence",
    "point_masks", "points_configuration", "projection", "qp", "qp_backends", "release",
    "residuals", "sensed_evidence", "sensed_pose", "solver", "step_ranges", "step_rows", "support",
    "support_motion", "sweeping", "swing_lead", "tasks.base", "tasks.chain", "tasks.column_shape",
    "tasks.damping", "tasks.orientation", "tasks.position", "tasks.posture", "tree_solve",
    "trunk_roll", "usual_release", "vec3", "wall_sink", "world_offset")) + (
    "ikfusion.retarget.compiled_step",  # (its Configuration subclass: compiled with its base)
)

#: Set (to anything) to keep the Python modules.
DISABLE = "IKFUSION_NO_TYPED"

#: Builds kept in the cache folder (the newest; :func:`prune_builds`).
KEPT_BUILDS = 3

#: The build folder's list of ``module-name relative-path`` lines, written last.
MANIFEST = "modules.txt"

_PACKAGE = Path(__file__).resolve().parents[1]  # the ikfusion package folder


def build_key(modules: Sequence[str] = MODULES) -> str:
    """Hash of what a build depends on: Python, the platform and the modules' sources."""
    digest = hashlib.sha256(f"{sys.version} {platform.machine()} {sys.platform}".encode())
    for module in modules:
        digest.update(f"\0{module}\0".encode())
        digest.update(module_source(module).read_bytes())
    return digest.hexdigest()[:20]


def build_folder(modules: Sequence[str] = MODULES) -> Path:
    """Where the build of the current sources lives (it may not exist)."""
    return user_cache_dir() / f"typed_{build_key(modules)}"


class _TypedFinder(importlib.abc.MetaPathFinder):
    """Finds the compiled modules of one build (module name -> extension module file)."""

    def __init__(self, files: dict[str, Path]) -> None:
        self.files = files

    def find_spec(self, fullname: str, path: Sequence[str] | None = None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        file = self.files.get(fullname)
        if file is None:
            return None
        loader = importlib.machinery.ExtensionFileLoader(fullname, str(file))
        return importlib.util.spec_from_file_location(fullname, file, loader=loader)


def enable() -> bool:
    """Load the compiled modules from now on when the current sources were built.

    Nothing happens (False) with ``IKFUSION_NO_TYPED`` or ``IKFUSION_NO_COMPILE`` set, without
    a build of these sources, when a module of :data:`MODULES` is already imported (the two
    would mix) or when the build's shared runtime does not load.
    """
    if os.environ.get(DISABLE) or os.environ.get("IKFUSION_NO_COMPILE"):
        return False
    if any(m in sys.modules for m in MODULES) or any(
            isinstance(f, _TypedFinder) for f in sys.meta_path):
        return False
    try:
        folder = build_folder()
        lines = (folder / MANIFEST).read_text().split("\n")
    except OSError:
        return False
    files = {name: folder / rel for name, rel in
             (line.split(" ", 1) for line in lines if line)}
    if not set(MODULES) <= set(files) or not all(f.is_file() for f in files.values()):
        return False
    finder = _TypedFinder(files)
    sys.meta_path.insert(0, finder)
    runtime = [name for name in files if name not in MODULES]  # mypyc's shared runtime
    try:
        for name in runtime:
            importlib.import_module(name)
    except ImportError as err:
        sys.meta_path.remove(finder)
        print(f"ikfusion: warning: the compiled modules in {folder} do not load ({err}); "
              "the Python modules are used", file=sys.stderr)
        return False
    return True


def enabled() -> bool:
    """Whether the compiled modules are in use in this process."""
    return any(isinstance(f, _TypedFinder) for f in sys.meta_path)


#: The build, run by a separate interpreter in the folder holding the ``ikfusion`` package:
#: mypyc's C for the modules, compiled by setuptools into ``<out>/lib``.
_BUILD_SCRIPT = """
import os, sys
from mypyc.build import mypycify
from setuptools import Distribution
from setuptools.command.build_ext import build_ext

out, paths = sys.argv[1], sys.argv[2:]
options = ["--ignore-missing-imports", "--cache-dir", os.path.join(out, "mypy_cache")]
extensions = mypycify(options + paths, opt_level="2", target_dir=os.path.join(out, "c"))
command = build_ext(Distribution({"name": "ikfusion-typed", "ext_modules": extensions}))
command.build_lib, command.build_temp = os.path.join(out, "lib"), os.path.join(out, "obj")
command.parallel = os.cpu_count() or 1
command.ensure_finalized()
command.run()
"""


def build(modules: Sequence[str] = MODULES, quiet: bool = False) -> Path:
    """Compile ``modules`` with mypyc into :func:`build_folder` (kept when already there).

    Raises:
        RuntimeError: The build failed (mypyc or the compiler's last lines say why).
    """
    folder = build_folder(modules)
    if (folder / MANIFEST).is_file():
        return folder
    folder.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        paths = [str(module_source(m).relative_to(_PACKAGE.parent)) for m in modules]
        if not quiet:
            print(f"ikfusion: compiling {len(modules)} modules with mypyc (once; about two "
                  f"minutes) into {folder} ...", file=sys.stderr, flush=True)
        done = subprocess.run([sys.executable, "-c", _BUILD_SCRIPT, str(work), *paths],
                              cwd=_PACKAGE.parent, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-5:])
            raise RuntimeError(f"mypyc build failed:\n{tail}")
        _install(work / "lib", folder)
        prune_builds(folder)
        return folder
    finally:
        shutil.rmtree(work, ignore_errors=True)


def prune_builds(kept: Path, keep: int = KEPT_BUILDS) -> list[Path]:
    """Remove the oldest builds beside ``kept`` beyond the ``keep`` newest (``kept`` stays).

    Each edit of a compiled module's source makes another build (6-8 MB); a few are kept for
    other checkouts or Python versions sharing the cache. A process still running on a removed
    build is unharmed (its extension modules stay mapped). Returns the folders removed.
    """
    builds = sorted((f for f in kept.parent.glob("typed_*") if f.is_dir() and f != kept),
                    key=lambda f: f.stat().st_mtime, reverse=True)
    removed = builds[max(keep - 1, 0):]
    for folder in removed:
        shutil.rmtree(folder, ignore_errors=True)
    return removed


def _install(lib: Path, folder: Path) -> None:
    """Move the built extension modules of ``lib`` into ``folder``, the manifest last."""
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    lines = []
    for file in sorted(lib.rglob("*")):
        suffix = next((s for s in suffixes if file.name.endswith(s)), None)
        if suffix is None:
            continue
        relative = file.relative_to(lib)
        name = ".".join(relative.parts)[:-len(suffix)]
        (staging / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(file, staging / relative)
        lines.append(f"{name} {relative.as_posix()}")
    (staging / MANIFEST).write_text("\n".join(lines) + "\n")
    try:
        os.replace(staging, folder)
    except OSError:  # another process built it meanwhile: theirs is kept
        shutil.rmtree(staging, ignore_errors=True)
