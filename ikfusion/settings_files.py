"""Settings dataclasses filled from shipped YAML files, with one source for every value.

A settings class (:class:`ikfusion.ik.SolverSettings`, :class:`ikfusion.app.correction.
CorrectionSettings`, :class:`ikfusion.retarget.settings.RetargetSettings`) has no defaults of
its own: its values come from a shipped file under ``configs/``, grouped in sections (one level
of mappings, e.g. ``limits: {lag_speed: 0.3}``), then from user overlays holding the same
sections with some of the keys, then from keyword overrides. The shipped file must set every
field exactly once; a key that is no field, a key in another section than the shipped file puts
it, and a value of the wrong type are :class:`~ikfusion.errors.ConfigError` naming the file, the
line and the key. :class:`ShippedSettings` gives such a class its ``load`` (shipped file, one
user file, keywords).
"""

from __future__ import annotations

import types
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from functools import cache
from pathlib import Path
from typing import Any, ClassVar, Self, TypeVar

from .errors import ConfigError
from .paths import shipped_config
from .yaml_files import YamlDocument, read_yaml_document

__all__ = ["Overlay", "ShippedSettings", "load_settings"]

T = TypeVar("T")


@dataclass(frozen=True)
class Overlay:
    """Sections of a YAML document that override some settings.

    Attributes:
        document: The parsed file with its key lines.
        prefix: Keys leading to the sections in the document (``()``: at its top; a robot
            config holds its retarget settings under ``("solver",)``).
    """

    document: YamlDocument
    prefix: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Value:
    """A setting's value and where it was written."""

    value: Any
    section: str | None
    path: Path | None
    line: int | None


def load_settings(cls: type[T], shipped: str | Path, what: str,
                  overlays: Sequence[Overlay] = (),
                  overrides: Mapping[str, Any] | None = None) -> T:
    """A settings dataclass from its shipped file, user overlays and keyword overrides.

    Args:
        cls: A dataclass whose fields are all settings (none with a default).
        shipped: The shipped YAML file, which must set every field.
        what: What the file holds, for messages (``"solver settings"``).
        overlays: Documents whose sections override some keys, in order (the last wins).
        overrides: Field -> value, applied last (checked like the files' values).

    Raises:
        ConfigError: An unknown key, a missing or repeated one, a key in another section than
            the shipped file's, or a value of the wrong type; with file, line and key.
    """
    names = [f.name for f in fields(cls)]  # type: ignore[arg-type]
    hints = _type_hints(cls)  # type: ignore[arg-type]  # (a class is hashable)
    shipped_doc = read_yaml_document(shipped, what)
    values = _sections(shipped_doc, (), names, None)
    missing = [n for n in names if n not in values]
    if missing:
        raise ConfigError(f"{what}: missing {', '.join(missing)} (every setting is given "
                          "here)", path=shipped_doc.path)
    for overlay in overlays:
        layer = _sections(overlay.document, overlay.prefix, names, values)
        values.update(layer)
    for key, value in (overrides or {}).items():
        if key not in values:
            raise ConfigError(f"unknown setting; known: {', '.join(names)}", field=key)
        values[key] = _Value(value, values[key].section, None, None)
    checked = {name: _check(hints[name], values[name], name) for name in names}
    return cls(**checked)


@cache
def _type_hints(cls: type) -> dict[str, Any]:
    """``cls``'s fields' types, resolved once a process (2 ms for the solver's settings)."""
    return typing.get_type_hints(cls)


class ShippedSettings:
    """Base of a settings dataclass read from one shipped file and one optional user file.

    A subclass names its file under ``configs/`` in ``shipped_file`` and what it holds, for
    messages, in ``what`` (``"solver settings"``).
    """

    shipped_file: ClassVar[str]
    what: ClassVar[str]

    @classmethod
    def load(cls, path: str | Path | None = None, **overrides: Any) -> Self:
        """The shipped ``configs/<shipped_file>``, overlaid by a user file; keywords win.

        Args:
            path: A user file with some of the shipped sections and keys (e.g.
                ``limits: {lag_speed: 0.2}``); None: the shipped values only.
            **overrides: Individual settings by field name.

        Raises:
            ConfigError: An unknown key, a key in the wrong section or a value of the wrong
                type, naming the file, the line and the key.
        """
        overlays = [] if path is None else [Overlay(read_yaml_document(path, cls.what))]
        return load_settings(cls, shipped_config(cls.shipped_file), cls.what, overlays,
                             overrides)


def _sections(doc: YamlDocument, prefix: tuple[str, ...], names: list[str],
              shipped: Mapping[str, _Value] | None) -> dict[str, _Value]:
    """The keys of the sections at ``prefix`` in ``doc`` (``shipped``: where each key belongs)."""
    data: Any = doc.data
    for key in prefix:
        data = data.get(key) if isinstance(data, dict) else None
    if data is None:
        return {}
    where = ".".join(prefix) or None
    if not isinstance(data, dict):
        raise ConfigError("expected a mapping of sections", path=doc.path,
                          line=doc.line_of(*prefix) if prefix else None, field=where)
    out: dict[str, _Value] = {}
    for section, block in data.items():
        keys = (*prefix, str(section))
        if not isinstance(block, dict):
            raise ConfigError("expected a mapping of settings (a section)", path=doc.path,
                              line=doc.line_of(*keys), field=".".join(keys))
        for key, value in block.items():
            name = str(key)
            line = doc.line_of(*keys, name)
            field = ".".join((*keys, name))
            if name not in names:
                raise ConfigError(f"unknown setting; known: {', '.join(names)}", path=doc.path,
                                  line=line, field=field)
            if name in out:
                raise ConfigError(f"set twice (also in section {out[name].section!r})",
                                  path=doc.path, line=line, field=field)
            belongs = shipped[name].section if shipped is not None else str(section)
            if belongs != str(section):
                raise ConfigError(f"this setting belongs in section {belongs!r}", path=doc.path,
                                  line=line, field=field)
            out[name] = _Value(value, str(section), doc.path, line)
    return out


def _check(kind: Any, value: _Value, name: str) -> Any:
    """``value`` as the field type ``kind`` (int, float, bool, str, list[...], dict[str, ...])."""
    def fail(expected: str) -> ConfigError:
        field = name if value.section is None else f"{value.section}.{name}"
        hint = " (write numbers in exponent form with a dot: 1.0e-9)" \
            if isinstance(value.value, str) and "e" in value.value.lower() else ""
        return ConfigError(f"expected {expected}, found {value.value!r}{hint}", path=value.path,
                           line=value.line, field=field)

    def convert(kind: Any, item: Any) -> Any:
        origin = typing.get_origin(kind)
        if origin in (types.UnionType, typing.Union):
            options = typing.get_args(kind)
            if item is None and type(None) in options:
                return None
            return convert(next(k for k in options if k is not type(None)), item)
        if kind is bool:
            if not isinstance(item, bool):
                raise fail("true or false")
            return item
        if kind is int:
            if isinstance(item, bool) or not isinstance(item, int):
                raise fail("a whole number")
            return item
        if kind is float:
            if isinstance(item, bool) or not isinstance(item, int | float):
                raise fail("a number")
            return float(item)
        if kind is str:
            if not isinstance(item, str):
                raise fail("text")
            return item
        if origin is list:
            if not isinstance(item, list):
                raise fail("a list")
            (inner,) = typing.get_args(kind)
            return [convert(inner, x) for x in item]
        if origin is dict:
            if not isinstance(item, dict):
                raise fail("a mapping")
            _, inner = typing.get_args(kind)
            return {str(k): convert(inner, v) for k, v in item.items()}
        raise TypeError(f"settings field {name} has an unsupported type {kind!r}")

    return convert(kind, value.value)
