"""``motion.mot``: header, columns, signs against our angles, and the pelvis rotation rebuilt."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import ConfigError
from ikfusion.ik import Motion
from ikfusion.model import CONTACT_SITES, HumanModel
from ikfusion.paths import shipped_config
from ikfusion.results.opensim_export import (
    C_OPENSIM_OURS,
    load_opensim_mapping,
    write_motion_mot,
)
from ikfusion.rotations import axis_rotation, matrix_to_quat_wxyz, wxyz_to_xyzw
from ikfusion.sim.gait import GaitParameters, generate_gait

RAJAGOPAL_COLUMNS = [
    "pelvis_tilt", "pelvis_list", "pelvis_rotation", "pelvis_tx", "pelvis_ty", "pelvis_tz",
    "hip_flexion_r", "hip_flexion_l", "hip_adduction_r", "hip_adduction_l",
    "hip_rotation_r", "hip_rotation_l", "knee_angle_r", "knee_angle_l",
    "ankle_angle_r", "ankle_angle_l", "subtalar_angle_r", "subtalar_angle_l",
    "mtp_angle_r", "mtp_angle_l", "lumbar_extension", "lumbar_bending", "lumbar_rotation",
    "arm_flex_r", "arm_flex_l", "arm_add_r", "arm_add_l", "arm_rot_r", "arm_rot_l",
    "elbow_flex_r", "elbow_flex_l", "pro_sup_r", "pro_sup_l",
    "wrist_flex_r", "wrist_flex_l", "wrist_dev_r", "wrist_dev_l",
]


@pytest.fixture(scope="module")
def human() -> HumanModel:
    return HumanModel.default()


def make_motion(model: HumanModel, rng: np.random.Generator, n: int = 8) -> Motion:
    """Random in-range configurations; the pelvis walks, turns, tilts and lists."""
    qs = np.array([model.random_configuration(rng, margin_deg=2.0,
                                              p_world_pelvis=[0.1 * k, -0.05 * k, 0.9])
                   for k in range(n)])
    for q in qs:
        tilt, roll, yaw = rng.uniform([-0.8, -0.8, -np.pi], [0.8, 0.8, np.pi])
        R = axis_rotation("z", yaw) @ axis_rotation("y", tilt) @ axis_rotation("x", roll)
        q[3:7] = wxyz_to_xyzw(matrix_to_quat_wxyz(R))
    return Motion(model, np.arange(n) / 60.0, qs, list(CONTACT_SITES),
                  np.zeros((n, 4), dtype=bool), np.full(n, 1e-3), np.full(n, 2),
                  np.zeros(n, dtype=bool))


def read_mot(path: Path) -> tuple[dict[str, str], list[str], np.ndarray, str]:
    """Our own .mot reader: header fields, column labels, the table and the name line."""
    lines = path.read_text().splitlines()
    end = lines.index("endheader")
    fields = dict(line.split("=", 1) for line in lines[1:end])
    labels = lines[end + 1].split("\t")
    table = np.array([[float(v) for v in line.split("\t")] for line in lines[end + 2:]])
    return fields, labels, table, lines[0]


@pytest.fixture
def written(human: HumanModel, rng: np.random.Generator, tmp_path: Path
            ) -> tuple[Motion, Path]:
    motion = make_motion(human, rng)
    return motion, write_motion_mot(tmp_path / "motion.mot", motion)


def column(labels: list[str], table: np.ndarray, name: str) -> np.ndarray:
    return table[:, labels.index(name)]


def test_header_and_columns(written: tuple[Motion, Path]) -> None:
    motion, path = written
    fields, labels, table, name = read_mot(path)
    assert name.strip()
    assert fields == {"version": "1", "nRows": str(len(motion)),
                      "nColumns": str(1 + len(RAJAGOPAL_COLUMNS)), "inDegrees": "yes"}
    assert labels == ["time", *RAJAGOPAL_COLUMNS]
    assert table.shape == (len(motion), 1 + len(RAJAGOPAL_COLUMNS))
    np.testing.assert_allclose(table[:, 0], motion.time, atol=1e-6)


def test_angles_and_signs(human: HumanModel, written: tuple[Motion, Path]) -> None:
    motion, path = written
    _, labels, table, _ = read_mot(path)
    ours = dict(zip(human.angle_columns, motion.joint_angles().T))
    expected = {
        "knee_angle_r": ours["jRightKnee_flex"], "knee_angle_l": ours["jLeftKnee_flex"],
        "hip_flexion_r": ours["jRightHip_flex"], "hip_adduction_r": -ours["jRightHip_abd"],
        "hip_adduction_l": -ours["jLeftHip_abd"], "hip_rotation_l": ours["jLeftHip_rot"],
        "ankle_angle_r": ours["jRightAnkle_flex"], "subtalar_angle_l": ours["jLeftAnkle_abd"],
        "mtp_angle_r": -ours["jRightBallFoot_flex"], "elbow_flex_l": ours["jLeftElbow_flex"],
        "pro_sup_r": ours["jRightElbow_rot"] + 90.0, "wrist_dev_r": -ours["jRightWrist_abd"],
    }
    for name, values in expected.items():
        np.testing.assert_allclose(column(labels, table, name), values, atol=0.1, err_msg=name)


def test_pelvis_translation_is_y_up(human: HumanModel, written: tuple[Motion, Path]) -> None:
    motion, path = written
    _, labels, table, _ = read_mot(path)
    p = np.array([human.segment_position(q, "Pelvis") for q in motion.q])
    np.testing.assert_allclose(column(labels, table, "pelvis_tx"), p[:, 0], atol=1e-6)
    np.testing.assert_allclose(column(labels, table, "pelvis_ty"), p[:, 2], atol=1e-6)
    np.testing.assert_allclose(column(labels, table, "pelvis_tz"), -p[:, 1], atol=1e-6)


def opensim_zxy(angles_deg: np.ndarray) -> np.ndarray:
    """OpenSim's body-fixed Z, X, Y rotation from three angles [deg]."""
    a = np.radians(angles_deg)
    return axis_rotation("z", a[0]) @ axis_rotation("x", a[1]) @ axis_rotation("y", a[2])


def test_pelvis_angles_rebuild_the_pelvis_rotation(human: HumanModel,
                                                   written: tuple[Motion, Path]) -> None:
    motion, path = written
    _, labels, table, _ = read_mot(path)
    names = ("pelvis_tilt", "pelvis_list", "pelvis_rotation")
    angles = np.column_stack([column(labels, table, n) for n in names])
    for k, q in enumerate(motion.q):
        R_opensim = C_OPENSIM_OURS @ human.segment_rotation(q, "Pelvis") @ C_OPENSIM_OURS.T
        # six decimals in the file: 5e-7 deg rounding, far below 1e-6 in the matrix entries
        np.testing.assert_allclose(opensim_zxy(angles[k]), R_opensim, atol=1e-6)


def test_lumbar_and_arm_rebuild_relative_rotations(human: HumanModel,
                                                   written: tuple[Motion, Path]) -> None:
    motion, path = written
    _, labels, table, _ = read_mot(path)
    C = C_OPENSIM_OURS
    for k, q in enumerate(motion.q):
        R = {s: human.segment_rotation(q, s) for s in ("Pelvis", "T8", "RightUpperArm",
                                                      "LeftUpperArm")}
        row = dict(zip(labels, table[k]))
        lumbar = opensim_zxy(np.array([row["lumbar_extension"], row["lumbar_bending"],
                                       row["lumbar_rotation"]]))
        np.testing.assert_allclose(lumbar, C @ R["Pelvis"].T @ R["T8"] @ C.T, atol=1e-6)
        right = opensim_zxy(np.array([row["arm_flex_r"], row["arm_add_r"], row["arm_rot_r"]]))
        np.testing.assert_allclose(right, C @ R["T8"].T @ R["RightUpperArm"] @ C.T, atol=1e-6)
        left = opensim_zxy(np.array([row["arm_flex_l"], -row["arm_add_l"], -row["arm_rot_l"]]))
        np.testing.assert_allclose(left, C @ R["T8"].T @ R["LeftUpperArm"] @ C.T, atol=1e-6)


def test_lumbar_extension_is_minus_spine_flexion(human: HumanModel, tmp_path: Path) -> None:
    spine = {f"{j}_flex": 10.0 for j in ("jL5S1", "jL4L3", "jL1T12", "jT9T8")}
    q = human.configuration(spine)
    motion = Motion(human, np.array([0.0]), q[None], [], np.zeros((1, 0), dtype=bool),
                    np.zeros(1), np.zeros(1, dtype=int), np.zeros(1, dtype=bool))
    _, labels, table, _ = read_mot(write_motion_mot(tmp_path / "m.mot", motion))
    assert column(labels, table, "lumbar_extension")[0] == pytest.approx(-40.0, abs=1e-5)
    assert column(labels, table, "lumbar_bending")[0] == pytest.approx(0.0, abs=1e-5)


def test_gait2392_flips_knee_and_mtp(written: tuple[Motion, Path], tmp_path: Path) -> None:
    motion, path = written
    _, labels, rajagopal, _ = read_mot(path)
    _, _, gait, _ = read_mot(write_motion_mot(tmp_path / "g.mot", motion,
                                              convention="gait2392"))
    for name in RAJAGOPAL_COLUMNS:
        sign = -1.0 if name.startswith(("knee_angle", "mtp_angle")) else 1.0
        np.testing.assert_allclose(column(labels, gait, name),
                                   sign * column(labels, rajagopal, name), atol=1e-9)


def test_pelvis_rotation_is_continuous_when_turning(human: HumanModel, tmp_path: Path) -> None:
    yaw = np.radians(np.linspace(0.0, 400.0, 41))
    qs = np.array([human.configuration(R_world_pelvis=axis_rotation("z", a)) for a in yaw])
    n = len(qs)
    motion = Motion(human, np.arange(n) / 60.0, qs, [], np.zeros((n, 0), dtype=bool),
                    np.zeros(n), np.zeros(n, dtype=int), np.zeros(n, dtype=bool))
    _, labels, table, _ = read_mot(write_motion_mot(tmp_path / "turn.mot", motion))
    np.testing.assert_allclose(column(labels, table, "pelvis_rotation"), np.degrees(yaw),
                               atol=1e-4)


def test_bad_mapping_names_the_row(tmp_path: Path) -> None:
    bad = tmp_path / "opensim.yaml"
    bad.write_text("coordinates:\n  knee_angle_r: {angle: jRightKnee_flex, euler: [a, b]}\n")
    with pytest.raises(ConfigError, match="knee_angle_r"):
        load_opensim_mapping(bad)


def test_the_shipped_mapping_is_read_once_per_process(tmp_path: Path) -> None:
    # Every solve exported motion.mot through a fresh YAML parse of configs/opensim.yaml
    # (~0.1 s of a 2505-frame solve's writing); the immutable mapping is now read once.
    first = load_opensim_mapping()
    assert load_opensim_mapping() is first
    copy = tmp_path / "opensim.yaml"
    copy.write_text(shipped_config("opensim.yaml").read_text())
    assert load_opensim_mapping(copy) == first  # a named file is still read as given


_OPENSIM_READER = """
import json, sys
import opensim
table = opensim.TimeSeriesTable(sys.argv[1])
labels = list(table.getColumnLabels())
knee = table.getDependentColumn("knee_angle_r").to_numpy().tolist()
print(json.dumps({"labels": labels, "rows": table.getNumRows(), "knee": knee,
                  "inDegrees": table.getTableMetaDataAsString("inDegrees")}))
"""


@pytest.fixture(scope="module")
def walk(human: HumanModel) -> Motion:
    """A simulated walk (the gait generator's truth) as a Motion."""
    truth = generate_gait(human, GaitParameters(path="straight", duration=3.0, stand=0.5))
    n = len(truth.time)
    return Motion(human, truth.time, truth.q, list(CONTACT_SITES), np.zeros((n, 4), dtype=bool),
                  np.full(n, 1e-3), np.full(n, 1), np.zeros(n, dtype=bool))


@pytest.mark.parametrize("source", ["random", "walk"])
def test_opensim_reads_the_file(source: str, written: tuple[Motion, Path], walk: Motion,
                                tmp_path: Path) -> None:
    """OpenSim's own reader, in a separate process, on random poses and on a simulated walk;
    its ``knee_angle_r`` (Rajagopal: flexion positive) is our ``jRightKnee_flex``.

    The ``opensim`` wheel bundles its own ``libcasadi.so.3.7``, built apart from the ``casadi``
    package ikfusion imports; both have the same soname, so whichever loads second fails with
    an undefined symbol. Hence a subprocess instead of ``pytest.importorskip("opensim")`` here.
    """
    if importlib.util.find_spec("opensim") is None:
        pytest.skip("opensim is not installed: it is the test-only extra "
                    "(pip install 'ikfusion[opensim]' or pip install opensim)")
    motion, path = written if source == "random" else (
        walk, write_motion_mot(tmp_path / "walk.mot", walk))
    result = subprocess.run([sys.executable, "-c", _OPENSIM_READER, str(path)],
                            capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert out["labels"] == RAJAGOPAL_COLUMNS
    assert out["rows"] == len(motion)
    assert out["inDegrees"] == "yes"
    ours = motion.joint_angles()[:, motion.model.angle_columns.index("jRightKnee_flex")]
    np.testing.assert_allclose(out["knee"], ours, atol=0.1)
    if source == "walk":
        assert np.ptp(ours) > 30.0  # the knee swings
