"""Seed inputs of the fuzz campaign: small real files for every reader the CLI exposes.

Each :class:`Seed` is a folder of its own (copied afresh for every case) holding the file to
mutate and any sibling files the reader needs, plus the cheapest CLI command that reads the file
fully (``argv``, with ``{dir}`` the case's copy of the folder, ``{file}`` the mutated file and
``{out}`` an empty output folder) or, when that command would solve a whole recording, the
reader function the command calls (``call``). Everything is written under a temporary root:
trimmed copies of shared recordings are made there, never in the repository.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ikfusion.cli import main

REPO = Path(__file__).resolve().parents[2]
#: Relative frequency of each reader's cases (1 when absent): the slow drivers (model, evaluate,
#: locate, simulate from a BVH, solve of a mutated recording) get fewer cases.
WEIGHTS: dict[str, float] = {"body": 0.25, "truth": 0.4, "toa": 0.6, "bvh": 0.15, "mvnx": 0.8,
                             "imu_solve": 0.08}
CONFIGS = REPO / "configs"


@dataclass(frozen=True)
class Seed:
    """One seed file and the command that reads it.

    Attributes:
        reader: The reader family (``mtmanager``, ``bvh``, ``constellation``, ...).
        source: A short name of the seed (no colons), unique within the reader.
        folder: The seed's own folder, copied for every case.
        target: The file to mutate, relative to ``folder``.
        argv: ``ikfusion`` arguments with ``{dir}``, ``{file}``, ``{out}`` placeholders.
        call: Instead of ``argv``: ``(command name, reader function)``.
        binary: Only byte-level mutations make sense (``truth.npz``).
    """

    reader: str
    source: str
    folder: Path
    target: str
    argv: tuple[str, ...] = ()
    call: tuple[str, Callable[[Path], object]] | None = None
    binary: bool = False


def _own_folder(root: Path, reader: str, source: str, files: dict[str, bytes]) -> Path:
    folder = root / "seeds" / reader / source
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (folder / name).write_bytes(data)
    return folder


def trim_mtmanager(text: str, rows: int) -> str:
    """The comment and header lines of an MT Manager export and its first ``rows`` samples."""
    lines = text.splitlines(keepends=True)
    start = next(i for i, line in enumerate(lines) if line.startswith("PacketCounter")) + 1
    return "".join(lines[: start + rows])


def trim_bvh(text: str, frames: int) -> str:
    """A BVH file cut to its first ``frames`` frames (the ``Frames:`` line updated)."""
    head, motion = text.split("MOTION", 1)
    lines = motion.strip().splitlines()
    body = [ln for ln in lines[2:] if ln.strip()][:frames]
    return head + f"MOTION\nFrames: {len(body)}\n{lines[1].strip()}\n" + "\n".join(body) + "\n"


def trim_mvnx(text: str, frames: int) -> str:
    """An MVNX file with only its first ``frames`` frames of type ``normal``."""
    kept = 0

    def keep(match: re.Match[str]) -> str:
        nonlocal kept
        if 'type="normal"' not in match.group(0)[:200]:
            return match.group(0)
        kept += 1
        return match.group(0) if kept <= frames else ""

    return re.sub(r"[ \t]*<frame .*?</frame>\s*\n", keep, text, flags=re.S)


@dataclass(frozen=True)
class Capture:
    """The tiny simulated capture, its solve result, and the files derived from it."""

    folder: Path
    result: Path


def simulate_capture(root: Path) -> Capture:
    """``ikfusion simulate`` (3 s at 30 Hz, 6 readers) and ``ikfusion solve`` of it, once."""
    cap = root / "capture"
    code = main(["simulate", "--seconds", "3", "--rate", "30", "--seed", "7", "--readers",
                 str(CONFIGS / "constellations" / "small_6.yaml"), "--out", str(cap), "--quiet"])
    if code != 0:
        raise RuntimeError(f"ikfusion simulate failed with exit {code}")
    result = root / "result"
    code = main(["solve", "--imu", str(cap / "imu"), "--map", str(cap / "sensors.yaml"),
                 "--body", str(cap / "body.yaml"), "--out", str(result), "--quiet"])
    if code != 0:
        raise RuntimeError(f"ikfusion solve failed with exit {code}")
    return Capture(cap, result)


def _imu_csv(cap: Path, samples: int) -> bytes:
    """A generic IMU CSV (SPEC section 4) of the capture's first ``samples`` samples."""
    from ikfusion.io.reader import read_imu

    rec = read_imu(cap / "imu")
    rows = ["time,sensor,qw,qx,qy,qz,ax,ay,az,gx,gy,gz"]
    for k in range(min(samples, len(rec))):
        for sid, s in rec.sensors.items():
            q = s.quat_wxyz(k)
            acc = s.acc[k] if s.acc is not None else np.zeros(3)
            gyr = s.gyr[k] if s.gyr is not None else np.zeros(3)
            rows.append(",".join([f"{k / rec.rate:.4f}", sid, *(f"{v:.6f}" for v in q),
                                  *(f"{v:.5f}" for v in acc), *(f"{v:.6f}" for v in gyr)]))
    return ("\n".join(rows) + "\n").encode()


def _renamed_capture(root: Path, cap: Path, sensor_map: Path, name: str) -> Path:
    """The capture's IMU files renamed to the ids of ``sensor_map`` (matched by segment)."""
    by_segment = {seg: sid for sid, seg in
                  yaml.safe_load((cap / "sensors.yaml").read_text())["sensors"].items()}
    wanted = yaml.safe_load(sensor_map.read_text())["sensors"]
    files = {f"SIM_{sid}.txt": (cap / "imu" / f"SIM_{by_segment[seg]}.txt").read_bytes()
             for sid, seg in wanted.items() if seg in by_segment}
    return _own_folder(root, "recordings", name, files)


def repo_seeds(root: Path, capture: Capture) -> list[Seed]:
    """Seeds from the repository's configs and the simulated capture (always available)."""
    from ikfusion.app.session import load_session
    from ikfusion.uwb.calibration_files import load_heights
    from ikfusion.uwb.tracking import load_tags

    cap = capture.folder
    imu_files = sorted((cap / "imu").glob("*.txt"))
    seeds: list[Seed] = []
    inspect_file = ("inspect", "{file}", "--json")
    inspect_dir = ("inspect", "{dir}", "--json")
    first = imu_files[0]
    seeds.append(Seed("mtmanager", "sim_" + first.stem[-8:], _own_folder(
        root, "mtmanager", "sim", {first.name: first.read_bytes()}), first.name, inspect_file))
    trial = {f.name: f.read_bytes() for f in imu_files}
    for f in (imu_files[0], imu_files[13]):
        folder = _own_folder(root, "mt_trial", "sim_" + f.stem[-8:], trial)
        seeds.append(Seed("mt_trial", "sim_" + f.stem[-8:], folder, f.name, inspect_dir))
    solve = ("solve", "--imu", "{dir}", "--map", str(cap / "sensors.yaml"), "--body",
             str(cap / "body.yaml"), "--out", "{out}/result", "--quiet")
    for f in (imu_files[0], imu_files[12]):  # pelvis, right lower leg: solved end to end
        folder = _own_folder(root, "imu_solve", "sim_" + f.stem[-8:], trial)
        seeds.append(Seed("imu_solve", "sim_" + f.stem[-8:], folder, f.name, solve))
    seeds.append(Seed("imu_csv", "sim_csv", _own_folder(
        root, "imu_csv", "sim", {"imu.csv": _imu_csv(cap, 30)}), "imu.csv", inspect_file))

    maps = {"sim_sensors": (cap / "sensors.yaml")} | {
        p.stem: p for p in sorted((CONFIGS / "sensors").glob("*.yaml"))}
    for name, path in maps.items():
        folder = _own_folder(root, "sensor_map", name, {path.name: path.read_bytes()})
        recording = _renamed_capture(root, cap, path, name)
        seeds.append(Seed("sensor_map", name, folder, path.name,
                          ("inspect", str(recording), "--json", "--map", "{file}")))

    seeds.append(Seed("body", "sim_body", _own_folder(
        root, "body", "sim", {"body.yaml": (cap / "body.yaml").read_bytes()}), "body.yaml",
        ("model", "--body", "{file}", "--json")))

    plan = ("plan", "{file}", "--no-plot", "--json", "--step", "2")
    consts = {"sim_readers": cap / "readers.yaml"} | {
        p.stem: p for p in sorted((CONFIGS / "constellations").glob("*.yaml"))}
    for name, path in consts.items():
        folder = _own_folder(root, "constellation", name, {path.name: path.read_bytes()})
        seeds.append(Seed("constellation", name, folder, path.name, plan))

    seeds.append(Seed("tags", "sim_tags", _own_folder(
        root, "tags", "sim", {"tags.yaml": (cap / "tags.yaml").read_bytes()}), "tags.yaml",
        call=("solve", load_tags)))
    readers = yaml.safe_load((cap / "readers.yaml").read_text())["readers"]
    heights = yaml.safe_dump({"heights": {r["id"]: r["position"][2] for r in readers}})
    seeds.append(Seed("heights", "sim_heights", _own_folder(
        root, "heights", "sim", {"heights.yaml": heights.encode()}), "heights.yaml",
        call=("calibrate-uwb", load_heights)))
    session = yaml.safe_dump({
        "toa": str(cap / "toa.csv"), "readers": str(cap / "readers.yaml"),
        "tags": str(cap / "tags.yaml"), "correction": "no-slide",
        "actors": {"A": {"imu": str(cap / "imu"), "map": str(cap / "sensors.yaml"),
                         "body": str(cap / "body.yaml")}}}, sort_keys=False)
    seeds.append(Seed("session", "sim_session", _own_folder(
        root, "session", "sim", {"session.yaml": session.encode()}), "session.yaml",
        call=("solve", load_session)))

    toa = "".join((cap / "toa.csv").read_text().splitlines(keepends=True)[:181])
    seeds.append(Seed("toa", "sim_toa", _own_folder(
        root, "toa", "sim", {"toa.csv": toa.encode()}), "toa.csv",
        ("locate", "{file}", "--readers", str(cap / "readers.yaml"), "--out",
         "{out}/fixes.csv", "--json")))
    seeds.append(Seed("truth", "sim_truth", _own_folder(
        root, "truth", "sim", {"truth.npz": (cap / "truth.npz").read_bytes()}), "truth.npz",
        ("evaluate", str(capture.result), "{file}", "--json"), binary=True))
    return seeds


def shared_seeds(root: Path, shared: Path) -> list[Seed]:
    """Seeds from the real recordings under ``shared/data`` (trimmed copies under ``root``)."""
    seeds: list[Seed] = []
    inspect_file = ("inspect", "{file}", "--json")
    for path in sorted((shared / "xsens" / "formats").glob("*.txt")):
        text = trim_mtmanager(path.read_text(encoding="utf-8", errors="replace"), 200)
        source = path.stem.replace("MT2022_", "").replace("_", "-")[-24:]
        folder = _own_folder(root, "mtmanager", source, {path.name: text.encode()})
        seeds.append(Seed("mtmanager", source, folder, path.name, inspect_file))
        if "// Update Rate:" not in text:  # also read past the rate, as `--rate` lets users
            seeds.append(Seed("mtmanager", source + "-rate100", folder, path.name,
                              (*inspect_file, "--rate", "100")))
    mt46 = {p.name: p.read_bytes() for p in (shared / "xsens" / "formats").glob("MT46_*.txt")}
    folder = _own_folder(root, "mt_trial", "MT46_prefix", mt46)
    seeds.append(Seed("mt_trial", "MT46_prefix", folder, sorted(mt46)[0],
                      ("inspect", "{dir}/MT46_01-000_", "--json")))

    walk = shared / "xsens" / "opensense_walk"
    trial = {p.name: trim_mtmanager(p.read_text(), 150).encode()
             for p in sorted(walk.glob("MT_*.txt"))}
    pelvis = next(n for n in trial if n.endswith("00B42279.txt"))
    folder = _own_folder(root, "mt_trial", "opensense_walk", trial)
    seeds.append(Seed("mt_trial", "opensense_walk", folder, pelvis, ("inspect", "{dir}", "--json")))
    walk_copy = _own_folder(root, "recordings", "opensense_walk", trial)
    xml = (walk / "myIMUMappings.xml").read_bytes()
    seeds.append(Seed("opensense_xml", "myIMUMappings", _own_folder(
        root, "opensense_xml", "walk", {"myIMUMappings.xml": xml}), "myIMUMappings.xml",
        ("inspect", str(walk_copy), "--json", "--map", "{file}")))
    lower8 = CONFIGS / "sensors" / "lower8.yaml"
    seeds.append(Seed("sensor_map", "lower8_walk", _own_folder(
        root, "sensor_map", "lower8_walk", {"lower8.yaml": lower8.read_bytes()}), "lower8.yaml",
        ("inspect", str(walk_copy), "--json", "--map", "{file}")))

    mvnx = trim_mvnx((shared / "mvnx" / "test_mocap.mvnx").read_text(), 20)
    seeds.append(Seed("mvnx", "test_mocap", _own_folder(
        root, "mvnx", "test_mocap", {"test_mocap.mvnx": mvnx.encode()}), "test_mocap.mvnx",
        inspect_file))

    simulate = ("simulate", "--motion", "{file}", "--seconds", "2.6", "--rate", "20",
                "--noise", "none", "--out", "{out}/capture", "--quiet")
    bvhs = [*sorted((shared / "mocap").glob("*.bvh")), shared / "mvnx" / "test_mocap.bvh"]
    for path in bvhs:
        text = trim_bvh(path.read_text(encoding="utf-8", errors="replace"), 30)
        folder = _own_folder(root, "bvh", path.stem, {path.name: text.encode()})
        seeds.append(Seed("bvh", path.stem, folder, path.name, simulate))
    return seeds


def copy_seed(seed: Seed, case_dir: Path) -> Path:
    """A fresh copy of the seed's folder at ``case_dir``; returns the file to mutate."""
    shutil.copytree(seed.folder, case_dir)
    return case_dir / seed.target
