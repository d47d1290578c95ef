"""Rerun (package ``rerun-sdk``, the optional extra ``view``), imported only when drawing."""

from __future__ import annotations

import re
from types import ModuleType

from ..errors import InputError


class ViewerUnavailable(InputError):
    """The optional viewer library is missing; the message says which extra to install."""


def require_rerun(what: str = "ikfusion view") -> ModuleType:
    """Import ``rerun`` (package ``rerun-sdk``) or explain how to install it.

    Args:
        what: The command or option that needs it, named in the message.

    Raises:
        ViewerUnavailable: rerun-sdk is not installed.
    """
    try:
        import rerun
    except ImportError as err:
        raise ViewerUnavailable(
            f"{what} needs the optional package rerun-sdk: install it with "
            "pip install 'ikfusion[view]' (or pip install rerun-sdk)") from err
    return rerun


def entity_name(name: str) -> str:
    """A name usable as one Rerun entity path part (letters, digits, ``_`` and ``-``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", name) or "_"
