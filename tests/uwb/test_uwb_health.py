"""Per-reader rejection report, tag fit and capture bounds on hand-made inputs."""

from __future__ import annotations

import numpy as np

from ikfusion.uwb import make_constellation
from ikfusion.uwb.bounds import capture_bounds, convex_hull, outside
from ikfusion.uwb.ekf import UnitTrack, UwbTotals
from ikfusion.uwb.health import faulty_readers, reader_report, tag_fit


def _track(time: np.ndarray, used: np.ndarray, rejected: np.ndarray) -> UnitTrack:
    heard = used | rejected
    t = len(time)
    totals = UwbTotals(int(heard.any(axis=1).sum()), int(used.any(axis=1).sum()),
                       int(heard.sum()), int(used.sum()), int(rejected.sum()), 0, 0.0)
    return UnitTrack(time, np.zeros((1, 3)), np.zeros((1, 3, 3)), np.zeros((1, 4)), time,
                     np.arange(t), used, rejected, heard, np.zeros(t, dtype=bool), totals)


def test_reader_report_finds_the_jump_and_the_silence() -> None:
    time = np.arange(200) * 0.1  # 20 s at 10 Hz, 5 readers
    used = np.ones((200, 5), dtype=bool)
    rejected = np.zeros_like(used)
    rejected[time >= 12.0, 0], used[time >= 12.0, 0] = True, False  # R1's clock jumps at 12 s
    used[(time >= 4.0) & (time < 9.0), 1] = False  # R2 silent for 5 s
    report = reader_report([_track(time, used, rejected)], ["R1", "R2", "R3", "R4", "R5"])
    assert report["R1"]["rejected"] == 80 and report["R1"]["rejected_share"] == 0.4
    assert report["R1"]["rejected_windows"] == [[12.0, 20.0]]
    assert report["R2"]["received"] == 150 and report["R2"]["silent_windows"] == [[4.0, 9.0]]
    assert report["R3"]["rejected_windows"] == [] and report["R3"]["silent_windows"] == []
    warnings = faulty_readers(report)
    assert len(warnings) == 1 and warnings[0].startswith("UWB reader R1: 80 of 200")


def test_tag_fit_refuses_a_tag_whose_toas_are_mostly_rejected() -> None:
    time = np.arange(100) * 0.1
    used = np.zeros((100, 6), dtype=bool)
    rejected = np.ones((100, 6), dtype=bool)
    used[:, 0], rejected[:, 0] = True, False  # one TOA per transmission fits: used, 5 rejected
    fit = tag_fit(_track(time, used, rejected))
    assert fit.used == fit.received == 100
    assert fit.problem is not None and "500 of 600 TOAs rejected" in fit.problem
    assert tag_fit(_track(time, rejected, used)).problem is None


def test_bounds_of_readers_in_a_line_and_the_hull() -> None:
    hull = convex_hull(np.array([[0, 0], [4, 0], [4, 4], [0, 4], [2, 2], [1, 3]]))
    assert {tuple(p) for p in hull} == {(0, 0), (4, 0), (4, 4), (0, 4)}
    corridor = make_constellation([[0, 0, 2.5], [25, 0, 0.5], [50, 0, 2.5], [75, 0, 0.5]])
    bounds = capture_bounds(corridor)  # a line: margin a quarter of 75 m
    p = np.array([[30, 10, 1], [30, 25, 1], [30, 0, -1], [np.nan, 0, 0]])
    area, height = outside(p, bounds)
    assert area.tolist() == [False, True, False, False]
    assert height.tolist() == [False, False, True, False]
