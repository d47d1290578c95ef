"""Constellation files: the shipped ones load, bad ones fail naming file and key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import ConfigError
from ikfusion.paths import configs_dir
from ikfusion.uwb import load_constellation, make_constellation, save_constellation

SHIPPED = sorted((configs_dir() / "constellations").glob("*.yaml"))

EXPECTED_READERS = {
    "minimal_4": 4,
    "small_6": 6,
    "medium_9": 9,
    "highend_12": 12,
    "room_6x8": 10,
    "stage_24x10": 12,
    "movie_set": 10,
    "corridor_75m": 18,
}


def test_every_expected_constellation_is_shipped():
    assert {p.stem for p in SHIPPED} == set(EXPECTED_READERS)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_constellations_load(path):
    c = load_constellation(path)
    assert len(c.readers) == EXPECTED_READERS[path.stem]
    assert c.area is not None and c.range is not None and c.sigma == 0.03
    assert np.all(c.clock_offsets == 0.0)  # planning files (README.md)
    # Every reader sits on the border of (or above) its capture area's bounding box.
    lo, hi = c.area.min(axis=0), c.area.max(axis=0)
    assert np.all(c.positions[:, :2] >= lo - 1e-9) and np.all(c.positions[:, :2] <= hi + 1e-9)


def test_room_and_stage_geometry():
    room = load_constellation(configs_dir() / "constellations" / "room_6x8.yaml")
    xy = room.positions[:, :2]
    on_border = (
        np.isclose(xy[:, 0], 0)
        | np.isclose(xy[:, 0], 6)
        | np.isclose(xy[:, 1], 0)
        | np.isclose(xy[:, 1], 8)
    )
    assert on_border.all()
    stage = load_constellation(configs_dir() / "constellations" / "stage_24x10.yaml")
    z = stage.positions[:, 2]
    assert np.count_nonzero(z == 7.0) == 8 and np.count_nonzero(z < 0.5) == 4
    np.testing.assert_allclose(np.ptp(stage.area, axis=0), [24, 10])


def test_round_trip(tmp_path):
    c = make_constellation(
        [[0, 0, 2], [5, 0, 0.5], [5, 5, 2], [0, 5, 0.5]],
        clock_offsets=[0.0, 1.5, -2.25, 3.0],
        coverage=25.0,
        sigma=0.05,
        area=[[0, 0], [5, 0], [5, 5], [0, 5]],
        name="t",
    )
    path = save_constellation(c, tmp_path / "sub" / "c.yaml")
    back = load_constellation(path)
    assert back.ids == c.ids and back.range == 25.0 and back.sigma == 0.05
    np.testing.assert_array_equal(back.positions, c.positions)
    np.testing.assert_array_equal(back.clock_offsets, c.clock_offsets)
    np.testing.assert_array_equal(back.area, c.area)
    assert [p.name for p in tmp_path.joinpath("sub").iterdir()] == ["c.yaml"]  # no temp left


@pytest.mark.parametrize(
    ("text", "key", "message"),
    [
        ("readers: []", "readers", "at least one reader"),
        ("readers: {R1: 1}", "readers", "list of readers"),
        ("readers:\n  - {id: R1, position: [0, 0]}", "readers[0].position", "3 numbers"),
        ("readers:\n  - {id: R1, postion: [0, 0, 0]}", "readers[0].postion", "unknown key"),
        ("readers:\n  - {position: [0, 0, 0]}", "readers[0].id", "missing reader id"),
        ("readers:\n  - {id: R1, position: [0, 0, .nan]}", "readers[0].position", "finite"),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1], clock_offset: x}",
            "readers[0].clock_offset",
            "finite number",
        ),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1]}\n  - {id: R1, position: [1, 0, 1]}",
            "readers[1].id",
            "duplicate",
        ),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1]}\n  - {id: R2, position: [0, -1e30, 1]}",
            "readers[1].position",
            "reader R2: coordinates .* beyond 1000 m",
        ),
        ("readers:\n  - {id: R1, position: [0, 0, 1.0e+6]}", "readers[0].position", "beyond"),
        (
            "readers:\n  - {id: R7, position: [0, 0, 1], clock_offset: 1.0e+30}",
            "readers[0].clock_offset",
            "reader R7: .*at most",
        ),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1]}\narea: [[0, 0], [5000, 0], [0, 3]]",
            "area[1]",
            "beyond",
        ),
        ("readers:\n  - {id: R1, position: [0, 0, 1]}\nrange: -3", "range", "positive"),
        ("readers:\n  - {id: R1, position: [0, 0, 1]}\nsigma: 0", "sigma", "positive"),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1]}\narea: [[0, 0], [1, 1]]",
            "area",
            "at least 3",
        ),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1]}\narea: [[0, 0], [1, 1], [2, 2]]",
            "area",
            "zero area",
        ),
        ("readers:\n  - {id: R1, position: [0, 0, 1]}\nsigm: 0.1", "sigm", "unknown key"),
        (
            "readers:\n  - {id: R1, position: [0, 0, 1],\n     position_covariance: "
            "[[1, 0, 0], [0, 1, 0], [0, 0, -1]]}",
            "readers[0].position_covariance",
            "semi-definite",
        ),
    ],
)
def test_bad_files_name_file_and_key(tmp_path, text, key, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as info:
        load_constellation(path)
    assert info.value.path == Path(path) and info.value.field == key
    assert str(path) in str(info.value) and repr(key) in str(info.value)


def test_not_yaml_names_the_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("readers:\n  - {id: R1, position: [0, 0, 1]\n")
    with pytest.raises(ConfigError) as info:
        load_constellation(path)
    assert info.value.line is not None


def test_reader_covariance_is_kept(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(
        "readers:\n  - {id: A, position: [0, 0, 1], position_covariance: "
        "[[1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 4e-4]]}\n  - {id: B, position: [1, 0, 1]}\n"
    )
    c = load_constellation(path)
    cov = c.position_covariances
    assert cov.shape == (2, 3, 3)
    np.testing.assert_array_equal(cov[0], np.diag([1e-4, 1e-4, 4e-4]))
    np.testing.assert_array_equal(cov[1], 0.0)
    assert make_constellation([[0, 0, 0]]).position_covariances is None
