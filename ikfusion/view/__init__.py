"""``ikfusion view``: a capture, a solve result or a BVH clip in the browser, offline.

:mod:`.load` turns a PATH into a neutral :class:`Scene` (world Z up, metres, seconds);
:mod:`.draw` logs it into a Rerun recording; :mod:`.serve` serves Rerun's web viewer from the
installed package, or saves an ``.rrd`` file. Rerun (``rerun-sdk``) is the optional extra
``view`` and is only imported when drawing.
"""

from __future__ import annotations

from .load import load_scene
from .scene import Actor, Readers, Scene

__all__ = ["Actor", "Readers", "Scene", "load_scene"]
