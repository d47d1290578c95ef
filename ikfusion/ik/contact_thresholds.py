"""The hysteresis thresholds of the contact detection (:mod:`.contacts`)."""

from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class ContactThresholds:
    """Hysteresis thresholds [m, m/s, deg, rad/s].

    Their defaults live in ``configs/solver.yaml`` (section contacts) and
    :class:`ikfusion.ik.SolverSettings`.
    """

    floor_z: float
    enter_height: float
    enter_speed: float
    enter_relative: float
    leave_relative: float
    leave_distance: float
    settle_speed: float
    tilt_deg: float
    still_relative: float
    reenter_delay: float

    @classmethod
    def from_settings(cls, settings: object) -> ContactThresholds:
        """The thresholds of a :class:`ikfusion.ik.SolverSettings`."""
        return cls(**{f.name: getattr(settings, f.name) for f in fields(cls)})
