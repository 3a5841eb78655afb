"""The ground world stepped in simulated time: robots, their sensors, and the truth.

``GroundSim.step()`` advances every robot by one physics step (20 ms) and returns what
their sensors produce at that instant (odometry at ``odom.rate``, a laser scan at
``laser.rate``, a bumper event when a bumper is pressed or released) as plain data; the
ROS 2 node turns those into messages. Same world, same seed, same commands at the same
steps: the same readings and the same truth, whatever the machine is doing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hfsmc.sim.ground.base import DiffDrive, Pose
from hfsmc.sim.ground.geometry import Obstacles, box_segments, cast, nearest
from hfsmc.sim.ground.world import GroundWorld

STEP_S = 0.02
TRAIL_S = 0.5  # the truth keeps a pose every half second


@dataclass(frozen=True, slots=True)
class Scan:
    robot: str
    t: float
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    scan_time: float
    ranges: tuple[float, ...]  # REP 117: +inf no return, -inf closer than range_min


@dataclass(frozen=True, slots=True)
class Odometry:
    robot: str
    t: float
    pose: Pose  # odom frame
    v: float
    w: float


@dataclass(frozen=True, slots=True)
class Bumper:
    robot: str
    t: float
    bumper: int  # 0 left, 1 centre, 2 right
    pressed: bool


Reading = Scan | Odometry | Bumper


def world_obstacles(world: GroundWorld) -> Obstacles:
    segs: list[tuple[float, float, float, float]] = []
    for wall in world.walls:
        segs += [(*wall[i], *wall[i + 1]) for i in range(len(wall) - 1)]
    for b in world.boxes:
        segs += box_segments(b.x, b.y, b.length, b.width, math.radians(b.yaw_deg))
    return Obstacles.of(segs)


@dataclass
class RobotTruth:
    collisions: list[dict[str, float]] = field(default_factory=list)
    trail: list[tuple[float, float, float, float]] = field(default_factory=list)
    visited: set[tuple[int, int]] = field(default_factory=set)
    touching: bool = False


class GroundSim:
    """Every robot of a world, one physics step at a time."""

    def __init__(self, world: GroundWorld) -> None:
        self.world = world
        self.step_s = STEP_S
        self.walls = world_obstacles(world)
        self.robots = [DiffDrive(r, world.base) for r in world.robots]
        self.steps = 0
        self.t = 0.0
        self._rng = [np.random.default_rng([world.seed, i]) for i in range(len(self.robots))]
        self._truth = [RobotTruth() for _ in self.robots]
        self._pressed: list[int | None] = [None] * len(self.robots)
        self._odom_every = max(1, round(1.0 / (world.odom.rate * STEP_S)))
        self._scan_every = max(1, round(1.0 / (world.laser.rate * STEP_S)))
        lz = world.laser
        self._angles = (-math.pi + np.arange(lz.rays) * (2 * math.pi / lz.rays)).astype(np.float64)
        self.cells = Coverage(world, self.walls)
        for i in range(len(self.robots)):
            self._mark(i)

    def robot(self, name: str) -> DiffDrive:
        return next(r for r in self.robots if r.name == name)

    def obstacles_for(self, i: int) -> Obstacles:
        """The walls and boxes, and every other robot as a disc."""
        others = [(r.pose.x, r.pose.y, r.limits.radius) for j, r in enumerate(self.robots) if j != i]
        return self.walls.with_circles(others)

    def step(self) -> list[Reading]:
        """One step of STEP_S seconds; the readings due at its end."""
        for i, r in enumerate(self.robots):
            r.step(self.t, STEP_S, self.obstacles_for(i))
        self.steps += 1
        self.t = self.steps * STEP_S
        out: list[Reading] = []
        for i, r in enumerate(self.robots):
            self._mark(i)
            out += self._bumper(i)
            if self.steps % self._odom_every == 0:
                pose, v, w = r.odometry()
                out.append(Odometry(r.name, self.t, pose, v, w))
            if self.steps % self._scan_every == 0:
                out.append(self.scan(i))
        return out

    def scan(self, i: int) -> Scan:
        lz, r = self.world.laser, self.robots[i]
        p = r.pose
        ox, oy = p.x + lz.x * math.cos(p.yaw), p.y + lz.x * math.sin(p.yaw)
        d = cast(ox, oy, self._angles + p.yaw, self.obstacles_for(i), lz.range_max)
        if lz.noise > 0:
            d = d + self._rng[i].normal(0.0, lz.noise, d.shape)
        d = np.where(d < lz.range_min, -np.inf, d)
        d = np.where(d > lz.range_max, np.inf, d)
        inc = 2 * math.pi / lz.rays
        return Scan(r.name, self.t, -math.pi, inc, lz.range_min, lz.range_max,
                    1.0 / lz.rate, tuple(float(x) for x in d))

    def _bumper(self, i: int) -> list[Bumper]:
        r, truth = self.robots[i], self._truth[i]
        touching = r.contact is not None
        if r.contact is not None and not truth.touching:
            truth.collisions.append({"t": round(self.t, 3), "x": round(r.pose.x, 3),
                                     "y": round(r.pose.y, 3),
                                     "bearing_deg": round(math.degrees(r.contact.bearing), 1)})
        truth.touching = touching
        now = r.contact.bumper if r.contact is not None else None
        was = self._pressed[i]
        self._pressed[i] = now
        if now == was:
            return []
        out = [] if was is None else [Bumper(r.name, self.t, was, False)]
        return out + ([] if now is None else [Bumper(r.name, self.t, now, True)])

    def _mark(self, i: int) -> None:
        r, truth = self.robots[i], self._truth[i]
        truth.visited |= self.cells.under(r.pose.x, r.pose.y, r.limits.radius)
        if self.steps % round(TRAIL_S / STEP_S) == 0:
            truth.trail.append((round(self.t, 3), round(r.pose.x, 3), round(r.pose.y, 3),
                                round(math.degrees(r.pose.yaw), 1)))

    def truth(self) -> dict[str, Any]:
        """What really happened, per robot: pose, collisions, coverage, path."""
        robots = {}
        for r, truth in zip(self.robots, self._truth, strict=True):
            clearance = nearest(r.pose.x, r.pose.y, self.walls)[0] - r.limits.radius
            robots[r.name] = {
                "namespace": r.namespace,
                "pose": {"x": round(r.pose.x, 4), "y": round(r.pose.y, 4),
                         "yaw_deg": round(math.degrees(r.pose.yaw), 2)},
                "speed": {"linear": round(r.v, 4), "angular": round(r.w, 4)},
                "clearance": round(clearance, 4),
                "collisions": truth.collisions,
                "travelled": round(r.travelled, 3),
                "coverage": round(self.cells.fraction(truth.visited), 4),
                "trail": truth.trail,
            }
        return {"world": self.world.name, "seed": self.world.seed, "time": round(self.t, 3),
                "robots": robots}


class Coverage:
    """Cells of ``coverage.cell`` metres a base can reach from where the robots start."""

    def __init__(self, world: GroundWorld, walls: Obstacles) -> None:
        self.size = world.coverage.cell
        x0, y0, x1, y1 = world.bounds()
        self.origin = (x0, y0)
        nx, ny = math.ceil((x1 - x0) / self.size), math.ceil((y1 - y0) / self.size)
        radius = world.base.radius
        free = {(i, j) for i in range(nx) for j in range(ny)
                if nearest(*self.centre((i, j)), walls)[0] >= radius}
        reach: set[tuple[int, int]] = set()
        todo = [self.cell(r.x, r.y) for r in world.robots]
        todo = [c for c in todo if c in free]
        while todo:
            c = todo.pop()
            if c in reach:
                continue
            reach.add(c)
            for n in ((c[0] + 1, c[1]), (c[0] - 1, c[1]), (c[0], c[1] + 1), (c[0], c[1] - 1)):
                if n in free and n not in reach and self._open(c, n, walls):
                    todo.append(n)
        self.reachable = frozenset(reach)

    def centre(self, c: tuple[int, int]) -> tuple[float, float]:
        return self.origin[0] + (c[0] + 0.5) * self.size, self.origin[1] + (c[1] + 0.5) * self.size

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return int((x - self.origin[0]) // self.size), int((y - self.origin[1]) // self.size)

    def _open(self, a: tuple[int, int], b: tuple[int, int], walls: Obstacles) -> bool:
        (ax, ay), (bx, by) = self.centre(a), self.centre(b)
        angle = np.array([math.atan2(by - ay, bx - ax)])
        return bool(cast(ax, ay, angle, walls, self.size)[0] == np.inf)

    def under(self, x: float, y: float, radius: float) -> set[tuple[int, int]]:
        """The reachable cells whose centre lies under a disc."""
        ci, cj = self.cell(x, y)
        k = math.ceil(radius / self.size) + 1
        return {(i, j) for i in range(ci - k, ci + k + 1) for j in range(cj - k, cj + k + 1)
                if (i, j) in self.reachable
                and math.hypot(self.centre((i, j))[0] - x, self.centre((i, j))[1] - y) <= radius}

    def fraction(self, visited: set[tuple[int, int]]) -> float:
        return len(visited) / len(self.reachable) if self.reachable else 0.0
