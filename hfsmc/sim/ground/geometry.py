"""Segments and circles of a ground world: laser rays and the base's contacts.

A world's obstacles are line segments (walls, the sides of boxes) and circles (other
robots). Coordinates are metres in the world frame of REP 103: x forward (east on the
map), y left (north), angles counter-clockwise from x. All the work is done on numpy
arrays: 360 rays against a few hundred segments take tens of microseconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Obstacles:
    """Segments as rows ``x1, y1, x2, y2``; circles as rows ``x, y, r``."""

    segments: Array  # shape (S, 4)
    circles: Array  # shape (C, 3)

    @staticmethod
    def of(segments: list[tuple[float, float, float, float]],
           circles: list[tuple[float, float, float]] = ()) -> Obstacles:  # type: ignore[assignment]
        return Obstacles(np.array(segments, dtype=float).reshape(-1, 4),
                         np.array(circles, dtype=float).reshape(-1, 3))

    def with_circles(self, circles: list[tuple[float, float, float]]) -> Obstacles:
        return Obstacles(self.segments, np.array(circles, dtype=float).reshape(-1, 3))


def box_segments(x: float, y: float, length: float, width: float,
                 yaw: float) -> list[tuple[float, float, float, float]]:
    """The four sides of a box centred at (x, y), ``length`` along its yaw."""
    c, s = np.cos(yaw), np.sin(yaw)
    hl, hw = length / 2, width / 2
    corners = [(x + c * dx - s * dy, y + s * dx + c * dy)
               for dx, dy in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))]
    return [(*corners[i], *corners[(i + 1) % 4]) for i in range(4)]


def cast(ox: float, oy: float, angles: Array, obstacles: Obstacles, max_range: float) -> Array:
    """The distance along each ray from (ox, oy) to the first obstacle, inf beyond max_range."""
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    best = np.full(angles.shape, np.inf)
    seg = obstacles.segments
    if len(seg):
        ax, ay = seg[:, 0][None, :], seg[:, 1][None, :]
        ex, ey = (seg[:, 2] - seg[:, 0])[None, :], (seg[:, 3] - seg[:, 1])[None, :]
        den = dx * ey - dy * ex  # ray x segment
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((ax - ox) * ey - (ay - oy) * ex) / den  # along the ray
            u = ((ax - ox) * dy - (ay - oy) * dx) / den  # along the segment
        hit = (np.abs(den) > 1e-12) & (t >= 0) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(hit, t, np.inf).min(axis=1))
    circ = obstacles.circles
    if len(circ):
        cx, cy, r = circ[:, 0][None, :] - ox, circ[:, 1][None, :] - oy, circ[:, 2][None, :]
        b = dx * cx + dy * cy  # projection of the centre on the ray
        disc = b * b - (cx * cx + cy * cy - r * r)
        with np.errstate(invalid="ignore"):
            t = b - np.sqrt(disc)
        hit = (disc >= 0) & (t >= 0)
        best = np.minimum(best, np.where(hit, t, np.inf).min(axis=1))
    return np.where(best <= max_range, best, np.inf)


def nearest(x: float, y: float, obstacles: Obstacles) -> tuple[float, float, float]:
    """The distance from (x, y) to the nearest obstacle's edge, and that edge's point."""
    best = (np.inf, x, y)
    seg = obstacles.segments
    if len(seg):
        ax, ay, bx, by = seg[:, 0], seg[:, 1], seg[:, 2], seg[:, 3]
        ex, ey = bx - ax, by - ay
        length2 = np.maximum(ex * ex + ey * ey, 1e-18)
        u = np.clip(((x - ax) * ex + (y - ay) * ey) / length2, 0.0, 1.0)
        px, py = ax + u * ex, ay + u * ey
        d = np.hypot(px - x, py - y)
        i = int(np.argmin(d))
        best = (float(d[i]), float(px[i]), float(py[i]))
    circ = obstacles.circles
    if len(circ):
        dc = np.hypot(circ[:, 0] - x, circ[:, 1] - y)
        gap = dc - circ[:, 2]
        i = int(np.argmin(gap))
        if gap[i] < best[0]:
            k = circ[i, 2] / max(dc[i], 1e-12)
            best = (float(gap[i]), float(circ[i, 0] + (x - circ[i, 0]) * k),
                    float(circ[i, 1] + (y - circ[i, 1]) * k))
    return best
