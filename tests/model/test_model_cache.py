"""The on-disk cache of human models: a loaded model equals a built one, keyed by the body."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.model import human_model
from ikfusion.model.body import Body
from ikfusion.model.human_model import HumanModel
from ikfusion.model.model_cache import entry_folder
from ikfusion.model.urdf import body_to_urdf


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty cache folder, and no model of any body kept in this process."""
    monkeypatch.setenv("IKFUSION_CACHE", str(tmp_path / "cache"))
    human_model._model_of_body.cache_clear()
    yield tmp_path / "cache"
    human_model._model_of_body.cache_clear()


def _fresh_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Forget the models kept in this process; refuse to build one or to write its URDF."""
    human_model._model_of_body.cache_clear()

    def no_build(*_: object) -> None:
        raise AssertionError("the model was built although it is cached")

    def no_text(*_: object) -> None:
        raise AssertionError("the URDF text was written although the model is cached")

    monkeypatch.setattr(HumanModel, "_from_urdf_text", no_build)
    monkeypatch.setattr(human_model, "body_to_urdf", no_text)


def _assert_same_model(a: HumanModel, b: HumanModel) -> None:
    assert a.model == b.model and a.revolute_model == b.revolute_model
    assert a.ball_joints == b.ball_joints and a.joint_map == b.joint_map
    assert a.sites == b.sites and a.segment_names == b.segment_names and a.body == b.body
    np.testing.assert_array_equal(a.neutral(), b.neutral())
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = a.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        for name in ("RightHand", "LeftToe", "HeadTop"):
            np.testing.assert_array_equal(a.site_position(q, name), b.site_position(q, name))
        np.testing.assert_array_equal(a.joint_angle_matrix(q), b.joint_angle_matrix(q))


def test_a_cached_model_equals_a_fresh_one(cache: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    body = Body.from_dict({"height": 1.62, "upper_leg": 0.41, "forearm": 0.25})
    fresh = HumanModel._from_urdf_text(body_to_urdf(body), body)
    built = HumanModel.from_body(body)  # built and stored
    assert (entry_folder(body) / "sha256").is_file()
    _fresh_process(monkeypatch)
    loaded = HumanModel.from_body(body)
    assert loaded.urdf_path is None
    _assert_same_model(loaded, fresh)
    _assert_same_model(loaded, built)


def test_other_dimensions_get_their_own_model(cache: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    short, long = (Body.from_dict({"height": 1.75, "lower_leg": leg}) for leg in (0.40, 0.46))
    a, b = HumanModel.from_body(short), HumanModel.from_body(long)
    folders = {entry_folder(x) for x in (short, long)}
    assert len(folders) == 2 and all(f.is_dir() for f in folders)
    _fresh_process(monkeypatch)
    a2, b2 = HumanModel.from_body(short), HumanModel.from_body(long)
    assert a2.body == short and b2.body == long
    shin = [float(m.model.jointPlacements[m.ball_joint("jRightAnkle").joint_id].translation[2])
            for m in (a2, b2)]
    assert shin[0] == pytest.approx(-0.40, abs=1e-9) and shin[1] == pytest.approx(-0.46, abs=1e-9)
    _assert_same_model(a2, a)
    _assert_same_model(b2, b)


def test_a_damaged_entry_is_rebuilt_not_loaded(cache: Path) -> None:
    body = Body.from_height(1.8)
    reference = HumanModel.from_body(body)
    tables = entry_folder(body) / "tables.pickle"
    data = bytearray(tables.read_bytes())
    data[len(data) // 2] ^= 0xFF
    tables.write_bytes(bytes(data))
    human_model._model_of_body.cache_clear()
    _assert_same_model(HumanModel.from_body(body), reference)
    human_model._model_of_body.cache_clear()  # the entry was written anew, and loads
    assert tables.read_bytes() != bytes(data)


def test_an_unwritable_cache_only_costs_time(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("a file where the cache folder would be\n")
    monkeypatch.setenv("IKFUSION_CACHE", str(blocker))
    human_model._model_of_body.cache_clear()
    try:
        model = HumanModel.from_body(Body.from_height(1.7))
    finally:
        human_model._model_of_body.cache_clear()
    q = model.neutral()
    assert pin.neutral(model.model).shape == q.shape
    assert min(model.site_position(q, n)[2] for n in ("LeftHeel", "RightToe")) == \
        pytest.approx(0.0, abs=1e-9)


def test_the_least_recently_used_entries_go_first(cache: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    from ikfusion.model import model_cache

    monkeypatch.setattr(model_cache, "MAX_ENTRIES", 2)
    bodies = [Body.from_height(h) for h in (1.6, 1.7, 1.8)]
    folders = [entry_folder(b) for b in bodies]
    for body in bodies[:2]:
        HumanModel.from_body(body)
    for i, folder in enumerate(folders[:2]):  # the first one built, the second used later
        os.utime(folder, ns=(10**18 + i, 10**18 + i))
    human_model._model_of_body.cache_clear()
    HumanModel.from_body(bodies[0])  # loaded: now the most recently used
    HumanModel.from_body(bodies[2])  # a third entry: the one used least recently goes
    assert [f.is_dir() for f in folders] == [True, False, True]


def test_equal_bodies_hit_and_other_bodies_or_joint_files_miss(
        cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from ikfusion.model import model_cache
    from ikfusion.paths import shipped_config

    body = Body.from_dict({"height": 1.71, "upper_arm": 0.3})
    built = HumanModel.from_body(body)
    twin = Body.from_dict({"upper_arm": 0.3, "height": 1.71})  # equal, made apart
    assert entry_folder(twin) == entry_folder(body)
    _fresh_process(monkeypatch)  # an equal body loads without building or writing a URDF
    _assert_same_model(HumanModel.from_body(twin), built)
    others = [Body.from_dict({"height": 1.71, "upper_arm": 0.3 + 1e-12}),  # the text rounds
              Body.from_dict({"height": 1.71, "upper_arm": 0.3, "mass": 70.0}),
              Body.from_dict({"height": 1.71, "upper_arm": 0.3,
                              "ranges": "athlete"})]
    folders = {entry_folder(b) for b in [body, *others]}
    assert len(folders) == 1 + len(others)
    joints = tmp_path / "joints.yaml"  # other shipped ranges of motion: another model
    joints.write_text(shipped_config("joints.yaml").read_text().replace("[-20, 35]", "[-20, 36]"))
    monkeypatch.setattr(model_cache, "shipped_config", lambda *_: joints)
    assert entry_folder(body) not in folders
