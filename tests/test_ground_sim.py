"""The ground robot's world, base, laser, bumper and truth (hfsmc/sim/ground), without DDS."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import pytest
from ruamel.yaml import YAML

from hfsmc.sim.ground.base import CENTRE, LEFT
from hfsmc.sim.ground.geometry import nearest
from hfsmc.sim.ground.sim import STEP_S, Bumper, GroundSim, Odometry, Reading, Scan
from hfsmc.sim.ground.world import GroundWorld, load_ground_world, parse_ground_world
from hfsmc.sim.world import WorldError

ROOM = """\
name: room
walls: [[[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]]]
"""


def world(text: str) -> GroundWorld:
    return parse_ground_world(YAML(typ="rt").load(text), "w.yaml")


def run(sim: GroundSim, seconds: float, v: float = 0.0, w: float = 0.0) -> list[Reading]:
    out: list[Reading] = []
    for _ in range(round(seconds / STEP_S)):
        sim.robots[0].command(v, w, sim.t)
        out += sim.step()
    return out


@pytest.mark.parametrize(("text", "where", "message"), [
    ("laser: {rays: 2}", "2:15", "rays: must be between 8 and 4096"),
    ("boxes: [{x: 1}]", "2:9", "a box needs `y`"),
    ("robots: [{name: 1a}]", "2:17", "a robot's name is a ROS name"),
    ("walls: [[[0, 0]]]", "2:9", "a wall is a list of at least two"),
    ("odom: {rate: fast}", "2:14", "rate: expected a number"),
    ("base: {wheels: 2}", "2:16", "unknown key `wheels` in base"),
    ("robots: [{name: a, namespace: b}]", "2:31", "a namespace is absolute"),
    ("robots: [{name: a}, {name: a}]", "2:21", "two robots named 'a'"),
    ("laser: {range_min: 4}", "2:20", r"laser\.range_min must be below range_max"),
    ("walls: [[[0, 0], [1, x]]]", "2:18", r"a point is \[x, y\]"),
    ("colour: red", "2:9", "unknown key `colour`"),
])
def test_a_bad_world_is_named_at_its_position(text: str, where: str, message: str) -> None:
    with pytest.raises(WorldError, match=rf"^w\.yaml:{where}: {message}"):
        world("name: x\n" + text)


def test_namespaces_default_to_root_for_one_robot_and_to_the_name_for_several() -> None:
    assert [r.namespace for r in world("robots: [{name: tb}]").robots] == ["/"]
    several = world("robots: [{name: a}, {name: b, namespace: /fleet/b/}]").robots
    assert [r.namespace for r in several] == ["/a", "/fleet/b"]


def test_the_laser_measures_the_walls_around_and_nothing_beyond_its_range() -> None:
    sim = GroundSim(world(ROOM + "laser: {noise: 0, range_max: 5}\nrobots: [{x: 2, y: 2}]"))
    scan = sim.scan(0)
    assert scan.angle_increment == pytest.approx(2 * math.pi / 360)
    # angle_min is -pi: ray 0 looks behind, 180 ahead, 270 to the left (counter-clockwise)
    assert [scan.ranges[0], scan.ranges[180], scan.ranges[270]] == pytest.approx([2.0, 4.0, 2.0])
    short = GroundSim(world(ROOM + "laser: {noise: 0, range_max: 3.5}\nrobots: [{x: 2, y: 2}]"))
    assert short.scan(0).ranges[180] == math.inf  # REP 117: no return


def test_the_base_stops_at_a_wall_presses_its_centre_bumper_and_turns_free() -> None:
    sim = GroundSim(world(ROOM + "robots: [{x: 5, y: 2, yaw_deg: 0}]"))
    out = run(sim, 3.0, v=0.5)
    r = sim.robots[0]
    assert r.pose.x == pytest.approx(6 - r.limits.radius, abs=1e-3)  # at the wall, not through it
    presses = [b for b in out if isinstance(b, Bumper)]
    assert [(b.bumper, b.pressed) for b in presses] == [(CENTRE, True)]
    truth = sim.truth()["robots"]["robot"]
    assert len(truth["collisions"]) == 1 and truth["collisions"][0]["bearing_deg"] == 0.0
    out = run(sim, 1.0, v=-0.3)
    assert [(b.bumper, b.pressed) for b in out if isinstance(b, Bumper)] == [(CENTRE, False)]
    assert r.pose.x < 6 - r.limits.radius - 0.1


def test_a_wall_on_the_left_presses_the_left_bumper() -> None:
    sim = GroundSim(world(ROOM + "robots: [{x: 3, y: 3.5, yaw_deg: 45}]"))
    out = run(sim, 3.0, v=0.4)
    assert [b.bumper for b in out if isinstance(b, Bumper) and b.pressed][:1] == [LEFT]


def test_the_base_stops_half_a_second_after_the_last_command() -> None:
    sim = GroundSim(world(ROOM + "robots: [{x: 1, y: 2}]"))
    run(sim, 1.0, v=0.3)
    x = sim.robots[0].pose.x
    for _ in range(round(0.4 / STEP_S)):
        sim.step()
    assert sim.robots[0].pose.x > x + 0.08  # still going on the last command
    for _ in range(round(1.0 / STEP_S)):
        sim.step()
    assert sim.robots[0].v == 0.0


def test_odometry_is_in_the_frame_where_the_base_started() -> None:
    sim = GroundSim(world(ROOM + "robots: [{x: 3, y: 1, yaw_deg: 90}]"))
    out = run(sim, 2.0, v=0.5)
    odom = [o for o in out if isinstance(o, Odometry)]
    assert len(odom) == 100  # 50 Hz for 2 s
    last = odom[-1]
    assert last.pose.x == pytest.approx(sim.robots[0].pose.y - 1)  # forward in odom is +y here
    assert last.pose.y == pytest.approx(0.0, abs=1e-9)
    assert sum(isinstance(o, Scan) for o in out) == 20  # 10 Hz


def test_two_robots_meet_and_do_not_pass_through_each_other() -> None:
    sim = GroundSim(world(ROOM + "laser: {noise: 0}\nrobots: [{name: a, x: 1, y: 2}, "
                          "{name: b, x: 3, y: 2, yaw_deg: 180}]"))
    assert sim.scan(0).ranges[180] == pytest.approx(2 - sim.robots[1].limits.radius)
    for _ in range(round(4 / STEP_S)):
        for r in sim.robots:
            r.command(0.5, 0.0, sim.t)
        sim.step()
    a, b = sim.robots
    assert b.pose.x - a.pose.x == pytest.approx(a.limits.radius * 2, abs=5e-3)
    assert all(len(sim.truth()["robots"][n]["collisions"]) == 1 for n in "ab")


def test_same_seed_same_run_and_another_seed_another_noise() -> None:
    def truth_and_scan(seed: int) -> tuple[dict[str, Any], tuple[float, ...]]:
        sim = GroundSim(world(ROOM + f"seed: {seed}\nboxes: [{{x: 3, y: 2, yaw_deg: 30}}]\n"
                              "robots: [{x: 1, y: 1}]"))
        run(sim, 20.0, v=0.5, w=0.4)
        return sim.truth(), sim.scan(0).ranges

    assert truth_and_scan(4) == truth_and_scan(4)
    assert truth_and_scan(4)[1] != truth_and_scan(5)[1]


def test_coverage_counts_the_cells_a_base_can_reach() -> None:
    open_room = GroundSim(world(ROOM + "robots: [{x: 1, y: 1}]"))
    boxed = GroundSim(world(ROOM + "boxes: [{x: 3, y: 2, length: 2, width: 2}]\n"
                            "robots: [{x: 1, y: 1}]"))
    assert len(boxed.cells.reachable) < len(open_room.cells.reachable)
    start = open_room.truth()["robots"]["robot"]["coverage"]
    run(open_room, 10.0, v=0.4, w=0.3)
    assert 0 <= start < open_room.truth()["robots"]["robot"]["coverage"] <= 1
    walled_off = GroundSim(world("walls: [[[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]], "
                                 "[[3, 0], [3, 4]]]\nrobots: [{x: 1, y: 1}]"))
    assert len(walled_off.cells.reachable) < len(open_room.cells.reachable) * 0.6


GROUND_WORLDS = sorted(p for p in Path("examples").glob("*/world.yaml")
                       if re.search(r"^(walls|robots):", p.read_text(), re.M))


def test_the_ground_example_worlds_are_there() -> None:
    assert {p.parent.name for p in GROUND_WORLDS} >= {"bump_and_go", "wall_follower",
                                                       "stop_at_wall"}


@pytest.mark.parametrize("path", GROUND_WORLDS, ids=lambda p: p.parent.name)
def test_a_ground_example_world_loads_and_its_robots_can_move(path: Path) -> None:
    sim = GroundSim(load_ground_world(path))
    assert len(sim.cells.reachable) > 50  # a room to drive in, not a box around the start
    for r in sim.robots:  # nobody starts touching a wall or a box
        assert r.contact is None and nearest(r.pose.x, r.pose.y, sim.walls)[0] > r.limits.radius
