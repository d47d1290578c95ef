"""Per-subject ranges of motion: a body file's ``ranges`` over those of ``configs/joints.yaml``.

Dancers and athletes go beyond the normal ranges the shipped model limits the solve to (a split
flexes a hip past 130 deg). A body file may widen or narrow any angle::

    height: 1.68
    ranges:
      preset: athlete            # optional: configs/ranges/athlete.yaml first
      jRightHip: {flex: [-30, 175], abd: [-45, 85]}

Values are ``[lower, upper]`` in degrees with ``-180 < lower < upper < 180``; the middle angle of
a joint's Euler sequence (``abd`` of the hip, ``rot`` of the shoulder, see the joints file) must
stay within [-90, 90] deg, where the angles of a rotation are unique (a range reaching +-90,
the gimbal lock, walls off no cone of poses around it). ``ranges: athlete`` alone
names a preset. Presets are the YAML files of ``configs/ranges/`` with the same ``ranges`` mapping.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from ..errors import ConfigError
from ..paths import configs_dir, shipped_config
from ..yaml_files import read_yaml_document, with_line
from .joints import ANGLE_NAMES, JointSpec, load_joint_specs

#: Range overrides as ``((joint, angle, lower_deg, upper_deg), ...)`` (hashable, in file order).
RangeOverrides = tuple[tuple[str, str, float, float], ...]


def preset_names() -> list[str]:
    """The shipped presets (file stems of ``configs/ranges/``)."""
    return sorted(p.stem for p in (configs_dir() / "ranges").glob("*.yaml"))


def parse_ranges(value: object, source: str | Path | None = None,
                 specs: Mapping[str, JointSpec] | None = None) -> RangeOverrides:
    """Validate a ``ranges`` entry (a preset name, or a mapping of joints with an optional preset).

    Args:
        value: The entry as read from YAML.
        source: The file it came from (for errors).
        specs: The joints; the shipped ``configs/joints.yaml`` when omitted.

    Returns:
        The overrides, the preset's first.

    Raises:
        ConfigError: Naming the file and the field (``ranges.jRightHip.flex``) at fault.
    """
    joints = specs if specs is not None else load_joint_specs()
    if isinstance(value, str):
        return load_preset(value, source, joints)
    if not isinstance(value, Mapping):
        raise ConfigError("expected a preset name or a mapping {<joint>: {<angle>: [lower, "
                          "upper]}} in degrees", path=source, field="ranges")
    out: list[tuple[str, str, float, float]] = []
    if "preset" in value:
        if not isinstance(value["preset"], str):
            raise ConfigError(f"preset must be one of {', '.join(preset_names())}", path=source,
                              field="ranges.preset")
        out += load_preset(value["preset"], source, joints)
    for joint, angles in value.items():
        if joint == "preset":
            continue
        if joint not in joints:
            raise ConfigError(f"unknown joint {joint!r}; known: {', '.join(joints)}",
                              path=source, field=f"ranges.{joint}")
        if not isinstance(angles, Mapping):
            raise ConfigError("expected {flex|abd|rot: [lower, upper]} in degrees", path=source,
                              field=f"ranges.{joint}")
        for angle, bounds in angles.items():
            out.append(_parse_bounds(joints[joint], str(angle), bounds, source))
    return tuple(out)


def _parse_bounds(spec: JointSpec, angle: str, bounds: object,
                  source: str | Path | None) -> tuple[str, str, float, float]:
    field = f"ranges.{spec.name}.{angle}"
    if angle not in ANGLE_NAMES:
        raise ConfigError(f"unknown angle {angle!r}; expected one of {', '.join(ANGLE_NAMES)}",
                          path=source, field=field)
    if not (isinstance(bounds, list) and len(bounds) == 2
            and all(isinstance(b, int | float) and not isinstance(b, bool) and math.isfinite(b)
                    for b in bounds)):
        raise ConfigError(f"expected [lower, upper] in degrees, found {bounds!r}", path=source,
                          field=field)
    lower, upper = float(bounds[0]), float(bounds[1])
    if not -180.0 < lower < upper < 180.0:
        raise ConfigError(f"expected -180 < lower < upper < 180 deg, found [{lower:g}, {upper:g}]",
                          path=source, field=field)
    if spec.angles[1].name == angle and not -90.0 <= lower < upper <= 90.0:
        raise ConfigError(
            f"{angle} is the middle angle of {spec.name}'s Euler sequence ({spec.sequence}): its "
            f"range must stay within [-90, 90] deg, found [{lower:g}, {upper:g}]",
            path=source, field=field)
    return spec.name, angle, lower, upper


def load_preset(name: str, source: str | Path | None = None,
                specs: Mapping[str, JointSpec] | None = None) -> RangeOverrides:
    """The overrides of the shipped preset ``name`` (``configs/ranges/<name>.yaml``).

    Raises:
        ConfigError: An unknown preset (naming ``source`` and the known ones), or a bad preset
            file (naming it).
    """
    if name not in preset_names():
        raise ConfigError(f"unknown ranges preset {name!r}; known: {', '.join(preset_names())}",
                          path=source, field="ranges")
    file = shipped_config("ranges", f"{name}.yaml")
    doc = read_yaml_document(file, "ranges preset")
    if not isinstance(doc.data, dict) or not isinstance(doc.data.get("ranges"), dict) or \
            "preset" in doc.data["ranges"]:
        raise ConfigError("expected a mapping 'ranges' of joints (no nested preset)", path=file)
    try:
        return parse_ranges(doc.data["ranges"], file, specs)
    except ConfigError as err:
        raise with_line(err, doc.line_of(*err.field.split("."))
                        if err.field else None) from None


def with_ranges(specs: Mapping[str, JointSpec],
                overrides: RangeOverrides) -> dict[str, JointSpec]:
    """The joints with the overridden ranges (later overrides of an angle win)."""
    out = dict(specs)
    for joint, angle, lower, upper in overrides:
        spec = out[joint]
        angles = tuple(replace(a, lower_deg=lower, upper_deg=upper) if a.name == angle else a
                       for a in spec.angles)
        out[joint] = replace(spec, angles=angles)  # type: ignore[arg-type]
    return out
