"""``python -m ikfusion`` runs the command line (Ctrl-C while it loads exits 130 quietly)."""

import sys

try:
    from .cli import main
except KeyboardInterrupt:
    print("ikfusion: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
