"""Back from an outage, the heading error is found from clean travel, and soon (issue #19, b).

Outside the readers' coverage a causal tag filter dead-reckons, and when UWB returns its
reported position converges back at a bounded speed, with a covariance as large as what is
left of the way. That convergence is not travel: compared with the body's travel it gave
heading errors of -90 and -110 deg for a true 20 deg (bench_uwb_experiments b). And the body,
whose heading drifted outside, walks the wrong way until the heading is turned back, so the
estimate must not wait a whole window of clean travel.
"""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.app.correction import CorrectionSettings, DriftCorrection, SiteFixes
from ikfusion.rotations import axis_rotation

RATE = 60.0  # [Hz]
BACK = 2.0  # UWB returns [s]
HEADING_DEG = 20.0  # the solved body's travel is turned this far from the true travel
SPEED = 1.2  # walking [m/s]
SIGMA = 0.015  # a converged fix's noise, each horizontal axis [m]
WITHIN_DEG = 5.0  # an estimate is this close to the truth (the shipped heading_sigma_deg)


def _reentry() -> tuple[DriftCorrection, np.ndarray, np.ndarray]:
    """A head tag walking a straight line, back from an outage at ``BACK``.

    Returns:
        The correction with its fixes and solved travel filled in, the frame times [s] and
        each frame's distance of the fix from the true head [m].
    """
    time = np.arange(0.0, 5.0, 1.0 / RATE)
    true = np.stack([SPEED * time, np.zeros_like(time), np.full_like(time, 1.75)], axis=1)
    solved = true @ axis_rotation("z", np.radians(-HEADING_DEG)).T  # drifted heading
    offset = solved[int(BACK * RATE)] - true[int(BACK * RATE)]  # where the filter coasted to
    p_fix = solved.copy()  # outside: the dead-reckoned fix goes with the drifted body ...
    cov = np.array([np.diag([0.3**2, 0.3**2, 0.1]) for _ in time])  # ... uncertain
    for k in range(int(BACK * RATE), len(time)):  # back: the offset decays as the EKF's does
        p_fix[k] = true[k] + offset
        cov[k] = SIGMA**2 * np.eye(3) + np.outer(offset, offset)
        norm = float(np.linalg.norm(offset))
        if norm > 0.0:
            offset *= 1.0 - min(norm / RATE / 0.2, 1.5 / RATE, norm) / norm
    correction = DriftCorrection([SiteFixes("HeadTop", p_fix, cov)], "no-slide",
                                 CorrectionSettings.load())
    correction._body = [True]  # noqa: SLF001 - what after_frame takes from the model
    correction._solved[0] = solved[:, :2]  # noqa: SLF001 - the solved site's travel
    return correction, time, np.linalg.norm(p_fix - true, axis=1)


def test_a_converging_fix_is_not_travel() -> None:
    correction, time, _ = _reentry()
    estimates = {round(t, 3): correction.heading_error(k, 1.0 / RATE)
                 for k, t in enumerate(time)}
    wrong = {t: round(float(np.degrees(e)), 1) for t, e in estimates.items()
             if e is not None and abs(np.degrees(e) - HEADING_DEG) > WITHIN_DEG}
    assert not wrong, f"heading errors off the true {HEADING_DEG} deg at t [s]: {wrong}"


def test_the_heading_is_found_soon_after_the_fixes_are_clean() -> None:
    correction, time, fix_error = _reentry()
    clean = time[(time >= BACK) & (fix_error < 3.0 * SIGMA)][0]
    found = [t for k, t in enumerate(time)
             if t > BACK and correction.heading_error(k, 1.0 / RATE) is not None]
    assert found, "no heading estimate after the outage"
    # half a window of clean travel (0.6 m at 1.2 m/s) is enough to tell 20 deg
    assert found[0] <= clean + 0.6, (f"fixes clean at {clean:.2f} s, heading found at "
                                     f"{found[0]:.2f} s")
    k = int(np.searchsorted(time, found[0]))
    angle = correction.heading_error(k, 1.0 / RATE)
    assert angle is not None
    assert np.degrees(angle) == pytest.approx(HEADING_DEG,
                                              abs=WITHIN_DEG)
