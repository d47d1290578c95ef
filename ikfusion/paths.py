"""Where the shipped files live (``configs/`` and ``robots/`` beside the package) and the cache."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import ConfigError

_REPO_ROOT = Path(__file__).resolve().parent.parent


def module_source(name: str) -> Path:
    """The ``.py`` file of the ikfusion module ``name`` (a module's ``__name__``), as shipped.

    Not ``module.__file__``: a module compiled by mypyc (:mod:`ikfusion.native.typed_modules`)
    is loaded from the cache folder, its ``__file__`` the extension there. Files shipped beside a
    module (a kernel's C source) are found from here: ``module_source(__name__).with_name(...)``.
    """
    return _REPO_ROOT.joinpath(*name.split(".")).with_suffix(".py")


def configs_dir() -> Path:
    """Folder of the shipped YAML configurations (``configs/``)."""
    return _REPO_ROOT / "configs"


def robots_dir() -> Path:
    """Folder of the shipped URDF files (``robots/``)."""
    return _REPO_ROOT / "robots"


def shipped_config(*parts: str) -> Path:
    """Path of a shipped configuration file, e.g. ``shipped_config("sensors", "mvn17.yaml")``.

    Raises:
        ConfigError: When the file is not shipped.
    """
    path = configs_dir().joinpath(*parts)
    if not path.is_file():
        raise ConfigError(
            f"shipped configuration {'/'.join(parts)!r} not found under {configs_dir()}"
        )
    return path


def user_cache_dir() -> Path:
    """Folder of what ikfusion builds once and reuses (compiled step functions, human models).

    ``$IKFUSION_CACHE``, else ``$XDG_CACHE_HOME/ikfusion``, else ``~/.cache/ikfusion``.
    """
    base = os.environ.get("IKFUSION_CACHE")
    if base:
        return Path(base)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "ikfusion"
