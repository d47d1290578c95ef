"""Argument types shared by the command modules (not a command itself)."""

from __future__ import annotations

import argparse

__all__ = ["positive_number"]


def positive_number(text: str, expected: str = "a number") -> float:
    """``text`` as a number above 0, for ``argparse`` ``type=``.

    Args:
        text: The argument as typed.
        expected: What the option takes, for the message of a value that is no number.

    Raises:
        argparse.ArgumentTypeError: Not a number, or not above 0 (NaN included); argparse
            reports it with the option's name (exit 2).
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value
