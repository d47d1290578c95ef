"""simulate --readers puts the motion inside the capture area, or says that it cannot."""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml

from ikfusion.cli import main
from ikfusion.paths import configs_dir
from ikfusion.sim.area_fit import fit_track, signed_clearance
from ikfusion.uwb import load_constellation

CONSTELLATIONS = configs_dir() / "constellations"


def _simulate(tmp_path: Path, clip: Path, readers: Path) -> Path:
    out = tmp_path / "capture"
    code = main(["simulate", "--motion", str(clip), "--readers", str(readers), "--rate", "30",
                 "--noise", "none", "--quiet", "--out", str(out)])  # fmt: skip
    assert code == 0
    return out


def _inside_rectangle(xy: np.ndarray, lo, hi, margin: float) -> np.ndarray:
    """Independent check for an axis-aligned rectangular area."""
    return np.all((xy >= np.add(lo, margin)) & (xy <= np.subtract(hi, margin)), axis=1)


def _toa_residuals(capture: Path) -> np.ndarray:
    """Reader-to-reader TOA differences minus the truth's distance differences [m].

    toa = transmit time + distance + clock offset (0 in the shipped files) + NLOS + noise, so the
    differences of one transmission between readers follow the tag's true place.
    """
    truth = np.load(capture / "truth.npz")
    sites = list(truth["site_names"])
    readers = {r.id: r.p_world_reader for r in load_constellation(capture / "readers.yaml").readers}
    tags = yaml.safe_load((capture / "tags.yaml").read_text())["tags"]
    rows: dict[tuple[str, str], list[tuple[float, str, float]]] = defaultdict(list)
    with open(capture / "toa.csv", newline="") as f:
        for r in csv.DictReader(f):
            rows[(r["tag"], r["seq"])].append((float(r["time"]), r["reader"], float(r["toa"])))
    out = []
    for (tag, _), hits in rows.items():
        if len(hits) < 2:
            continue
        k = int(np.argmin(np.abs(truth["time"] - hits[0][0])))
        p = truth["p_world_site"][k, sites.index(tags[tag]["site"])]
        d = [np.linalg.norm(p - readers[rid]) for _, rid, _ in hits]
        toa = [t for _, _, t in hits]
        out += [(toa[i] - toa[0]) - (d[i] - d[0]) for i in range(1, len(hits))]
    return np.abs(np.array(out))


def test_a_clip_beside_the_room_is_moved_into_it(tmp_path, shared_data, capsys):
    # cmu_131_01 sits where the BVH puts it: about a quarter of its walk inside the 6 x 8 m
    # room. It fits: the whole pelvis track must end up inside with the 0.5 m margin.
    room = CONSTELLATIONS / "room_6x8.yaml"
    capture = _simulate(tmp_path, shared_data / "mocap" / "cmu_131_01.bvh", room)
    captured = capsys.readouterr()
    assert "warning" not in captured.err
    assert "placed in the capture area" in captured.out
    truth = np.load(capture / "truth.npz")
    pelvis = truth["p_world_segment"][:, list(truth["segment_names"]).index("Pelvis"), :2]
    assert np.all(_inside_rectangle(pelvis, [0, 0], [6, 8], 0.5))
    fit = json.loads(str(truth["area_fit"]))
    assert fit["fits"] and fit["inside_before"] < 0.5 and fit["inside_after"] == 1.0
    # UWB was simulated on the moved motion: the times of arrival follow the truth's tags.
    assert np.median(_toa_residuals(capture)) < 0.05


def test_a_clip_that_cannot_fit_is_reported(tmp_path, shared_data, capsys):
    # Jogging on a curved path about 4 x 5 m cannot fit a 3 m wide corridor: the clip is put
    # where most of it is covered (turned), and the terminal and truth.npz say so.
    corridor = CONSTELLATIONS / "corridor_75m.yaml"
    capture = _simulate(tmp_path, shared_data / "mocap" / "sfu_0005_Jogging001.bvh", corridor)
    err = capsys.readouterr().err
    assert "warning" in err and "does not fit" in err and "corridor_75m" in err
    truth = np.load(capture / "truth.npz")
    fit = json.loads(str(truth["area_fit"]))
    assert not fit["fits"]
    area = load_constellation(corridor).area
    pelvis = truth["p_world_segment"][:, list(truth["segment_names"]).index("Pelvis"), :2]
    share = float(np.mean(signed_clearance(area, pelvis) >= 0))
    assert share == pytest.approx(fit["inside_after"], abs=0.01)
    assert share > fit["inside_before"]
    # Turned and moved consistently: the UWB data still follow the truth.
    assert fit["yaw_deg"] != 0.0
    assert np.median(_toa_residuals(capture)) < 0.05


def test_fit_track_turns_a_long_track_into_a_long_area():
    # A 5 m straight line along y in a 6 x 2 m strip fits only when turned by 90 degrees.
    track = np.column_stack([np.zeros(50), np.linspace(0.0, 5.0, 50)])
    strip = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 2.0], [0.0, 2.0]])
    yaw, t = fit_track(track, strip, margin=0.4)
    c, s = np.cos(yaw), np.sin(yaw)
    placed = track @ np.array([[c, -s], [s, c]]).T + t
    assert abs(np.degrees(yaw)) >= 60.0  # the smallest turn that fits (80 deg here)
    assert np.all(_inside_rectangle(placed, [0, 0], [6, 2], 0.4))
    # A track already inside with the margin is left alone.
    inside = np.column_stack([np.linspace(1.0, 5.0, 20), np.full(20, 1.0)])
    yaw, t = fit_track(inside, strip, margin=0.4)
    assert yaw == 0.0 and np.all(t == 0.0)
