"""Bad samples inside motion files: found, bridged when the gap is short, refused otherwise.

A sample is *bad* when it is not finite (NaN, inf) or absurd: a position farther than
:data:`FAR_BEYOND_ANY_HALL_M` from the origin, an angle beyond :data:`MAX_ANGLE_DEG`, a
quaternion whose norm is far from 1. Good data around a bad sample is never lost: a short run
of bad frames (at most :data:`MAX_BRIDGE_SECONDS`) is bridged by interpolating the channel from
the good frames on both sides (held from the one good side at the start or end of the file),
and a warning names the file, the frames (and lines, when known) and the channel. A channel
without any good frame, with a longer run, or with more than :data:`MAX_BAD_SHARE` of its frames
bad cannot be bridged honestly: :class:`~ikfusion.errors.InputError` (file, line, field).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np

from ..errors import InputError

__all__ = [
    "FAR_BEYOND_ANY_HALL_M",
    "Kind",
    "MAX_ANGLE_DEG",
    "MAX_BAD_SHARE",
    "MAX_BRIDGE_SECONDS",
    "bad_runs",
    "bad_samples",
    "bridge_channel",
]

#: A position farther than this from the origin is a corrupt value, not a capture [m].
FAR_BEYOND_ANY_HALL_M = 1.0e4
#: An Euler angle beyond this is a corrupt value (about 2800 turns, far more than any
#: unwrapped spin) [deg].
MAX_ANGLE_DEG = 1.0e6
#: A quaternion whose norm differs from 1 by more than this is corrupt (files round to 1e-6).
MAX_QUAT_NORM_ERROR = 0.1
#: The longest run of bad frames bridged by interpolation [s]; a body moves too much in
#: longer gaps for a straight line (or a held value) to stand in for it.
MAX_BRIDGE_SECONDS = 0.25
#: The largest share of a channel's frames that may be bridged.
MAX_BAD_SHARE = 0.1

Kind = Literal["position", "angle_deg", "quat_wxyz", "value"]


def bad_samples(values: np.ndarray, kind: Kind, position_limit: float = FAR_BEYOND_ANY_HALL_M
                ) -> np.ndarray:
    """Which frames of a channel are bad.

    Args:
        values: (N,) or (N, k) samples of one channel.
        kind: ``position`` (bad beyond ``position_limit`` in the file's unit), ``angle_deg``
            (bad beyond :data:`MAX_ANGLE_DEG`), ``quat_wxyz`` (bad when the norm is off),
            ``value`` (only non-finite values are bad).
        position_limit: Largest plausible distance from the origin, in the file's unit.

    Returns:
        (N,) bool.
    """
    v = np.asarray(values, dtype=float).reshape(len(values), -1)
    with np.errstate(invalid="ignore", over="ignore"):
        bad = ~np.all(np.isfinite(v), axis=1)
        if kind == "position":
            bad |= np.any(np.abs(v) > position_limit, axis=1)
        elif kind == "angle_deg":
            bad |= np.any(np.abs(v) > MAX_ANGLE_DEG, axis=1)
        elif kind == "quat_wxyz":
            bad |= np.abs(np.linalg.norm(v, axis=1) - 1.0) > MAX_QUAT_NORM_ERROR
    return bad


def bad_runs(bad: np.ndarray) -> list[tuple[int, int]]:
    """Runs of consecutive True entries as ``(first, stop)`` index pairs (stop exclusive)."""
    flags = np.concatenate([[False], np.asarray(bad, dtype=bool), [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(flags))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def bridge_channel(
    values: np.ndarray,
    bad: np.ndarray,
    *,
    rate: float,
    path: Path | None,
    channel: str,
    kind: Kind = "value",
    frame_lines: Sequence[int] | np.ndarray | None = None,
    frame_labels: Sequence[int] | np.ndarray | None = None,
) -> tuple[np.ndarray, str | None]:
    """Bridge the bad frames of one channel, or refuse.

    Args:
        values: (N,) or (N, k) samples of the channel (not modified).
        bad: (N,) which frames are bad (see :func:`bad_samples`).
        rate: Frames per second [Hz].
        path: The file, for the messages.
        channel: The channel's name, for the messages (the error's field).
        kind: ``angle_deg`` interpolates along the shorter way round; ``quat_wxyz``
            interpolates on the same hemisphere and normalises; others linearly.
        frame_lines: 1-based file line of each frame, when known.
        frame_labels: The number the file gives each frame (printed; default 1-based count).

    Returns:
        The bridged copy and one warning line (None when nothing was bad).

    Raises:
        InputError: No good frame, a run longer than :data:`MAX_BRIDGE_SECONDS`, or more
            than :data:`MAX_BAD_SHARE` of the frames bad (file, first bad line, channel).
    """
    out = np.array(values, dtype=float, copy=True)
    bad = np.asarray(bad, dtype=bool)
    n = len(out)
    runs = bad_runs(bad)
    if not runs:
        return out, None
    labels = np.arange(1, n + 1) if frame_labels is None else np.asarray(frame_labels)
    lines = None if frame_lines is None else np.asarray(frame_lines)

    def where(first: int, stop: int) -> str:
        frames = f"frame {labels[first]}" if stop - first == 1 else \
            f"frames {labels[first]}-{labels[stop - 1]}"
        if lines is None:
            return frames
        line = f"line {lines[first]}" if stop - first == 1 else \
            f"lines {lines[first]}-{lines[stop - 1]}"
        return f"{frames} ({line})"

    first_line = None if lines is None else int(lines[runs[0][0]])
    count = int(bad.sum())
    if count == n:
        raise InputError(f"no frame of {channel} holds a usable value (NaN, infinite or "
                         "absurd everywhere)", path, line=first_line, field=channel)
    longest = max(runs, key=lambda r: r[1] - r[0])
    max_run = max(1, int(np.floor(MAX_BRIDGE_SECONDS * rate + 1e-9)))
    if longest[1] - longest[0] > max_run:
        line = None if lines is None else int(lines[longest[0]])
        raise InputError(
            f"{where(*longest)} of {channel} hold NaN, infinite or absurd values: "
            f"{longest[1] - longest[0]} frames in a row, more than the "
            f"{MAX_BRIDGE_SECONDS:g} s ({max_run} frames) that can be bridged; fix or cut "
            "that part of the file", path, line=line, field=channel)
    if count > MAX_BAD_SHARE * n:
        raise InputError(
            f"{count} of {n} frames of {channel} hold NaN, infinite or absurd values (first: "
            f"{where(*runs[0])}), more than the {100 * MAX_BAD_SHARE:g} % that can be "
            "bridged", path, line=first_line, field=channel)
    for first, stop in runs:
        before, after = first - 1, stop
        for k in range(first, stop):
            if before < 0:
                out[k] = out[after]
            elif after >= n:
                out[k] = out[before]
            else:
                t = (k - before) / (after - before)
                out[k] = _between(out[before], out[after], t, kind)
    shown = ", ".join(where(a, b) for a, b in runs[:5])
    more = f" and {len(runs) - 5} more runs" if len(runs) > 5 else ""
    name = "" if path is None else f"{path}: "
    return out, (f"{name}{channel}: bridged {count} bad frame{'s' if count > 1 else ''} "
                 f"(NaN, infinite or absurd values) by interpolation: {shown}{more}")


def _between(a: np.ndarray, b: np.ndarray, t: float, kind: Kind) -> np.ndarray:
    """The value a fraction ``t`` of the way from ``a`` to ``b``."""
    if kind == "angle_deg":
        step = (b - a + 180.0) % 360.0 - 180.0
        return a + t * step
    if kind == "quat_wxyz":
        b = -b if float(np.dot(a, b)) < 0.0 else b
        q = (1.0 - t) * a + t * b
        return q / np.linalg.norm(q)
    return (1.0 - t) * a + t * b
