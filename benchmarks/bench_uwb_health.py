"""Where healthy UWB data lie: the figures behind the thresholds of :mod:`ikfusion.uwb.health`.

Simulates clean captures (default sensor noise, the default 10 % NLOS, no reader faults) of
the procedural walk with several seeds and constellations, tracks their tags as ``solve`` does,
and prints per capture the smallest share of transmissions a tag's filter used, the largest
share of TOAs a tag's filter rejected and the largest share of TOAs rejected of one reader.
The thresholds of :mod:`ikfusion.uwb.health` must stay clear of these maxima.

    PYTHONPATH=. python benchmarks/bench_uwb_health.py --seconds 20 --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from ikfusion.app.uwb_aiding import track_capture
from ikfusion.paths import shipped_config
from ikfusion.sim.capture import truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation
from ikfusion.uwb.health import (
    READER_REJECTED_SHARE_LIMIT,
    TAG_REJECTED_SHARE_MAX,
    TAG_USED_SHARE_MIN,
    reader_report,
    tag_fit,
)


def main() -> None:
    """Print the health figures of clean simulated captures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--constellations", nargs="+", default=["room_6x8", "small_6"])
    args = parser.parse_args()
    truth = truth_motion("gait", args.seconds, 60.0, progress=False)
    worst = {"tag_used": 1.0, "tag_rejected": 0.0, "reader_rejected": 0.0}
    print("constellation seed  tag_used_min  tag_rejected_max  reader_rejected_max")
    for name in args.constellations:
        room = load_constellation(shipped_config("constellations", f"{name}.yaml"))
        for seed in args.seeds:
            with tempfile.TemporaryDirectory() as tmp:
                folder = Path(tmp) / "capture"
                write_capture(folder, truth, ImuNoise(), seed, constellation=room)
                tracked = track_capture(folder)
            fits = [tag_fit(t) for t in tracked.tracks.values()]
            used = min(f.used / max(f.received, 1) for f in fits)
            rejected = max(f.rejected_share for f in fits)
            readers = reader_report(list(tracked.tracks.values()), room.ids)
            reader = max(float(r["rejected_share"]) for r in readers.values())
            print(f"{name:13s} {seed:4d}  {used:12.3f}  {rejected:16.3f}  {reader:19.3f}")
            worst = {"tag_used": min(worst["tag_used"], used),
                     "tag_rejected": max(worst["tag_rejected"], rejected),
                     "reader_rejected": max(worst["reader_rejected"], reader)}
    print(f"worst: tag used share {worst['tag_used']:.3f} (limit {TAG_USED_SHARE_MIN}), tag "
          f"rejected share {worst['tag_rejected']:.3f} (limit {TAG_REJECTED_SHARE_MAX}), reader "
          f"rejected share {worst['reader_rejected']:.3f} (limit {READER_REJECTED_SHARE_LIMIT})")


if __name__ == "__main__":
    main()
