"""Fuzz campaign over every reader the CLI exposes (select with ``-k fuzz``).

Seed files (the repository's configs, a tiny simulated capture and, when ../shared/data is
present, trimmed copies of the real recordings) are mutated (truncation, byte flips, deleted,
duplicated and swapped lines and columns, NaN/inf/1e30, CRLF, UTF-16, BOM, Latin-1, junk, empty
files, a folder for a file, duplicate keys) with a fixed seed and read by the cheapest command
that reads them fully. Every case must exit 0 or 2 (2 naming the mutated file, no traceback),
never 1, within 30 s and 2 GB, and no NaN may reach an output. Every failing case is listed at
the end with a replay command; ``benchmarks/bench_fuzz.py`` runs more cases.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from fuzz_mutators import Case, mutate_file
from fuzz_runner import Campaign, Outcome, _non_finite_outputs, catalogue, draw_cases
from fuzz_seeds import WEIGHTS, Seed, repo_seeds, shared_seeds, simulate_capture

#: The campaign's fixed seed; change it only on purpose (the failures then differ).
SEED = 20261126
REPLAY = "PYTHONPATH=. python benchmarks/bench_fuzz.py --replay"
REPO_CASES = 1000
SHARED_CASES = 1000

pytestmark = pytest.mark.fuzz


@pytest.fixture(scope="module")
def repo_inputs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Seed]]:
    root = tmp_path_factory.mktemp("fuzz")
    return root, repo_seeds(root, simulate_capture(root))


def _report(outcomes: list[Outcome]) -> str:
    """The catalogue of failing cases ('' when every case passes)."""
    return "" if all(o.problem is None for o in outcomes) else catalogue(outcomes, REPLAY)


def _baseline_report(seeds: list[Seed], workdir: Path) -> str:
    """Seeds that fail as they are: they must exit 0 with finite outputs ('' when they do)."""
    cases = [Case(s.reader, s.source, 0, ("none",)) for s in seeds]
    outcomes = Campaign(seeds, workdir).run(cases)
    bad = [f"  {o.case}: exit {o.code}, {o.problem or 'no problem'}: {o.last_line}"
           for o in outcomes if o.code != 0 or o.problem is not None]
    return "seeds that fail unmutated:\n" + "\n".join(bad) if bad else ""


def test_fuzz_mutations_replay_to_the_same_bytes(tmp_path: Path) -> None:
    text = "".join(f"{k},{k * 0.5},x{k}\n" for k in range(50)).encode()
    case = Case.parse("toa:any:12345:special_value+swap_columns+junk")
    assert Case.parse(str(case)) == case
    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    for f in (a, b, c):
        f.write_bytes(text)
    mutate_file(a, case.mutations, case.seed)
    mutate_file(b, case.mutations, case.seed)
    mutate_file(c, case.mutations, case.seed + 1)
    assert a.read_bytes() == b.read_bytes() != text
    assert c.read_bytes() != a.read_bytes()
    mutate_file(c, ("folder",), 1)
    assert c.is_dir()


def test_fuzz_seeds_pass_unmutated(repo_inputs: tuple[Path, list[Seed]]) -> None:
    """The harness is sound: every seed as it is exits 0 with finite outputs."""
    root, seeds = repo_inputs
    report = _baseline_report(seeds, root / "baseline")
    assert not report, report


def test_fuzz_cli_repo_inputs(repo_inputs: tuple[Path, list[Seed]]) -> None:
    """The repository's configs and a simulated capture, mutated."""
    root, seeds = repo_inputs
    cases = draw_cases(seeds, REPO_CASES, SEED, WEIGHTS)
    report = _report(Campaign(seeds, root / "work").run(cases))
    assert not report, report


def test_fuzz_cli_shared_recordings(shared_data: Path, tmp_path: Path) -> None:
    """Trimmed copies of the real recordings (MT Manager, MVNX, BVH, OpenSense XML), mutated."""
    seeds = shared_seeds(tmp_path, shared_data)
    baseline = _baseline_report(seeds, tmp_path / "baseline")
    cases = draw_cases(seeds, SHARED_CASES, SEED + 1, WEIGHTS)
    report = _report(Campaign(seeds, tmp_path / "work").run(cases))
    assert not baseline and not report, f"{baseline}\n{report}"


def test_fuzz_nan_check_reads_numbers_not_words(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"warnings": ["Gyr_Z missing; those are NaN"]}')
    (out / "fixes.csv").write_text("time,x\n0.0,1.5\n")
    assert _non_finite_outputs('{"rate": 60.0}', out) is None
    (out / "summary.json").write_text('{"rate": NaN}')
    assert "summary.json at rate" in str(_non_finite_outputs("", out))
    (out / "summary.json").write_text("{}")
    (out / "fixes.csv").write_text("time,x\n0.0,-inf\n")
    assert "fixes.csv line 2" in str(_non_finite_outputs("", out))
    assert "standard output" in str(_non_finite_outputs('{"q": [1, Infinity]}', tmp_path / "x"))
