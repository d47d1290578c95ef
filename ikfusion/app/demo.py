"""The main job on embedded data: simulate a capture, solve it three ways, print a table.

The capture is a walk in circles in a 6 m x 8 m room (the 10-reader constellation of
``configs/constellations/room_6x8.yaml`` surrounds it), worn by the 17-sensor MVN layout with
random mountings and the default sensor errors (orientation noise and heading wander), with UWB
tags on the head and both feet, written as MT Manager files and a TOA log. The IMU files are
read and the body calibrated on the N-pose at the start once, the tags are tracked once by their
IMU + UWB filters, and the recording is solved from those files three times: IMU only, UWB with
``slide`` and with ``no-slide`` correction (SPEC: the default when UWB is given). Each result is
written like ``ikfusion solve`` writes it and scored against the ground truth: the IMU-only one
after shifting it to the true start (its absolute position is unobservable), the UWB ones as
they are, in the readers' frame.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..ik import Motion
from ..mocap.model_motion import TruthMotion
from ..model import HumanModel
from ..output_folders import check_output_folder, prepare_output_folder
from ..paths import shipped_config
from ..results import write_result_folder
from ..sim.capture import Capture, write_capture
from ..sim.gait import GaitParameters, generate_gait
from ..sim.imu import ImuNoise
from ..uwb.constellation import load_constellation
from .correction import DriftCorrection
from .evaluate import Evaluation, evaluate
from .pipeline import solve_recording
from .uwb_aiding import TrackedCapture, TrackedTags, UwbAiding, track_capture, uwb_aiding

#: The three solves: column label, result folder, correction mode (None: IMU only). The last
#: one is the default of ``solve`` with UWB and is written to ``result/``.
MODES = (("IMU only", "result_imu_only", None),
         ("UWB slide", "result_slide", "slide"),
         ("UWB no-slide", "result", "no-slide"))


@dataclass
class ModeResult:
    """One solve of the demo capture.

    Attributes:
        label: Column heading of the table.
        folder: Its result folder.
        motion: The solved motion (one frame per IMU sample).
        evaluation: Scored against the truth (IMU only: after the start alignment; UWB: as it
            is, in the readers' frame).
        solve_seconds: Wall time of the solve [s] (calibration and tag tracking excluded: they
            are done once for all modes).
        gap_m: Mean and largest remaining horizontal gap between the body's tag sites and the
            tracked tags over the frames with a fix [m] (None: IMU only).
    """

    label: str
    folder: Path
    motion: Motion
    evaluation: Evaluation
    solve_seconds: float
    gap_m: tuple[float, float] | None


@dataclass
class DemoResult:
    """What the demo produced: its folder, the truth and one result per mode of :data:`MODES`."""

    out_dir: Path
    truth: TruthMotion
    modes: list[ModeResult]

    @property
    def motion(self) -> Motion:
        """The default mode's motion (UWB no-slide, ``result/``)."""
        return self.modes[-1].motion


def demo_walk(seconds: float) -> GaitParameters:
    """Walking in circles (radius 1.5 m, 1.1 m/s) after a 2 s N-pose, ``seconds`` [s] in all."""
    return GaitParameters(path="circle", radius=1.5, duration=seconds, stand=2.0, speed=1.1,
                          step_length=0.6)


def run_demo(out_dir: str | Path = "ikfusion-demo", seconds: float = 60.0, seed: int = 7,
             progress: bool = True, force: bool = False) -> DemoResult:
    """Simulate a capture into files, solve it three ways from the files, write and evaluate.

    Args:
        out_dir: Folder of ``capture/`` and the three result folders.
        seconds: Length of the capture [s] (2 s N-pose, then walking), at 60 Hz.
        seed: Random seed of the sensor and UWB simulation.
        progress: Show progress bars (gait synthesis and each solve).
        force: Write into ``out_dir`` and replace its folders even when ikfusion did not
            write them.

    Raises:
        InputError: ``out_dir`` or a folder in it is refused (checked before any work).
    """
    out = Path(out_dir)
    check_output_folder(out, force)
    for name in ("capture", *(name for _, name, _ in MODES)):
        check_output_folder(out / name, force)
    prepare_output_folder(out, "demo", force)
    capture = simulate_demo_capture(out / "capture", seconds, seed, progress, force)
    shared = track_capture(capture.folder)
    modes = [_solve_mode(shared, capture, out / name, label, mode, progress, force)
             for label, name, mode in MODES]
    return DemoResult(out, capture.truth, modes)


def simulate_demo_capture(folder: Path, seconds: float, seed: int, progress: bool,
                          force: bool = False) -> Capture:
    """The walk in the middle of the 6 m x 8 m room, with IMUs and UWB, written to ``folder``.

    The gait starts at the origin heading +X; it is moved to (3.0, 2.5) m so that its circle
    (radius 1.5 m) is centred in the room (readers' frame, ENU).
    """
    truth = generate_gait(HumanModel.default(), demo_walk(seconds), rate=60.0, progress=progress)
    truth.q[:, 0] += 3.0
    truth.q[:, 1] += 4.0 - 1.5
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    return write_capture(folder, truth, ImuNoise(), seed, constellation=room, force=force)


def _solve_mode(shared: TrackedCapture, capture: Capture, folder: Path, label: str,
                mode: str | None, progress: bool, force: bool = False) -> ModeResult:
    """Solve with one correction mode (None: IMU only), write its result folder, score it."""
    aiding: UwbAiding | None = None
    if mode is not None:
        tracked = TrackedTags(shared.tags, shared.tracks, shared.reader_ids)
        aiding = uwb_aiding(tracked, shared.recording.time, mode)
    correction = None if aiding is None else aiding.correction
    start = time.perf_counter()
    solved = solve_recording(shared.recording, shared.sensor_map, shared.model,
                             progress=progress, correction=correction,
                             calibration=shared.calibration)
    elapsed = time.perf_counter() - start
    if aiding is not None:
        solved.motion.warnings += aiding.warnings
    written = write_result_folder(solved.motion, folder,
                                  extra_summary=_summary(shared, label, aiding),
                                  force=force)
    score = evaluate(written, capture.folder / "truth.npz",
                     align="auto" if correction is None else "none")
    gap = None if correction is None else _gap(correction)
    return ModeResult(label, Path(written), solved.motion, score, elapsed, gap)


def _summary(shared: TrackedCapture, label: str, aiding: UwbAiding | None) -> dict[str, Any]:
    """The extra ``summary.json`` keys, as ``ikfusion solve`` writes them, and the source.

    ``calibration``: how the heading was found, the body heading [deg] and the still window [s];
    ``uwb``: ``{"used": false}`` or :func:`ikfusion.app.uwb_aiding.uwb_summary`.
    """
    cal = shared.calibration
    rate = shared.recording.rate
    uwb = {"used": False} if aiding is None else aiding.summary()
    return {
        "source": f"ikfusion demo: simulated walk in circles, 17 sensors, default noise, "
                  f"{label}",
        "calibration": {"method": cal.method, "heading_deg": float(np.degrees(cal.heading)),
                        "window_s": [cal.window[0] / rate, cal.window[1] / rate]},
        "uwb": uwb,
    }


def _gap(correction: DriftCorrection) -> tuple[float, float]:
    """Mean and largest remaining horizontal gap of a correction over its frames with a fix [m]."""
    gap = correction.gap[np.isfinite(correction.gap)]
    return (float(gap.mean()), float(gap.max())) if gap.size else (0.0, 0.0)


def _rows(result: DemoResult) -> list[tuple[str, list[str]]]:
    """The table's rows: a name and one cell per mode (the first row holds the headings)."""

    def row(name: str, cell: Callable[[ModeResult], str]) -> tuple[str, list[str]]:
        return name, [cell(r) for r in result.modes]

    return [
        ("", [r.label for r in result.modes]),
        row("joint angle RMS [deg]", lambda r: f"{r.evaluation.joint_angle_rms_deg:.2f}"),
        row("segment orientation RMS [deg]",
            lambda r: f"{r.evaluation.segment_orientation_rms_deg:.2f}"),
        row("head position RMS 3-D [cm]",
            lambda r: f"{100 * r.evaluation.head_position_rms_m:.1f}"),
        row("head position RMS horizontal [cm]",
            lambda r: f"{100 * r.evaluation.head_position_rms_xy_m:.1f}"),
        row("foot slide per contact [mm]", lambda r: f"{r.evaluation.foot_slide_mm:.1f} mean, "
                                                     f"{r.evaluation.foot_slide_max_mm:.1f} max"),
        row("largest joint-angle jump [deg/frame]",
            lambda r: f"{r.evaluation.joint_angle_jump_max_deg:.2f}"),
        row("UWB gap remaining [cm]", lambda r: "-" if r.gap_m is None else
            f"{100 * r.gap_m[0]:.1f} mean, {100 * r.gap_m[1]:.1f} max"),
        row("speed [frames/s]", lambda r: f"{len(r.motion) / r.solve_seconds:.0f} "
                                          f"({1e3 * np.median(r.motion.solve_time):.2f} ms/frame)"),
    ]


def table(result: DemoResult) -> str:
    """The accuracy and speed table printed by ``ikfusion demo``, one column per mode.

    Metrics are those of :func:`ikfusion.app.evaluate.evaluate` over the whole capture (foot slide
    over the truth's contact phases); speed is frames per second of wall time of the solve and
    the median solver time per frame [ms].
    """
    m = result.motion
    walked = float(np.sum(np.linalg.norm(np.diff(result.truth.q[::60, :2], axis=0), axis=1)))
    rows = _rows(result)
    width = max(len(name) for name, _ in rows)
    cols = [max(len(cells[i]) for _, cells in rows) for i in range(len(result.modes))]
    lines = [f"capture: {m.time[-1] - m.time[0]:.0f} s walk in circles, {walked:.0f} m, "
             f"17 IMUs at {m.rate:.0f} Hz with default noise, UWB tags on head and feet, "
             f"10 readers"]
    lines += [f"{name:<{width}}  " + "  ".join(f"{c:>{w}}" for c, w in zip(cells, cols))
              for name, cells in rows]
    lines.append("IMU-only positions are shifted to the true start (absolute position is not "
                 "observable without UWB); UWB results are scored as they are.")
    lines.append(f"results in {result.out_dir}/result (UWB no-slide), result_slide and "
                 f"result_imu_only; capture and truth in {result.out_dir}/capture")
    lines.append(f"see it: ikfusion view {result.out_dir}/result --truth "
                 f"{result.out_dir}/capture/truth.npz")
    return "\n".join(lines)
