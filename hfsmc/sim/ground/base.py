"""A differential-drive base (TurtleBot 2 / Kobuki size and limits) that meets what it hits.

The base follows its last ``cmd_vel`` (linear x, angular z) within its speed and
acceleration limits, and stops when none has come for ``cmd_timeout`` seconds, as Kobuki's
driver does. Turning in place is never blocked (the base is a disc); a forward or backward
move stops where the disc touches a wall, a box or another robot, the base stalls there
(its speed drops to 0) and the bumper on that side is pressed while it touches: Kobuki has
three, left, centre and right, over the front half. Odometry is the base's own motion,
exact (a simulated base does not slip), from where it started.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hfsmc.sim.ground.geometry import Obstacles, nearest
from hfsmc.sim.ground.world import Base, RobotStart

CONTACT_M = 0.002  # closer than this to an obstacle's edge counts as touching it
BUMPER_CENTRE_RAD = math.radians(20)  # |bearing| below this: the centre bumper
BUMPER_SIDE_RAD = math.radians(90)  # up to this: left (positive) or right (negative)
LEFT, CENTRE, RIGHT = 0, 1, 2  # kobuki's BumperEvent.bumper


@dataclass(slots=True)
class Pose:
    x: float
    y: float
    yaw: float


@dataclass(slots=True)
class Contact:
    x: float  # the touched point, world frame
    y: float
    bearing: float  # rad from the base's heading, counter-clockwise

    @property
    def bumper(self) -> int | None:
        """Which bumper it presses, or None (the side or rear: no bumper there)."""
        if abs(self.bearing) < BUMPER_CENTRE_RAD:
            return CENTRE
        if abs(self.bearing) <= BUMPER_SIDE_RAD:
            return LEFT if self.bearing > 0 else RIGHT
        return None


def _toward(value: float, target: float, step: float) -> float:
    return min(target, value + step) if target > value else max(target, value - step)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


class DiffDrive:
    """One base: its true pose, speeds, the last command and its contact."""

    def __init__(self, start: RobotStart, base: Base) -> None:
        self.name, self.namespace, self.limits = start.name, start.namespace, base
        self.pose = Pose(start.x, start.y, _wrap(math.radians(start.yaw_deg)))
        self.start = Pose(self.pose.x, self.pose.y, self.pose.yaw)
        self.v = 0.0  # m/s, forward
        self.w = 0.0  # rad/s, counter-clockwise
        self.cmd = (0.0, 0.0)
        self.cmd_t = -math.inf
        self.contact: Contact | None = None
        self.travelled = 0.0

    def command(self, linear_x: float, angular_z: float, t: float) -> None:
        """A cmd_vel at time t; values that are not finite stop the base."""
        if not (math.isfinite(linear_x) and math.isfinite(angular_z)):
            linear_x = angular_z = 0.0
        lim = self.limits
        self.cmd = (max(-lim.max_speed, min(lim.max_speed, linear_x)),
                    max(-lim.max_turn, min(lim.max_turn, angular_z)))
        self.cmd_t = t

    def step(self, t: float, dt: float, obstacles: Obstacles) -> None:
        """Move for dt seconds at time t among the obstacles (other robots included)."""
        lim = self.limits
        target = self.cmd if t - self.cmd_t <= lim.cmd_timeout else (0.0, 0.0)
        self.v = _toward(self.v, target[0], lim.accel * dt)
        self.w = _toward(self.w, target[1], lim.turn_accel * dt)
        p = self.pose
        yaw = _wrap(p.yaw + self.w * dt)
        mid = p.yaw + self.w * dt / 2
        dx, dy = self.v * dt * math.cos(mid), self.v * dt * math.sin(mid)
        f = self._free_fraction(p.x, p.y, dx, dy, obstacles)
        if f < 1.0:
            self.v = 0.0  # stalled against it
        self.pose = Pose(p.x + f * dx, p.y + f * dy, yaw)
        self.travelled += f * math.hypot(dx, dy)
        self.contact = self._touching(obstacles)

    def _free_fraction(self, x: float, y: float, dx: float, dy: float,
                       obstacles: Obstacles) -> float:
        """How much of the move (0..1) the disc makes before it touches something."""
        r = self.limits.radius
        if dx == dy == 0.0 or nearest(x + dx, y + dy, obstacles)[0] >= r:
            return 1.0
        low, high = 0.0, 1.0
        if nearest(x, y, obstacles)[0] < r:  # already overlapping (a start inside a box):
            return 1.0 if _moving_away(x, y, dx, dy, obstacles) else 0.0
        for _ in range(12):  # to 1/4096 of the move: well under a millimetre
            mid = (low + high) / 2
            if nearest(x + mid * dx, y + mid * dy, obstacles)[0] >= r:
                low = mid
            else:
                high = mid
        return low

    def _touching(self, obstacles: Obstacles) -> Contact | None:
        p = self.pose
        d, cx, cy = nearest(p.x, p.y, obstacles)
        if d > self.limits.radius + CONTACT_M:
            return None
        return Contact(cx, cy, _wrap(math.atan2(cy - p.y, cx - p.x) - p.yaw))

    def odometry(self) -> tuple[Pose, float, float]:
        """The pose in the odom frame (where the base started) and the speeds (body frame)."""
        s, p = self.start, self.pose
        c, sn = math.cos(-s.yaw), math.sin(-s.yaw)
        ox, oy = p.x - s.x, p.y - s.y
        return Pose(c * ox - sn * oy, sn * ox + c * oy, _wrap(p.yaw - s.yaw)), self.v, self.w


def _moving_away(x: float, y: float, dx: float, dy: float, obstacles: Obstacles) -> bool:
    return nearest(x + dx, y + dy, obstacles)[0] > nearest(x, y, obstacles)[0]
