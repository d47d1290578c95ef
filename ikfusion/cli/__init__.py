"""The ``ikfusion`` command line: one module per subcommand under ``ikfusion.cli``.

Each command module defines ``register(subparsers)``, which adds its parser and sets
``func`` (a callable taking the parsed ``argparse.Namespace`` and returning an exit code).
Exit codes: 0 ok, 2 bad input or usage (the message names file, line and field), 1 internal error.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from ..errors import InputError

#: Command modules in the order ``ikfusion --help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "demo", "inspect", "simulate", "solve", "evaluate", "model", "locate", "plan",
    "calibrate_uwb", "view", "batch", "retarget",
)


class _Parser(argparse.ArgumentParser):
    """Argument parser whose usage errors exit 2 with the usage line (argparse's default)."""


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered subcommand."""
    parser = _Parser(
        prog="ikfusion",
        description="Full-body human motion from body-worn IMUs and UWB, solved as a QP.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"{__name__}.{name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = args.func(args)
    except InputError as err:
        print(f"ikfusion {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"ikfusion {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # noqa: BLE001 - last-resort report with exit code 1
        import traceback

        traceback.print_exc()
        print(f"ikfusion {args.command}: internal error: {err}", file=sys.stderr)
        return 1
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
