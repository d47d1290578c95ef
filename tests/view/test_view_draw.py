"""What ``ikfusion view --save`` logs: named, coloured curves; capsules; a robot's URDF meshes.

Each test saves an ``.rrd`` through the CLI and reads it back with Rerun's own reader, so it
checks what a person opening the file gets.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from view_motion import FRAMES

from ikfusion.cli import main
from ikfusion.retarget.robot_config import robots_installed
from ikfusion.view import load_scene
from ikfusion.view.draw import DEFAULT_CURVES
from ikfusion.view.shapes import capsule_poses

rerun = pytest.importorskip("rerun", reason="ikfusion view needs rerun-sdk (extra 'view')")

needs_robots = pytest.mark.skipif(not robots_installed(), reason="example-robot-data is not "
                                  "installed (pip install 'ikfusion[robots]')")


class Logged:
    """The components of a saved recording: static values and per-frame rows by entity."""

    def __init__(self, rrd: Path) -> None:
        reader = rerun.chunk.RrdReader(rrd)
        self.static: dict[str, dict[str, list[Any]]] = defaultdict(dict)
        self.frames: dict[str, dict[str, list[Any]]] = defaultdict(lambda: defaultdict(list))
        for chunk in reader.store().stream().to_chunks():
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" not in name:
                    continue
                values = batch.column(name).to_pylist()
                if chunk.is_static:
                    self.static[chunk.entity_path].setdefault(name, []).extend(values)
                else:
                    self.frames[chunk.entity_path][name].extend(values)
        self.blueprint: dict[str, list[Any]] = defaultdict(list)
        for chunk in reader.store(store=reader.blueprints()[0]).stream().to_chunks():
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" in name:
                    self.blueprint[name].extend(batch.column(name).to_pylist())

    def value(self, entity: str, component: str) -> Any:
        """The one static value of a component (its instances)."""
        values = self.static[entity][component]
        assert len(values) == 1, f"{entity} {component} logged {len(values)} times"
        return values[0]


def _save(path: Path, rrd: Path) -> Logged:
    assert main(["view", str(path), "--save", str(rrd)]) == 0
    return Logged(rrd)


def _rgb(packed: int) -> tuple[int, int, int]:
    """RGB of a Rerun colour (0xRRGGBBAA)."""
    return (packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255


def test_every_curve_and_contact_row_is_named_in_its_own_colour(result_folder: Path,
                                                                 tmp_path: Path) -> None:
    logged = _save(result_folder, tmp_path / "motion.rrd")
    columns = load_scene(result_folder).main.angle_names
    assert set(DEFAULT_CURVES) <= set(columns)
    colours = {}
    for column in columns:
        entity = f"/plots/subject/angles/{column}"
        assert logged.value(entity, "SeriesLines:names") == [column]
        colours[column] = _rgb(logged.value(entity, "SeriesLines:colors")[0])
    assert len(set(colours.values())) == len(columns), "two joint-angle curves share a colour"
    rows = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
    row_colours = set()
    for point in rows:
        entity = f"/plots/subject/contacts/{point}"
        assert logged.value(entity, "SeriesLines:names") == [point]
        row_colours.add(_rgb(logged.value(entity, "SeriesLines:colors")[0]))
    assert len(row_colours) == 4
    # both plots show their legend; the contact plot's title says which row is which
    assert logged.blueprint["PlotLegend:visible"] == [[True], [True]]
    titles = [t[0] for t in logged.blueprint["ViewBlueprint:display_name"]]
    assert "Contacts (rows 0-3: LeftHeel, LeftToe, RightHeel, RightToe; raised = in contact)" \
        in titles


def _rotate(quat_xyzw: np.ndarray, v: np.ndarray) -> np.ndarray:
    x, y, z, w = quat_xyzw
    return np.asarray(pin.Quaternion(w, x, y, z).matrix() @ v)


def test_the_human_is_drawn_as_capsules_along_its_bones(result_folder: Path,
                                                        tmp_path: Path) -> None:
    logged = _save(result_folder, tmp_path / "motion.rrd")
    actor = load_scene(result_folder).main
    entity = "/world/subject/capsules"
    labels = logged.value(entity, "Capsules3D:labels")
    radii = dict(zip(labels, logged.value(entity, "Capsules3D:radii")))
    assert len(labels) == 27  # 22 joints between the 23 segments, 5 leaf ends
    # sized by the bone: a 1.75 m subject's thigh, shank and forearm
    assert radii["RightUpperLeg>RightLowerLeg"] == pytest.approx(0.07, abs=0.01)
    assert radii["LeftLowerLeg>LeftFoot"] == pytest.approx(0.05, abs=0.01)
    assert radii["RightForeArm>RightHand"] == pytest.approx(0.035, abs=0.01)
    frames = logged.frames[entity]
    assert len(frames["Capsules3D:translations"]) == FRAMES
    knee = actor.segment_names.index("RightLowerLeg")
    hip = actor.segment_names.index("RightUpperLeg")
    thigh = labels.index("RightUpperLeg>RightLowerLeg")
    for k in (0, FRAMES // 3, FRAMES - 1):
        start = np.array(frames["Capsules3D:translations"][k][thigh])
        q = np.array(frames["Capsules3D:quaternions"][k][thigh])
        length = frames["Capsules3D:lengths"][k][thigh]
        np.testing.assert_allclose(start, actor.p_world_segment[k, hip], atol=1e-5)
        np.testing.assert_allclose(start + _rotate(q, np.array([0.0, 0.0, length])),
                                   actor.p_world_segment[k, knee], atol=1e-5)


def test_capsule_axes_turn_onto_their_bones() -> None:
    rng = np.random.default_rng(3)
    ends = np.concatenate([rng.normal(size=(50, 3)), [[0, 0, -2.0], [0, 0, 0.5], [0, 0, 0.0]]])
    strips = np.stack([np.zeros_like(ends), ends], axis=1) + np.array([0.3, -0.2, 1.0])
    start, quat_xyzw, length = capsule_poses(strips)
    np.testing.assert_allclose(length, np.linalg.norm(ends, axis=1), atol=1e-12)
    for s, q, n, e in zip(start, quat_xyzw, length, strips[:, 1]):
        np.testing.assert_allclose(s + _rotate(q, np.array([0.0, 0.0, n])), e, atol=1e-9)


def _urdf_visual_meshes(urdf: Path, share: Path) -> dict[str, list[Path]]:
    """Link -> mesh files of its ``<visual>`` elements, read from the URDF directly."""
    out: dict[str, list[Path]] = {}
    for link in ET.parse(urdf).getroot().iter("link"):
        for mesh in link.findall("visual/geometry/mesh"):
            name = mesh.get("filename", "")
            assert name.startswith("package://")
            out.setdefault(link.get("name", ""), []).append(share / name[len("package://"):])
    return out


@needs_robots
def test_a_g1_retarget_draws_every_link_mesh_once(result_folder: Path, tmp_path: Path) -> None:
    from ikfusion.retarget import retarget
    from ikfusion.retarget.robot_config import example_robot_data_dir, load_retarget_config

    out = tmp_path / "g1"
    motion, _ = retarget(result_folder, "g1", out=out)
    rrd = tmp_path / "g1.rrd"
    logged = _save(out, rrd)
    urdf = load_retarget_config("g1").urdf
    expected = _urdf_visual_meshes(urdf, example_robot_data_dir().parent.parent)
    assert len(expected) > 25
    mesh_bytes = 0
    for link, files in expected.items():
        base = f"/world/robot/links/{link}"
        for i, file in enumerate(files):
            blob = logged.value(f"{base}/{link}_{i}", "Asset3D:blob")[0]
            assert bytes(blob) == file.read_bytes(), f"{link}: not the URDF's mesh {file.name}"
            mesh_bytes += len(blob)
        # the link moves: one pose per frame, no mesh re-sent
        assert len(logged.frames[base]["Transform3D:translation"]) == FRAMES
        assert not any(e.startswith(base) and "Asset3D:blob" in c
                       for e, c in logged.frames.items())
    # the pelvis is the root link: it follows the written root position
    pelvis = np.array(logged.frames["/world/robot/links/pelvis"]["Transform3D:translation"])
    np.testing.assert_allclose(pelvis.reshape(-1, 3), motion.root_pos, atol=1e-6)
    # each mesh is in the file once, not once per frame
    assert rrd.stat().st_size < 1.5 * mesh_bytes
