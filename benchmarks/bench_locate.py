"""Speed of UWB positioning: transmissions located per second, and TOA CSV round trip.

Run: ``.venv/bin/python benchmarks/bench_locate.py [--n 100000]``. Tags are spread uniformly over
the capture area of a shipped constellation (tag height 0.3-2.0 m), transmit times are
arbitrary, readers have non-zero clock offsets, range noise 3 cm; NLOS delays uniform 0.2-2 m.
Columns: ``fixes`` is the fraction of transmissions with status ok; ``r`` is each fix's error in
units of its expected RMS (sigma x DOP at the true position), so ``rms(r)`` is 1 for an efficient
estimator, ``p99(r)`` its 99th percentile and ``r>5`` the count of gross errors; precision and
recall of the NLOS rejection count receptions.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from ikfusion.paths import shipped_config
from ikfusion.uwb import (
    compute_dop,
    group_transmissions,
    load_constellation,
    locate,
    make_constellation,
    read_toa_csv,
    simulate_toa,
    toa_log_from_matrix,
    write_toa_csv,
)


def _constellation(name: str, rng: np.random.Generator):
    c = load_constellation(shipped_config("constellations", name))
    return make_constellation(
        c.positions,
        ids=c.ids,
        clock_offsets=rng.uniform(-30.0, 30.0, len(c.readers)),
        sigma=0.03,
        area=c.area,
    )


def _positions(c, n: int, rng: np.random.Generator, height: float | None) -> np.ndarray:
    lo, hi = c.area.min(axis=0), c.area.max(axis=0)
    z = rng.uniform(0.3, 2.0, n) if height is None else np.full(n, height)
    return np.column_stack([rng.uniform(lo[0], hi[0], n), rng.uniform(lo[1], hi[1], n), z])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=100_000, help="transmissions per case")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    cases = [
        ("highend_12.yaml", "3d", "free", 0.0),
        ("highend_12.yaml", "3d", "free", 0.10),
        ("highend_12.yaml", "2d", "free", 0.10),
        ("room_6x8.yaml", "3d", "free", 0.10),
        ("room_6x8.yaml", "2d", "zero", 0.0),
    ]
    print(f"ikfusion locate benchmark: {args.n} transmissions per case, sigma 3 cm")
    print(
        f"{'constellation':<16}{'mode':>5}{'clock':>6}{'NLOS':>6}{'time [s]':>10}"
        f"{'tx/s':>10}{'fixes':>8}{'rms(r)':>8}{'p99(r)':>8}{'r>5':>6}"
        f"{'precision':>11}{'recall':>8}"
    )
    for name, mode, clock, nlos in cases:
        c = _constellation(name, rng)
        height = 1.2 if mode == "2d" else None
        p = _positions(c, args.n, rng, height)
        tau = np.zeros(args.n) if clock == "zero" else rng.uniform(0, 1e4, args.n)
        sim = simulate_toa(p, c, rng, tau=tau, nlos_fraction=nlos)
        start = time.perf_counter()
        fixes = locate(sim.toa, c, height=height, clock=clock)
        elapsed = time.perf_counter() - start
        ok = fixes.ok
        err = np.linalg.norm(fixes.p_world_tag[ok] - p[ok], axis=1)
        dop = compute_dop(p[ok], c.positions, mode=mode, clock=clock == "free").position
        r = err / (0.03 * dop)  # error in units of its expected RMS
        ratio = np.sqrt(np.mean(r**2))
        delayed = sim.nlos_delay > 0
        tp = np.count_nonzero(fixes.rejected & delayed)
        precision = tp / max(np.count_nonzero(fixes.rejected), 1)
        recall = tp / max(np.count_nonzero(delayed), 1)
        pr = f"{precision:>11.3f}{recall:>8.3f}" if nlos else f"{'-':>11}{'-':>8}"
        print(
            f"{name[:-5]:<16}{mode:>5}{clock:>6}{nlos:>6.0%}{elapsed:>10.2f}"
            f"{args.n / elapsed:>10.0f}{ok.mean():>8.4f}{ratio:>8.3f}"
            f"{np.percentile(r, 99):>8.2f}{np.count_nonzero(r > 5):>6d}{pr}"
        )
    # TOA CSV round trip at the same scale (12 readers -> about 12 rows per transmission).
    c = _constellation("highend_12.yaml", rng)
    p = _positions(c, args.n, rng, None)
    sim = simulate_toa(p, c, rng, miss_probability=0.05)
    tags = np.array(["T1", "T2", "T3", "T4"])[np.arange(args.n) % 4]
    seq = (np.arange(args.n) // 4) % 65536
    log = toa_log_from_matrix(np.arange(args.n) * 1e-3, tags, seq, sim.toa, c.ids)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "toa.csv"
        start = time.perf_counter()
        write_toa_csv(path, log)
        t_write = time.perf_counter() - start
        start = time.perf_counter()
        back = read_toa_csv(path)
        t_read = time.perf_counter() - start
        start = time.perf_counter()
        tx = group_transmissions(back, c.ids)
        t_group = time.perf_counter() - start
    print(
        f"TOA CSV, {len(log)} rows: write {t_write:.2f} s, read {t_read:.2f} s, "
        f"group into {len(tx)} transmissions {t_group:.2f} s"
    )


if __name__ == "__main__":
    main()
