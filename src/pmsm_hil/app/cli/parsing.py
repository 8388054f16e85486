"""argparse value parsers that reject non-finite and out-of-range numbers with the option's name."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def finite_float(name: str) -> Callable[[str], float]:
    """Parser for a finite float option."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return value
    return parse


def positive_float(name: str) -> Callable[[str], float]:
    """Parser for a finite float > 0."""
    base = finite_float(name)

    def parse(text: str) -> float:
        value = base(text)
        if value <= 0:
            raise argparse.ArgumentTypeError(f"{name} must be > 0, got {text!r}")
        return value
    return parse


def int_at_least(text: str, minimum: int, not_int: str, too_small: str) -> int:
    """`int(text)` if ≥ `minimum`; else ArgumentTypeError "<not_int|too_small>, got '<text>'"."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{not_int}, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"{too_small}, got {text!r}")
    return value


def non_negative_int(name: str) -> Callable[[str], int]:
    """Parser for an integer ≥ 0."""
    def parse(text: str) -> int:
        return int_at_least(text, 0, f"{name} must be an integer", f"{name} must be ≥ 0")
    return parse


def positive_int(text: str) -> int:
    """Parser for a whole number ≥ 1 (counts: periods, steps, repeats)."""
    return int_at_least(text, 1, "expected a whole number ≥ 1", "expected a whole number ≥ 1")
