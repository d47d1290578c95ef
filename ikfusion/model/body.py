"""Body dimensions of a subject: from a height alone or from measured dimensions (SPEC section 2).

Defaults are fractions of body height ``H`` from the anthropometric tables of Drillis & Contini
(1966) as reprinted in D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed.
(2009), Fig. 4.1: ankle height 0.039 H, knee height 0.285 H, hip height 0.530 H, shoulder height
0.818 H, upper arm 0.186 H, forearm 0.146 H, hand 0.108 H, foot length 0.152 H. The distance
between hip joint centres (0.10 H) and between shoulder joint centres (0.215 H) follow the same
figure's bitrochanteric and biacromial widths reduced to joint centres. Segment masses and
inertias are in :mod:`ikfusion.model.layout` (de Leva 1996).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path

from ..errors import ConfigError
from ..yaml_files import read_yaml_document, with_line
from .ranges import RangeOverrides, parse_ranges

#: Default dimension / body height ratios (Winter 2009, Fig. 4.1; see module docstring).
HEIGHT_FRACTIONS: dict[str, float] = {
    "ankle_height": 0.039,
    "lower_leg": 0.246,
    "upper_leg": 0.245,
    "hip_width": 0.100,
    "shoulder_width": 0.215,
    "shoulder_height": 0.818,
    "upper_arm": 0.186,
    "forearm": 0.146,
    "hand": 0.108,
    "foot_length": 0.152,
}

#: Plausible range of each dimension as a fraction of height (a typo or unit mistake fails here).
_PLAUSIBLE = {
    "ankle_height": (0.015, 0.08),
    "lower_leg": (0.15, 0.35),
    "upper_leg": (0.15, 0.35),
    "hip_width": (0.05, 0.2),
    "shoulder_width": (0.12, 0.32),
    "shoulder_height": (0.7, 0.9),
    "upper_arm": (0.12, 0.26),
    "forearm": (0.09, 0.21),
    "hand": (0.06, 0.15),
    "foot_length": (0.1, 0.2),
    "hip_height": (0.4, 0.65),
}

#: Body mass index used when no mass is given [kg/m^2].
DEFAULT_BMI = 22.5


@dataclass(frozen=True)
class Body:
    """Subject dimensions in metres (mass in kg). Unset fields take the height-based defaults.

    Attributes:
        height: Standing body height [m], floor to the top of the head.
        mass: Body mass [kg]; ``DEFAULT_BMI * height**2`` when omitted.
        shoulder_width: Distance between the shoulder joint centres [m].
        hip_width: Distance between the hip joint centres [m].
        upper_arm: Shoulder to elbow joint [m].
        forearm: Elbow to wrist joint [m].
        hand: Wrist to fingertip [m].
        upper_leg: Hip to knee joint [m].
        lower_leg: Knee to ankle joint [m].
        foot_length: Heel to toe tip [m].
        ankle_height: Floor to ankle joint [m].
        shoulder_height: Floor to shoulder joint [m].
        hip_height: Floor to hip joint [m]; must equal ankle_height + lower_leg + upper_leg
            within 3 cm when all four are given.
        ranges: Per-subject ranges of motion over ``configs/joints.yaml``'s, as
            ``((joint, angle, lower_deg, upper_deg), ...)`` [deg] (:mod:`.ranges`; the body
            file's ``ranges`` entry, a preset such as ``athlete`` already expanded).
    """

    height: float = 1.75
    mass: float | None = None
    shoulder_width: float | None = None
    hip_width: float | None = None
    upper_arm: float | None = None
    forearm: float | None = None
    hand: float | None = None
    upper_leg: float | None = None
    lower_leg: float | None = None
    foot_length: float | None = None
    ankle_height: float | None = None
    shoulder_height: float | None = None
    hip_height: float | None = None
    ranges: RangeOverrides = ()

    def __post_init__(self) -> None:
        _validate(self, source=None)

    @classmethod
    def from_height(cls, height: float) -> Body:
        """A body with every dimension from the height-based defaults."""
        return cls(height=height)

    @classmethod
    def from_dict(cls, values: Mapping[str, object], source: str | Path | None = None) -> Body:
        """A body from a mapping of SPEC section 2 keys (and ``ranges``); unknown keys are an error.

        Raises:
            ConfigError: Naming the file (``source``) and the key at fault.
        """
        known = {f.name for f in fields(cls)}
        values = dict(values)
        ranges = parse_ranges(values.pop("ranges"), source) if "ranges" in values else ()
        unknown = sorted(set(values) - known)
        if unknown:
            raise ConfigError(
                f"unknown body dimension(s) {', '.join(unknown)}; "
                f"known: {', '.join(sorted(known))}",
                path=source, field=unknown[0],
            )
        if "height" not in values:
            raise ConfigError("a body needs 'height' [m]", path=source, field="height")
        parsed: dict[str, float | None] = {}
        for key, value in values.items():
            if value is None:
                parsed[key] = None
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(f"expected a number in metres, found {value!r}", path=source,
                                  field=key)
            try:
                parsed[key] = float(value)
            except OverflowError:  # an integer with hundreds of digits
                raise ConfigError(f"expected a number in metres, found an integer of "
                                  f"{len(str(abs(int(value))))} digits", path=source,
                                  field=key) from None
        body = object.__new__(cls)
        for f in fields(cls):
            object.__setattr__(body, f.name, parsed.get(f.name, f.default))
        object.__setattr__(body, "ranges", ranges)
        _validate(body, source=source)
        return body

    @classmethod
    def from_yaml(cls, path: str | Path) -> Body:
        """Read a body file (YAML mapping of SPEC section 2 keys).

        Raises:
            ConfigError: Unreadable, not YAML (see :mod:`ikfusion.yaml_files`), or a value that is
                not a finite, plausible number in metres (kg for ``mass``); naming the file, the
                line and the key.
        """
        file = Path(path)
        doc = read_yaml_document(file, "body file")
        if not isinstance(doc.data, dict):
            raise ConfigError("expected a mapping of body dimensions", path=file)
        try:
            return cls.from_dict(doc.data, source=file)
        except ConfigError as err:
            raise with_line(err, doc.line_of(*err.field.split(".")) if err.field else None) \
                from None

    def to_dict(self) -> dict[str, float]:
        """Every dimension resolved (defaults filled in), in metres and kg."""
        return {name: self.dimension(name) for name in _RESOLVED}

    def dimension(self, name: str) -> float:
        """A dimension [m]: the measured value when given, else the height-based default."""
        value = getattr(self, name)
        if name == "height" or value is not None:
            return float(value)
        if name == "hip_height":
            return self.dimension("ankle_height") + self.dimension("lower_leg") + self.dimension(
                "upper_leg")
        if name == "upper_leg" and self.hip_height is not None:
            return self.hip_height - self.dimension("ankle_height") - self.dimension("lower_leg")
        if name == "mass":
            return DEFAULT_BMI * self.height**2
        return HEIGHT_FRACTIONS[name] * self.height


_RESOLVED = ("height", "mass", *HEIGHT_FRACTIONS, "hip_height")


def _validate(body: Body, source: str | Path | None) -> None:
    h = body.height
    if not (isinstance(h, int | float) and math.isfinite(h) and 0.5 <= h <= 2.6):
        raise ConfigError(f"height must be 0.5-2.6 m, found {h!r}", path=source, field="height")
    if body.mass is not None and not (math.isfinite(body.mass) and 10.0 <= body.mass <= 400.0):
        raise ConfigError(f"mass must be 10-400 kg, found {body.mass!r}", path=source, field="mass")
    for name, (lo, hi) in _PLAUSIBLE.items():
        value = body.dimension(name)
        if not (math.isfinite(value) and lo * h <= value <= hi * h):
            raise ConfigError(
                f"{name} = {value:.3f} m is not plausible for a {h:.2f} m body "
                f"(expected {lo * h:.3f}-{hi * h:.3f} m); lengths are in metres",
                path=source, field=name,
            )
    given = [body.hip_height, body.ankle_height, body.lower_leg, body.upper_leg]
    if all(v is not None for v in given):
        legs = body.ankle_height + body.lower_leg + body.upper_leg  # type: ignore[operator]
        if abs(legs - body.hip_height) > 0.03:  # type: ignore[operator]
            raise ConfigError(
                f"hip_height {body.hip_height:.3f} m differs from ankle_height + lower_leg + "
                f"upper_leg = {legs:.3f} m by more than 3 cm", path=source, field="hip_height",
            )
    if body.dimension("shoulder_height") <= body.dimension("hip_height") + 0.15 * h:
        raise ConfigError("shoulder_height must be well above hip_height", path=source,
                          field="shoulder_height")
