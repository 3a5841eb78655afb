"""Durations as written in models: ``250ms``, ``2s``, ``1.5s``, ``2m``, or a bare
integer meaning milliseconds (VisualStates compatibility)."""

from __future__ import annotations

import re
from fractions import Fraction

_RE = re.compile(r"^\s*([0-9]+(?:\.[0-9]+)?)\s*(ms|s|m)?\s*$")
_US_PER_UNIT = {"ms": 1000, "s": 1_000_000, "m": 60_000_000}
MAX_US = 366 * 24 * 3600 * 1_000_000  # a year: far beyond any mission, far inside int64


def parse_us(value: object) -> int | None:
    """Microseconds in ``value``, or None when it is not a duration.

    Exact (no float rounding); durations finer than a microsecond are refused.
    """
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return value * 1000 if 0 <= value * 1000 <= MAX_US else None
    if not isinstance(value, str):
        return None
    m = _RE.match(value)
    if m is None:
        return None
    us = Fraction(m.group(1)) * _US_PER_UNIT[m.group(2) or "ms"]
    return int(us) if us.denominator == 1 and us <= MAX_US else None


def has_unit(value: object) -> bool:
    """Does a duration as written name its unit (``5ms``, not ``5``)?"""
    if not isinstance(value, str):
        return False
    m = _RE.match(value)
    return m is not None and m.group(2) is not None


def format_us(us: int) -> str:
    """The shortest exact spelling of a duration: ``100ms``, ``2s``, ``1.5s``, ``2m``."""
    if us >= 60_000_000 and us % 60_000_000 == 0:
        return f"{us // 60_000_000}m"
    if us >= 1_000_000 and us % 100_000 == 0:  # whole tenths of a second read best in s
        return f"{_decimal(us, 6)}s"
    return f"{_decimal(us, 3)}ms"


def _decimal(n: int, places: int) -> str:
    """``n / 10**places`` written exactly, without trailing zeros (integers only, no float)."""
    whole, frac = divmod(n, 10**places)
    digits = f"{frac:0{places}d}".rstrip("0")
    return f"{whole}.{digits}" if digits else str(whole)
