"""Two actors walking around each other in one room: one session, one world frame."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from ikfusion.app.session import load_session
from ikfusion.cli import main
from ikfusion.errors import ConfigError
from ikfusion.mocap.model_motion import TruthMotion, site_positions
from ikfusion.paths import shipped_config
from ikfusion.sim.imu import ImuNoise
from ikfusion.sim.session_capture import circling_pair, write_session_capture
from ikfusion.uwb.constellation import load_constellation
from ikfusion.view import load_scene

CENTRE = np.array([3.0, 4.0, 0.0])  # middle of the 6 m x 8 m room


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, TruthMotion]]:
    truths = circling_pair(16.0, CENTRE)
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    folder = tmp_path_factory.mktemp("session") / "session"
    return write_session_capture(folder, truths, room, ImuNoise(), seed=5), truths


def test_relative_head_distance_with_uwb(session, tmp_path: Path) -> None:
    session_file, truths = session
    out = tmp_path / "out"
    assert main(["solve", "--session", str(session_file), "--out", str(out), "--quiet"]) == 0
    heads = {}
    for name in truths:
        summary = json.loads((out / name / "summary.json").read_text())
        assert summary["actor"] == name and summary["uwb"]["used"]
        assert set(summary["uwb"]["tags"]) == {f"{name}-T1", f"{name}-T2", f"{name}-T3"}
        rows = [r.split(",") for r in (out / name / "sites.csv").read_text().splitlines()[1:]]
        heads[name] = np.array([[float(v) for v in r[2:5]] for r in rows if r[1] == "HeadTop"])
    true = {n: site_positions(t.model, t.q, ["HeadTop"])[:, 0] for n, t in truths.items()}
    n = min(len(heads["alice"]), len(heads["bob"]), len(true["alice"]))
    d_est = np.linalg.norm(heads["alice"][:n] - heads["bob"][:n], axis=1)
    d_true = np.linalg.norm(true["alice"][:n] - true["bob"][:n], axis=1)
    assert d_true.min() > 2.5  # they do keep apart: opposite sides of a 3 m circle
    assert np.sqrt(np.mean((d_est - d_true) ** 2)) < 0.05
    for name in truths:
        err = np.linalg.norm(heads[name][:n] - true[name][:n], axis=1)
        assert np.sqrt(np.mean(err ** 2)) < 0.10
    scene = load_scene(out)
    assert sorted(a.name for a in scene.actors) == ["alice", "bob"]


def test_session_mistakes_name_the_key(session, tmp_path: Path) -> None:
    session_file, _ = session
    data = yaml.safe_load(session_file.read_text())
    data["actors"]["bob"]["imu"] = "nobody/imu"
    data["correction"] = "sometimes"
    bad = session_file.parent / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="correction"):
        load_session(bad)
    data["correction"] = "slide"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        load_session(bad)
    assert "actors.bob.imu" in str(err.value) and str(bad) in str(err.value)
    assert main(["solve", "--session", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()
