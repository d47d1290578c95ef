"""Fuzz campaign over every reader the CLI exposes: many more cases than the test.

    PYTHONPATH=. python benchmarks/bench_fuzz.py --cases 5000 --seed 1
    PYTHONPATH=. python benchmarks/bench_fuzz.py --replay 'toa:sim_toa:123:junk'

Prints a table per reader and mutation (cases, exit 0, exit 2, failures, exit 1, timeouts, max
seconds, max memory) and the catalogue of failing cases grouped by cause, each with a replay
command. ``--replay CASE`` runs one case in this process and prints its full output. The seeds
are trimmed copies of ../shared/data (when present) and a tiny simulated capture, made in a
temporary folder.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "fuzz"))

from fuzz_mutators import Case  # noqa: E402
from fuzz_runner import (  # noqa: E402
    Campaign,
    catalogue,
    draw_cases,
    exit2_messages,
    limit_memory,
    run_case,
    table,
)
from fuzz_seeds import WEIGHTS, repo_seeds, shared_seeds, simulate_capture  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
REPLAY = "PYTHONPATH=. python benchmarks/bench_fuzz.py --replay"


def build_seeds(root: Path, shared: Path) -> list:
    capture = simulate_capture(root)
    seeds = repo_seeds(root, capture)
    if shared.is_dir():
        seeds += shared_seeds(root, shared)
    else:
        print(f"{shared} is absent: fuzzing the repository's configs and a simulated capture only")
    return seeds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=5000)
    parser.add_argument("--seed", type=int, default=20261126)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--timeout", type=float, default=30.0, help="per case [s]")
    parser.add_argument("--memory", type=float, default=2048.0, help="per case [MB]")
    parser.add_argument("--shared", type=Path, default=SHARED)
    parser.add_argument("--uniform", action="store_true",
                        help="as many cases per reader (default: the test's weights, fewer for "
                        "the slow solve/simulate/model drivers)")
    parser.add_argument("--readers", help="comma-separated readers to fuzz (default: all)")
    parser.add_argument("--replay", metavar="CASE", help="run one case and print its output")
    parser.add_argument("--messages", action="store_true",
                        help="also list the most frequent exit-2 messages per reader")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="ikfusion-fuzz-") as tmp:
        root = Path(tmp)
        seeds = build_seeds(root, args.shared)
        if args.replay:
            case = Case.parse(args.replay)
            seed = next(s for s in seeds if (s.reader, s.source) == (case.reader, case.source))
            limit_memory(args.memory)
            outcome, out, err = run_case(case, seed, root / "replay", args.timeout,
                                            args.memory, keep=True)
            print(f"case {case}\ncommand: {' '.join(seed.argv) or seed.call}\n--- stdout\n"
                  f"{out[-4000:]}\n--- stderr\n{err[-8000:]}\n--- exit {outcome.code}, "
                  f"{outcome.seconds:.2f} s, {outcome.peak_mb:.0f} MB: "
                  f"{outcome.problem or 'pass'}")
            return 0 if outcome.problem is None else 1
        if args.readers:
            keep = set(args.readers.split(","))
            seeds = [s for s in seeds if s.reader in keep]
        cases = draw_cases(seeds, args.cases, args.seed, None if args.uniform else WEIGHTS)
        t0 = time.perf_counter()
        outcomes = Campaign(seeds, root / "work", workers=args.workers, timeout=args.timeout,
                            memory_mb=args.memory).run(cases)
        wall = time.perf_counter() - t0
        print(table(outcomes))
        print(f"\n{len(outcomes)} cases in {wall:.1f} s ({args.workers} worker(s), seed "
              f"{args.seed})\n")
        print(catalogue(outcomes, REPLAY))
        if args.messages:
            print("\n" + exit2_messages(outcomes))
    return 0


if __name__ == "__main__":
    sys.exit(main())
