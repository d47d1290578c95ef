"""``python -m ikfusion.native.compile_typed``: compile the solver's modules with mypyc, once.

See :mod:`.typed_modules` (what is compiled, where it is kept, when it is loaded).
"""

from __future__ import annotations

import sys

from .typed_modules import build


def main() -> int:
    """Build them for the current sources (kept when already built); say where."""
    try:
        folder = build()
    except (RuntimeError, OSError) as err:
        print(f"ikfusion: {err}", file=sys.stderr)
        return 1
    print(f"ikfusion: compiled modules ready in {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
