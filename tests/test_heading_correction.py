"""A heading drift of the IMUs (a magnetically disturbed area) is found and undone from UWB."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.app.correction import CorrectionSettings
from ikfusion.app.pipeline import solve_recording
from ikfusion.app.uwb_aiding import drift_correction, track_capture
from ikfusion.mocap.model_motion import site_positions
from ikfusion.paths import shipped_config
from ikfusion.sim.capture import add_heading_drift, truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation

DRIFT_DEG = 12.0  # turned into the sensors' headings between 6 s and 18 s


@pytest.fixture(scope="module")
def drifted(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    truth = truth_motion("gait", 26.0, 60.0)
    truth.q[:, :2] += [3.0, 2.5]  # the 1.5 m circle in the middle of the room
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    capture = write_capture(tmp_path_factory.mktemp("drift") / "capture", truth, ImuNoise(), 2,
                            constellation=room)
    add_heading_drift(capture.folder / "imu", 6.0, 18.0, DRIFT_DEG / 12.0)
    t = track_capture(capture.folder)
    return (t.recording, t.sensor_map, t.model, t.calibration, t.tags, t.tracks,
            capture.truth)


def _head_rms_after(drifted, correction, t0: float) -> float:  # type: ignore[no-untyped-def]
    recording, sensor_map, model, calibration, _, _, truth = drifted
    motion = solve_recording(recording, sensor_map, model, correction=correction,
                             calibration=calibration).motion
    late = motion.time >= t0
    head = site_positions(model, motion.q[late], ["HeadTop"])[:, 0]
    true = site_positions(truth.model, truth.q[late], ["HeadTop"])[:, 0]
    return float(np.sqrt(np.mean(np.sum((head - true) ** 2, axis=1))))


@pytest.mark.parametrize("mode", ["slide", "no-slide"])
def test_the_drift_is_turned_back(drifted, mode: str) -> None:  # type: ignore[no-untyped-def]
    recording, _, _, _, tags, tracks, _ = drifted
    turned = drift_correction(tags, tracks, recording.time, mode)
    still = drift_correction(tags, tracks, recording.time, mode,
                             CorrectionSettings.load(heading_rate_deg=0.0))
    with_turn = _head_rms_after(drifted, turned, 20.0)
    without = _head_rms_after(drifted, still, 20.0)
    # the targets were turned back by about the drift the sensors took
    assert np.degrees(turned.heading[-1]) == pytest.approx(-DRIFT_DEG, abs=3.0)
    assert np.all(still.heading == 0.0)
    assert with_turn < 0.6 * without
