"""The ``ikfusion`` command line: one module per subcommand under ``ikfusion.cli``.

Each command module defines ``register(subparsers)``, which adds its parser and sets
``func`` (a callable taking the parsed ``argparse.Namespace`` and returning an exit code).
Exit codes: 0 ok, 2 bad input or usage (the message names file, line and field), 1 internal
error, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM), 141 standard output closed early
(``ikfusion inspect ... | head``). An interrupted or terminated command removes its temporary
folders and leaves earlier outputs as they were.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from types import FrameType
from typing import Any

from ..errors import InputError

#: Command modules in the order ``ikfusion --help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "demo", "inspect", "simulate", "solve", "evaluate", "model", "locate", "plan",
    "calibrate_uwb", "view", "batch", "retarget", "live",
)

#: Exit codes of a stopped command (128 + the signal number, as shells report it).
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143
EXIT_BROKEN_PIPE = 141


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that the same clean-up runs (temporary folders removed)."""


class _Parser(argparse.ArgumentParser):
    """Argument parser whose usage errors exit 2 with the usage line (argparse's default)."""


def add_force_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--force`` to a command that writes an output folder."""
    parser.add_argument(
        "--force", action="store_true",
        help="replace --out (or write into it) even when it exists and ikfusion did not write "
        "it; without --force an existing folder is used only when it is empty or holds the "
        ".ikfusion.json marker of an earlier ikfusion output. The current folder, its parents, "
        "the home folder and / are refused even with --force")


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The top-level parser: every subcommand, or only the one ``argv`` names.

    A command module imports what its command needs (``demo`` the simulator and SciPy's
    statistics, ``view`` the viewer, ...): when ``argv`` starts with a command name only that
    module is loaded, which saves seconds at the start of every command. Without one (no
    arguments, ``--help``, a misspelt command) every command is registered, so the listing and
    the usage error name them all.
    """
    parser = _Parser(
        prog="ikfusion",
        description="Full-body human motion from body-worn IMUs and UWB, solved as a QP.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    named = [m for m in COMMAND_MODULES if list(argv or [])[:1] == [m.replace("_", "-")]]
    for name in named or COMMAND_MODULES:
        module = importlib.import_module(f"{__name__}.{name}")
        module.register(sub)
    return parser


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into :class:`Terminated` while the command runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous: Callable[[int, FrameType | None], Any] | int | None = signal.signal(
        signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _say(text: str) -> None:
    """One line on standard error, ignoring a closed standard error."""
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _stdout_closed() -> None:
    """Point standard output at /dev/null, so flushing it at exit raises nothing more."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


def _run(args: argparse.Namespace, name: str) -> int:
    """Run the parsed command, mapping bad input to 2 and anything unexpected to 1."""
    if not gc.get_freeze_count():  # once a process (later calls would freeze their garbage)
        # what is alive now, the imported modules (hundreds of thousands of objects), lives as
        # long as the process: the collector's full passes need not walk it (~20 ms a solve)
        gc.freeze()
    try:
        code = int(args.func(args) or 0)
    except InputError as err:
        _say(f"{name}: error: {err}")
        return 2
    except (KeyboardInterrupt, BrokenPipeError):
        raise
    except Exception as err:  # noqa: BLE001 - last-resort report with exit code 1
        import traceback

        traceback.print_exc()
        _say(f"{name}: internal error: {err}")
        return 1
    sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit code.

    Ctrl-C (at any point, start-up included) returns 130 and SIGTERM 143, each with a one-line
    message and no traceback; a closed standard output returns 141 quietly.
    """
    name = "ikfusion"
    try:
        with _sigterm_as_interrupt():
            argv = sys.argv[1:] if argv is None else list(argv)
            parser = build_parser(argv)
            try:
                args = parser.parse_args(argv)
            except SystemExit:  # --help or a usage error: their text must reach a closed pipe
                sys.stdout.flush()
                raise
            name = f"ikfusion {args.command}"
            return _run(args, name)
    except Terminated:
        _say(f"{name}: terminated")
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        _say(f"{name}: interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        _stdout_closed()
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
