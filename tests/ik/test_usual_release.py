"""The usual frame's release shortcut (ikfusion.ik.usual_release) is release_contacts's answer.

:meth:`ContactTracker.release` skips :func:`release_contacts` where
:func:`keeps_every_point` says it returns its state unchanged (#20). Wherever it says so, the
general rule must return the very same state: on random frames (one foot or two planted,
still, moving and unknown feet, NaN heights and pitches, trunk points, a negative
``leave_distance``), and on the real Xsens walk (when ../shared is there), solved with and
without the shortcut into the same bytes.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from real_walk import solve_real_walk_natively

from ikfusion.ik import contacts
from ikfusion.ik.contact_thresholds import ContactThresholds
from ikfusion.ik.contacts import ContactState, release_contacts
from ikfusion.ik.point_bits import point_bits
from ikfusion.ik.point_evidence import frame_evidence, heights_above_lowest, stance_bits
from ikfusion.ik.settings import SolverSettings
from ikfusion.ik.usual_release import keeps_every_point
from ikfusion.model import HumanModel
from ikfusion.model.layout import TRUNK_CONTACT_SITES
from ikfusion.model.topology import BodyTopology

MODEL = HumanModel.default()
POINTS = MODEL.sites_of_kind("contact")
LAYOUT = BodyTopology.of(MODEL).foot_layout(POINTS)
BITS = point_bits(LAYOUT)
K = len(POINTS)
REST = np.array([n in TRUNK_CONTACT_SITES for n in POINTS])
THRESHOLDS = ContactThresholds.from_settings(SolverSettings.load())


def _random_frame(rng: np.random.Generator) -> tuple[ContactState, dict[str, object]]:
    """A random state and the keyword arguments of its release (no hints, toe-offs, motion)."""
    active = rng.random(K) < 0.4
    if rng.random() < 0.6:  # one foot planted, as on most frames of a walk
        first = int(np.flatnonzero(active)[0]) if active.any() else 0
        active &= ~BITS.mask(BITS.other_foot(1 << first))
    anchors = rng.normal(0.0, 0.5, (K, 3))
    anchors[:, 2] = rng.random(K) * rng.choice([0.04, 0.5], K)  # most low, some high [m]
    state = ContactState(list(POINTS), active, anchors, rng.random(K), rng.random(K))
    p_sensed = state.anchors + rng.normal(0.0, 0.02, (K, 3)) * rng.integers(0, 2, (K, 1))
    pitch = rng.normal(0.0, rng.choice([0.05, 0.6]), K)  # [rad]
    # planted feet mostly still, free ones mostly moving (the usual frame), some any
    still = np.where(active, rng.choice([1.0, 1.0, math.nan], K),
                     rng.choice([0.0, 0.0, 0.0, 1.0], K))
    if rng.random() < 0.2:
        still = rng.choice([0.0, 1.0, math.nan], K)
    p_sensed[rng.random(K) < 0.05, 2] = math.nan
    pitch[rng.random(K) < 0.1] = math.nan
    th = replace(THRESHOLDS, leave_distance=-0.01) if rng.random() < 0.05 else THRESHOLDS
    evidence = frame_evidence(BITS, heights_above_lowest(p_sensed), pitch,
                              stance_bits(BITS, still), BITS.of(REST),
                              math.radians(th.tilt_deg), th.leave_relative, th.enter_relative)
    return state, dict(p_sensed=p_sensed, thresholds=th, foot_pitch=pitch, foot_still=still,
                       p_solved=state.anchors + 0.001, placed=rng.normal(0.0, 0.01, (K, 3)),
                       layout=LAYOUT, needs_rest=REST, v_sensed=rng.normal(0.0, 0.3, (K, 3)),
                       step_sensed=rng.normal(0.0, 0.01, (K, 3)), evidence=evidence,
                       on=BITS.of(active))


@pytest.mark.parametrize("seed", range(4))
def test_random_frames_kept_by_the_general_rule(seed: int,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the shortcut keeps every point, release_contacts returns the state itself."""
    monkeypatch.setattr(contacts, "keeps_every_point", lambda *args: False)  # the general rule
    rng = np.random.default_rng(seed)
    kept = 0
    for _ in range(2000):
        state, kwargs = _random_frame(rng)
        th = kwargs["thresholds"]
        assert isinstance(th, ContactThresholds)
        if keeps_every_point(BITS, kwargs["on"], kwargs["evidence"],  # type: ignore[arg-type]
                             th.leave_distance):
            kept += 1
            assert release_contacts(state, **kwargs) is state  # type: ignore[arg-type]
    assert kept > 50  # the shortcut is taken often enough to be tested


def test_real_walk_solved_without_the_shortcut(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """The real walk solved with the shortcut and with release_contacts on every frame: the
    same files, byte for byte; the shortcut taken on most frames."""
    taken = [0]

    def counted(*args: object) -> bool:
        kept = keeps_every_point(*args)  # type: ignore[arg-type]
        taken[0] += kept
        return kept

    monkeypatch.setattr(contacts, "keeps_every_point", counted)
    solve_real_walk_natively(tmp_path / "fast")
    monkeypatch.setattr(contacts, "keeps_every_point", lambda *args: False)
    solve_real_walk_natively(tmp_path / "general")
    assert taken[0] > 1000
    files = sorted(p.relative_to(tmp_path / "fast") for p in (tmp_path / "fast").rglob("*")
                   if p.is_file())
    assert files
    for name in files:
        if name.name in ("solve_time.csv", "summary.json", ".ikfusion.json"):
            continue  # (timings, the time written)
        assert (tmp_path / "fast" / name).read_bytes() == (tmp_path / "general" /
                                                           name).read_bytes(), name
