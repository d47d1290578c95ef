"""``ikfusion calibrate-uwb`` end to end on a simulated calibration log."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from ikfusion.cli import main
from ikfusion.uwb import hall_constellation, load_constellation, simulate_calibration_log, wand_path

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def write_session(folder, n_readers: int = 10, seconds: float = 30.0, seed: int = 5):
    rng = np.random.default_rng(seed)
    truth = hall_constellation(rng, n_readers=n_readers, size=(15.0, 12.0))
    t, p = wand_path("hall", seconds=seconds, size=(15.0, 12.0))
    sim = simulate_calibration_log(truth, t, p, rng, nlos_fraction=0.05)
    toa = sim.write(folder / "toa.csv")
    heights = folder / "heights.yaml"
    heights.write_text(yaml.safe_dump({"heights": sim.heights}), encoding="utf-8")
    return sim, toa, heights


def truth_in_order(sim, ids):
    """True reader positions in the order of ``ids`` (a heights file may sort its keys)."""
    return np.stack([sim.truth.positions[sim.truth.index(rid)] for rid in ids])


def test_calibrate_uwb_writes_readers_plot_and_summary(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    sim, toa, heights = write_session(tmp_path)
    out = tmp_path / "out" / "readers.yaml"
    png = tmp_path / "calibration.png"
    code = main(["calibrate-uwb", str(toa), "--heights", str(heights), "--out", str(out),
                 "--plot", str(png), "--json"])  # fmt: skip
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["readers"] == 10
    assert 0.0 < summary["outlier_fraction"] < 0.1
    readers = load_constellation(out)
    assert sorted(readers.ids) == sorted(sim.truth.ids)
    assert readers.position_covariances is not None
    np.testing.assert_allclose(readers.positions[:, 2], truth_in_order(sim, readers.ids)[:, 2],
                               atol=1e-6)  # fmt: skip
    assert png.read_bytes()[:8] == PNG_MAGIC
    assert not list(out.parent.glob(".*.tmp"))


def test_calibrate_uwb_text_output_and_survey(tmp_path, capsys):
    sim, toa, heights = write_session(tmp_path)
    survey = tmp_path / "survey.yaml"
    points = {rid: sim.truth.positions[j].tolist() for j, rid in enumerate(sim.truth.ids)
              if j in (0, 3, 6)}  # fmt: skip
    survey.write_text(yaml.safe_dump({"points": points}), encoding="utf-8")
    out = tmp_path / "readers.yaml"
    code = main(["calibrate-uwb", str(toa), "--heights", str(heights), "--out", str(out),
                 "--survey", str(survey)])  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "outliers" in text and "survey" in text
    readers = load_constellation(out)
    err = readers.positions - truth_in_order(sim, readers.ids)
    assert np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))) < 0.05


def test_four_readers_exit_2_with_the_reason(tmp_path, capsys):
    _, toa, heights = write_session(tmp_path, n_readers=4, seconds=10.0)
    out = tmp_path / "readers.yaml"
    code = main(["calibrate-uwb", str(toa), "--heights", str(heights), "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert "at least 5 readers" in err and "heights.yaml" in err
    assert not out.exists()


def test_bad_height_names_file_and_field(tmp_path, capsys):
    _, toa, heights = write_session(tmp_path, seconds=5.0)
    heights.write_text("heights: {R1: 2.5, R2: high}\n", encoding="utf-8")
    code = main(["calibrate-uwb", str(toa), "--heights", str(heights), "--out",
                 str(tmp_path / "r.yaml")])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert "heights.yaml" in err and "heights.R2" in err


def test_huge_height_is_refused_naming_file_and_reader(tmp_path, capsys):
    """A height of 1e6 m used to end in a traceback about coinciding readers."""
    _, toa, heights = write_session(tmp_path, seconds=5.0)
    data = yaml.safe_load(heights.read_text())
    first = next(iter(data["heights"]))
    data["heights"][first] = 1.0e6
    heights.write_text(yaml.safe_dump(data), encoding="utf-8")
    out = tmp_path / "r.yaml"
    code = main(["calibrate-uwb", str(toa), "--heights", str(heights), "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert "heights.yaml" in err and f"heights.{first}" in err and f"reader {first}" in err
    assert "Traceback" not in err and not out.exists()


def test_malformed_log_line_names_line_and_field(tmp_path, capsys):
    _, toa, heights = write_session(tmp_path, seconds=5.0)
    lines = toa.read_text().splitlines()
    fields = lines[5].split(",")
    fields[4] = "abc"
    lines[5] = ",".join(fields)
    toa.write_text("\n".join(lines) + "\n")
    code = main(["calibrate-uwb", str(toa), "--heights", str(heights), "--out",
                 str(tmp_path / "r.yaml")])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert "line 6" in err and "'toa'" in err
