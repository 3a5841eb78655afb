# hfsmc_helpers.py: helpers of snippets that need no engine (docs/model.md, "Code snippets").
# Copied unchanged into every Python component folder; standard library only.
"""Orientation helpers: a quaternion's yaw, and its roll, pitch and yaw, as ROS 1's
``tf.transformations.euler_from_quaternion`` gave them (models converted from VisualStates
call it; there is no tf in ROS 2)."""

from __future__ import annotations

import math
from typing import Any


def _xyzw(q: Any) -> tuple[float, float, float, float]:
    """``q`` as x, y, z, w: a message with those fields, or a sequence [x, y, z, w]."""
    if all(hasattr(q, k) for k in ("x", "y", "z", "w")):
        return float(q.x), float(q.y), float(q.z), float(q.w)
    x, y, z, w = q  # ValueError or TypeError: not a quaternion
    return float(x), float(y), float(z), float(w)


def euler_from_quaternion(q: Any) -> tuple[float, float, float]:
    """Roll, pitch and yaw (rad, static x-y-z axes, as tf's default ``sxyz``)."""
    x, y, z, w = _xyzw(q)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def yaw_of(q: Any) -> float:
    """The heading (rad, counter-clockwise from x, -pi..pi) of a quaternion."""
    x, y, z, w = _xyzw(q)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
