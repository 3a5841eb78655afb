"""`hfsmc sim`'s vehicle, flown from a pymavlink ground station as a component would.

Every test starts real simulator processes that send MAVLink to a free UDP port
on 127.0.0.1, where the test listens (``udpin``), as MAVProxy listens for SITL.
Every wait has a timeout; processes are stopped (SIGINT, then kill) by the fixture.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import random
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("MAVLINK20", "1")  # the ground station speaks MAVLink 2, as the vehicle
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as v20

from hfsmc.sim.autopilot import Autopilot
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World, load_world
from tests.support import free_port

ROOT = Path(__file__).resolve().parent.parent
RUN = "import sys; from hfsmc.sim.run import main; sys.exit(main(sys.argv[1:]))"
ML = mavutil.mavlink
STABILIZE, GUIDED, LOITER, LAND = 0, 4, 5, 9
SET_MODE_ACK = 11  # ArduPilot acknowledges the SET_MODE message as "command 11"
VELOCITY_ONLY = 0b0000_0101_1100_0111  # ignore position, acceleration, yaw; use yaw_rate
POSITION_ONLY = 0b0000_1101_1111_1000  # ignore velocity, acceleration, yaw, yaw_rate
FAST_WORLD = "vehicle: {max_speed: 5, max_accel: 4, max_climb: 3}\n"


class Sim:
    """One `hfsmc sim` process and the pymavlink ground station listening for it."""

    def __init__(self, tmp: Path, args: list[str], boot: float) -> None:
        self.port = free_port(socket.SOCK_DGRAM)
        self.gs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}",
                                             source_system=255, dialect="ardupilotmega")
        self.truth_path = tmp / f"truth-{self.port}.json"
        cmd = [sys.executable, "-c", RUN, "--mavlink", f"udpout:127.0.0.1:{self.port}",
               "--no-camera", "--boot-time", str(boot), "--truth", str(self.truth_path), *args]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stderr=subprocess.PIPE, text=True)
        self.stderr = ""
        self.returncode: int | None = None

    # -- listening ----------------------------------------------------------------

    def recv(self, kind: str, cond: Callable[[Any], bool] = lambda m: True,
             timeout: float = 5.0) -> Any:
        """The next ``kind`` message meeting ``cond``; fails after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            m = self.gs.recv_match(type=kind, blocking=True, timeout=min(left, 0.5))
            if m is not None and cond(m):
                return m
        raise AssertionError(f"no {kind} as expected within {timeout} s")

    def drain(self) -> None:
        """Read what is queued, so ``latest`` is current."""
        while self.gs.recv_match(blocking=False) is not None:
            pass

    def latest(self, kind: str) -> Any:
        self.drain()
        return self.gs.messages[kind]

    def collect(self, kind: str | list[str], seconds: float) -> list[Any]:
        out: list[Any] = []
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            m = self.gs.recv_match(type=kind, blocking=True, timeout=left)
            if m is not None:
                out.append(m)
        return out

    def heartbeat(self, cond: Callable[[Any], bool] = lambda m: True,
                  timeout: float = 5.0) -> Any:
        return self.recv("HEARTBEAT", cond, timeout)

    # -- commanding ---------------------------------------------------------------

    def command(self, cmd: int, *params: float, timeout: float = 3.0) -> int:
        p = [*params, *[0.0] * (7 - len(params))]
        self.drain()
        self.gs.mav.command_long_send(1, 1, cmd, 0, *p)
        return int(self.recv("COMMAND_ACK", lambda m: m.command == cmd, timeout).result)

    def set_mode(self, mode: int) -> int:
        self.drain()
        self.gs.mav.set_mode_send(1, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode)
        return int(self.recv("COMMAND_ACK", lambda m: m.command == SET_MODE_ACK).result)

    def target(self, frame: int, mask: int, pos: tuple[float, float, float] = (0, 0, 0),
               vel: tuple[float, float, float] = (0, 0, 0), yaw_rate: float = 0.0) -> None:
        self.gs.mav.set_position_target_local_ned_send(0, 1, 1, frame, mask, *pos, *vel,
                                                       0, 0, 0, 0, yaw_rate)

    def fly_velocity(self, frame: int, vel: tuple[float, float, float], seconds: float) -> None:
        """Stream a velocity target at 10 Hz, as a component does each tick."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.target(frame, VELOCITY_ONLY, vel=vel)
            time.sleep(0.1)
            self.drain()

    def wait_ready(self) -> None:
        self.recv("GPS_RAW_INT", lambda m: m.fix_type >= 3)
        self.recv("EKF_STATUS_REPORT", lambda m: m.flags & ML.EKF_POS_HORIZ_ABS)

    def take_off(self, alt: float) -> None:
        self.wait_ready()
        assert self.set_mode(GUIDED) == ML.MAV_RESULT_ACCEPTED
        assert self.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ML.MAV_RESULT_ACCEPTED
        assert self.command(ML.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt) == \
            ML.MAV_RESULT_ACCEPTED
        self.recv("GLOBAL_POSITION_INT", lambda m: m.relative_alt >= (alt - 0.15) * 1000,
                  timeout=4 + 2 * alt)

    def position(self) -> tuple[float, float, float]:
        m = self.latest("LOCAL_POSITION_NED")
        return (m.x, m.y, m.z)

    # -- the end ------------------------------------------------------------------

    def close(self, sig: int = signal.SIGINT) -> tuple[int, str]:
        """Stop the simulator (``sig``, then kill); its exit status and stderr."""
        if self.returncode is None:
            if self.proc.poll() is None:
                self.proc.send_signal(sig)
            try:
                _, self.stderr = self.proc.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                _, self.stderr = self.proc.communicate(timeout=5)
            self.returncode = self.proc.returncode
            self.gs.close()
        assert self.returncode is not None
        return self.returncode, self.stderr

    def truth(self) -> dict[str, Any]:
        return dict(json.loads(self.truth_path.read_text()))


@pytest.fixture
def sims(tmp_path: Path) -> Iterator[Callable[..., Sim]]:
    """Start simulators (``sims(*args, boot=0.3)``); all are stopped at the end."""
    started: list[Sim] = []

    def start(*args: str, boot: float = 0.3) -> Sim:
        sim = Sim(tmp_path, list(args), boot)
        started.append(sim)
        return sim

    yield start
    for sim in started:
        sim.close()


@pytest.fixture
def fast_world(tmp_path: Path) -> str:
    path = tmp_path / "fast.yaml"
    path.write_text(FAST_WORLD)
    return str(path)


def test_heartbeat_and_telemetry_arrive(sims: Callable[..., Sim]) -> None:
    sim = sims()
    hb = sim.heartbeat()
    assert (hb.type, hb.autopilot) == (ML.MAV_TYPE_QUADROTOR, ML.MAV_AUTOPILOT_ARDUPILOTMEGA)
    assert hb.base_mode & ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.custom_mode == STABILIZE
    assert (hb.get_srcSystem(), hb.get_srcComponent()) == (1, 1)
    assert hb.get_msgbuf()[0] == 0xFD  # MAVLink 2
    sim.wait_ready()
    assert "HOME_POSITION" in sim.gs.messages  # sent once when the EKF got its origin
    assert sim.command(ML.MAV_CMD_REQUEST_MESSAGE, ML.MAVLINK_MSG_ID_HOME_POSITION) == \
        ML.MAV_RESULT_ACCEPTED
    home = sim.recv("HOME_POSITION", timeout=2)
    assert home.latitude == round(-35.363261 * 1e7) and home.longitude == round(149.16523 * 1e7)
    status = sim.recv("SYS_STATUS")
    assert status.battery_remaining == 100 and 16000 < status.voltage_battery < 17000
    pos = sim.recv("GLOBAL_POSITION_INT", lambda m: m.lat != 0)
    assert abs(pos.lat - home.latitude) < 20 and abs(pos.relative_alt) < 200
    local = sim.recv("LOCAL_POSITION_NED")
    assert max(abs(local.x), abs(local.y), abs(local.z)) < 0.2  # cm-level noise on the ground
    sim.recv("ATTITUDE")
    got = [m.get_type() for m in sim.collect(["ATTITUDE", "HEARTBEAT"], 1.5)]
    assert 10 <= got.count("ATTITUDE") <= 20  # 10 Hz by default
    assert got.count("HEARTBEAT") in (1, 2)  # 1 Hz


def test_guided_refused_before_ready_then_accepted(sims: Callable[..., Sim]) -> None:
    sim = sims(boot=1.5)
    sim.heartbeat()
    assert sim.recv("GPS_RAW_INT").fix_type < 3
    assert not sim.recv("EKF_STATUS_REPORT").flags & ML.EKF_POS_HORIZ_ABS
    assert sim.set_mode(GUIDED) == ML.MAV_RESULT_FAILED
    assert sim.gs.messages["STATUSTEXT"].text == "Mode change to GUIDED failed: requires position"
    assert sim.command(ML.MAV_CMD_DO_SET_MODE, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED) \
        == ML.MAV_RESULT_FAILED
    assert sim.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ML.MAV_RESULT_FAILED
    assert sim.gs.messages["STATUSTEXT"].text == "PreArm: Need Position Estimate"
    sim.wait_ready()
    assert sim.set_mode(GUIDED) == ML.MAV_RESULT_ACCEPTED
    hb = sim.heartbeat()
    assert hb.custom_mode == GUIDED and hb.base_mode & ML.MAV_MODE_FLAG_GUIDED_ENABLED
    assert sim.command(ML.MAV_CMD_DO_SET_MODE, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LOITER) \
        == ML.MAV_RESULT_ACCEPTED
    assert sim.heartbeat(lambda m: m.custom_mode == LOITER, timeout=2).custom_mode == LOITER


def test_arming_rules(sims: Callable[..., Sim]) -> None:
    """Refused outside GUIDED; one ACK per command; accepted in GUIDED, and disarmed
    by the vehicle itself 10 s later if it never took off."""
    ground, sim = sims(), sims()
    ground.wait_ready()
    assert ground.set_mode(GUIDED) == ML.MAV_RESULT_ACCEPTED
    assert ground.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ML.MAV_RESULT_ACCEPTED
    armed_at = time.monotonic()
    ground.heartbeat(lambda m: m.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED, timeout=2)

    sim.wait_ready()
    assert sim.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ML.MAV_RESULT_FAILED
    assert sim.gs.messages["STATUSTEXT"].text == "Arm: Mode STABILIZE not armable"
    assert not sim.heartbeat().base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED
    sent = {ML.MAV_CMD_COMPONENT_ARM_DISARM: ML.MAV_RESULT_FAILED,  # still STABILIZE
            ML.MAV_CMD_NAV_TAKEOFF: ML.MAV_RESULT_FAILED,  # not armed
            ML.MAV_CMD_DO_PARACHUTE: ML.MAV_RESULT_UNSUPPORTED,  # unknown here
            ML.MAV_CMD_GET_HOME_POSITION: ML.MAV_RESULT_ACCEPTED}
    sim.drain()
    for cmd in sent:
        sim.gs.mav.command_long_send(1, 1, cmd, 0, 1, 0, 0, 0, 0, 0, 5)
    acks = sim.collect("COMMAND_ACK", 1.0)
    assert sorted(a.command for a in acks) == sorted(sent)
    assert {a.command: a.result for a in acks} == sent

    ground.heartbeat(lambda m: not m.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED, timeout=15)
    assert 8.5 < time.monotonic() - armed_at < 14
    assert "disarmed (auto-disarm after 10 s on the ground)" in ground.close()[1]


def test_arm_then_takeoff_reaches_5m(sims: Callable[..., Sim], fast_world: str) -> None:
    sim = sims("--world", fast_world)
    sim.take_off(5.0)
    hb = sim.heartbeat()
    assert hb.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED and hb.system_status == ML.MAV_STATE_ACTIVE
    alts = [m.relative_alt / 1000 for m in sim.collect("GLOBAL_POSITION_INT", 0.7)]
    assert alts and max(alts) < 5.25 and min(alts) > 4.7  # there, without overshoot
    assert sim.command(ML.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 8) == ML.MAV_RESULT_FAILED


def test_velocity_targets_move_north_in_local_and_body_frames(
        sims: Callable[..., Sim], fast_world: str) -> None:
    sim = sims("--world", fast_world)
    sim.take_off(2.0)
    n0, e0, _ = sim.position()
    sim.fly_velocity(ML.MAV_FRAME_LOCAL_NED, (2.0, 0.0, 0.0), 1.0)
    n1, e1, d1 = sim.position()
    assert n1 - n0 > 0.9 and abs(e1 - e0) < 0.3 and abs(d1 + 2) < 0.3
    # Face east, then "left" in the body frame is north.
    assert sim.command(ML.MAV_CMD_CONDITION_YAW, 90, 180, 1, 0) == ML.MAV_RESULT_ACCEPTED
    sim.recv("ATTITUDE", lambda m: abs(m.yaw - math.pi / 2) < 0.03, timeout=5)
    sim.fly_velocity(ML.MAV_FRAME_BODY_NED, (0.0, -2.0, 0.0), 1.0)
    n2, e2, _ = sim.position()
    assert n2 - n1 > 0.9 and abs(e2 - e1) < 0.4
    sim.fly_velocity(ML.MAV_FRAME_BODY_OFFSET_NED, (2.0, 0.0, 0.0), 1.0)
    _, e3, _ = sim.position()
    assert e3 - e2 > 0.6 and abs(sim.latest("ATTITUDE").yaw - math.pi / 2) < 0.05


def test_land_touches_down_and_disarms(sims: Callable[..., Sim], fast_world: str) -> None:
    sim = sims("--world", fast_world)
    sim.take_off(1.5)
    assert sim.command(ML.MAV_CMD_NAV_LAND) == ML.MAV_RESULT_ACCEPTED
    assert sim.heartbeat(lambda m: m.custom_mode == LAND, timeout=2)
    sim.recv("GLOBAL_POSITION_INT", lambda m: m.relative_alt < 100, timeout=8)
    sim.heartbeat(lambda m: not m.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED, timeout=6)
    rc, err = sim.close(signal.SIGTERM)
    assert rc == 0 and "landed at" in err and "disarmed (landed)" in err
    truth = sim.truth()
    assert (truth["mode"], truth["armed"], truth["landed"]) == ("LAND", False, True)
    assert truth["position"]["down"] == 0.0 and truth["track"]["landings"] == 1
    assert 1.3 < truth["track"]["max_altitude"] < 1.7  # LAND came before the climb ended


def test_set_message_interval_changes_a_rate(sims: Callable[..., Sim]) -> None:
    sim = sims()
    sim.wait_ready()
    interval = ML.MAV_CMD_SET_MESSAGE_INTERVAL
    assert sim.command(interval, ML.MAVLINK_MSG_ID_ATTITUDE, 40_000) == ML.MAV_RESULT_ACCEPTED
    assert 18 <= len(sim.collect("ATTITUDE", 1.0)) <= 32  # 25 Hz
    assert sim.command(interval, ML.MAVLINK_MSG_ID_ATTITUDE, -1) == ML.MAV_RESULT_ACCEPTED
    time.sleep(0.1)
    sim.drain()
    assert sim.collect("ATTITUDE", 0.8) == []
    assert sim.command(interval, ML.MAVLINK_MSG_ID_ATTITUDE, 0) == ML.MAV_RESULT_ACCEPTED
    assert 6 <= len(sim.collect("ATTITUDE", 1.0)) <= 14  # back to the default 10 Hz
    assert sim.command(interval, ML.MAVLINK_MSG_ID_FENCE_STATUS, 1e5) == ML.MAV_RESULT_DENIED


def test_link_drop_stops_heartbeats_for_its_window(sims: Callable[..., Sim]) -> None:
    """The window is in the simulator's own time (the messages' time_boot_ms), not the test's
    wall clock: a loaded machine that starts or steps the simulator late changes nothing."""
    sim = sims("--drop-link-after", "0.5", "--drop-link-for", "1.6")
    stamped = ["ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT"]  # sent with heartbeats
    stamps: list[int] = []  # time_boot_ms of the stamped messages, as they arrive
    heartbeats: list[int] = []  # a heartbeat's instant: that of the stamped message after it
    waiting = 0  # heartbeats before any stamped message of their step has come
    deadline = time.monotonic() + 30
    while (not stamps or stamps[-1] < 3600) and (left := deadline - time.monotonic()) > 0:
        m = sim.gs.recv_match(type=["HEARTBEAT", *stamped], blocking=True, timeout=min(left, 1))
        if m is None:
            continue
        if m.get_type() == "HEARTBEAT":
            waiting += 1
        else:
            stamps.append(m.time_boot_ms)
            heartbeats += [m.time_boot_ms] * waiting
            waiting = 0
    assert stamps and stamps[-1] >= 3600, stamps  # the simulator ran 3.6 s of its time
    assert [t for t in stamps if 500 <= t < 2100] == [], stamps  # nothing within the window
    assert min(stamps) < 500 and min(t for t in stamps if t >= 2100) < 2200, stamps
    # Heartbeats (1 Hz, at whole seconds) before, none within, then back.
    assert heartbeats == [0, 3000], heartbeats
    # SIGUSR1 toggles the link at run time: once the simulator says it is down (its truth
    # file, written after the link went down), what it sent before is drained.
    sim.proc.send_signal(signal.SIGUSR1)
    deadline = time.monotonic() + 15
    while sim.truth()["link"] != "down" and time.monotonic() < deadline:
        time.sleep(0.05)
    assert sim.truth()["link"] == "down"
    sim.drain()
    assert sim.collect("HEARTBEAT", 1.3) == []
    sim.proc.send_signal(signal.SIGUSR1)
    sim.heartbeat(timeout=10)
    rc, err = sim.close()
    assert rc == 0 and "link dropped (SIGUSR1)" in err and "link restored (SIGUSR1)" in err


def test_garbage_datagrams_are_ignored(sims: Callable[..., Sim]) -> None:
    sim = sims()
    sim.heartbeat()
    address = next(iter(sim.gs.clients))  # the vehicle's own socket
    rng = random.Random(5)
    garbage = [b"", b"\xfd", b"\xfd\xff" + bytes(8), b"\xfe\x21" + bytes(20), b"\xfd" * 4000,
               bytes(rng.randrange(256) for _ in range(300)), b"hello, vehicle"]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for data in garbage * 5:
            s.sendto(data, address)
    sim.wait_ready()
    # Well-formed but absurd: NaN where numbers are needed.
    assert sim.command(ML.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, math.nan) == \
        ML.MAV_RESULT_FAILED
    assert sim.command(ML.MAV_CMD_DO_SET_MODE, math.nan, math.nan) == ML.MAV_RESULT_DENIED
    assert sim.set_mode(GUIDED) == ML.MAV_RESULT_ACCEPTED
    assert sim.heartbeat().custom_mode == GUIDED
    assert sim.proc.poll() is None


def _script(sim: Sim, fly: bool) -> dict[int, tuple[float, float, float]]:
    """Noise samples on the ground by timestamp; then (``fly``) a short flight."""
    sim.wait_ready()
    assert sim.command(ML.MAV_CMD_SET_MESSAGE_INTERVAL, ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                       20_000) == ML.MAV_RESULT_ACCEPTED
    samples = {m.time_boot_ms: (m.x, m.y, m.z) for m in sim.collect("LOCAL_POSITION_NED", 0.5)}
    if fly:
        sim.take_off(1.5)
        time.sleep(0.5)  # settle at 1.5 m
        assert sim.command(ML.MAV_CMD_NAV_LAND) == ML.MAV_RESULT_ACCEPTED
        sim.heartbeat(lambda m: not m.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED, timeout=8)
    assert sim.close()[0] == 0
    return samples


def test_same_seed_same_flight(sims: Callable[..., Sim], fast_world: str) -> None:
    a, b, c = (sims("--world", fast_world, "--seed", seed) for seed in ("7", "7", "8"))
    with ThreadPoolExecutor(3) as pool:
        runs = [pool.submit(_script, sim, fly) for sim, fly in ((a, True), (b, True), (c, False))]
        noise_a, noise_b, noise_c = (r.result(timeout=40) for r in runs)
    common = sorted(set(noise_a) & set(noise_b))
    assert len(common) >= 10
    assert [noise_a[k] for k in common] == [noise_b[k] for k in common]
    assert any(noise_a[k] != noise_c[k] for k in set(noise_a) & set(noise_c))
    ta, tb = a.truth(), b.truth()
    for key in ("mode", "armed", "landed", "victims", "home", "seed"):
        assert ta[key] == tb[key], key
    for key in ("north", "east", "down"):
        assert abs(ta["position"][key] - tb["position"][key]) < 0.02
    assert ta["position"] == {"north": 0.0, "east": 0.0, "down": 0.0}
    assert ta["track"]["max_altitude"] > 1.4 and ta["track"]["max_altitude"] <= 1.5
    for key in ("max_altitude", "distance"):
        assert abs(ta["track"][key] - tb["track"][key]) < 0.05, key
    assert abs(ta["battery"]["remaining_pct"] - tb["battery"]["remaining_pct"]) < 0.5


def test_truth_file(tmp_path: Path) -> None:
    world = tmp_path / "w.yaml"
    world.write_text("name: check\nseed: 3\n"
                     "accident: {north: 20, east: 5, radius: 6}\n"
                     "victims: [{north: 18, east: 4}, {north: 22, east: 7}]\n"
                     "objects: [{name: red, color: [220, 0, 0], speed: 1.0,"
                     " path: [[5, 0], [15, 0]]}]\n")
    truth = tmp_path / "truth.json"
    port = free_port(socket.SOCK_DGRAM)
    proc = subprocess.run(
        [sys.executable, "-c", RUN, "--world", str(world), "--seed", "42", "--no-camera",
         "--mavlink", f"udpout:127.0.0.1:{port}", "--boot-time", "0.5", "--duration", "1.5",
         "--truth", str(truth), "--world-clock", "start"],  # the objects move from the start
        cwd=ROOT, capture_output=True, text=True, timeout=20)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines()[0] == \
        f"sim: MAVLink to udp:127.0.0.1:{port}, no camera (--no-camera)"
    assert "ready" in proc.stderr
    t = json.loads(truth.read_text())
    assert (t["world"], t["seed"], t["mode"], t["armed"], t["landed"], t["ready"]) == \
        ("check", 42, "STABILIZE", False, True, True)
    assert abs(t["time"] - 1.5) < 0.05
    assert t["position"] == {"north": 0.0, "east": 0.0, "down": 0.0} and t["altitude"] == 0.0
    assert t["home"]["lat"] == -35.363261 and t["home"]["lon"] == 149.16523
    assert t["takeoff"] is None and t["landing"] is None
    assert t["track"] == {"max_altitude": 0.0, "distance": 0.0, "flight_time": 0.0,
                          "takeoffs": 0, "landings": 0}
    assert t["battery"]["remaining_pct"] == 100.0
    assert t["accident"] == {"north": 20.0, "east": 5.0, "radius": 6.0}
    assert t["victims"] == [{"north": 18.0, "east": 4.0}, {"north": 22.0, "east": 7.0}]
    red = load_world(world).objects[0].position(t["time"])
    [obj] = t["objects"]
    assert obj["name"] == "red" and obj["color"] == [220, 0, 0]
    assert math.dist((obj["north"], obj["east"]), red) < 1e-3


def test_truth_log_has_a_line_every_half_second_and_at_exit(tmp_path: Path) -> None:
    """--truth-log: the truth as a JSON line every 0.5 s of simulated time and at the exit
    (1.7 s: 0.5, 1.0, 1.5 and 1.7), each the truth file's content at that step."""
    log, truth = tmp_path / "truth.jsonl", tmp_path / "truth.json"
    port = free_port(socket.SOCK_DGRAM)
    proc = subprocess.run(
        [sys.executable, "-c", RUN, "--no-camera", "--mavlink", f"udpout:127.0.0.1:{port}",
         "--boot-time", "0.5", "--duration", "1.7", "--truth", str(truth), "--truth-log",
         str(log)], cwd=ROOT, capture_output=True, text=True, timeout=20)
    assert proc.returncode == 0, proc.stderr
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    assert [x["time"] for x in lines] == [0.5, 1.0, 1.5, 1.7]
    assert [x["ready"] for x in lines] == [False, True, True, True]
    assert lines[-1] == json.loads(truth.read_text())


def test_a_truth_log_that_cannot_be_written_is_one_line_and_exit_2(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-c", RUN, "--no-camera", "--duration", "1",
                           "--truth-log", str(tmp_path / "no" / "such" / "t.jsonl")],
                          cwd=ROOT, capture_output=True, text=True, timeout=20)
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        f"hfsmc: error: --truth-log {tmp_path}/no/such/t.jsonl: No such file or directory"]


@pytest.mark.parametrize("content", ["vehicle: {max_speed: fast}\n", "bogus: 1\n", None])
def test_bad_world_exits_2_with_one_line(tmp_path: Path, content: str | None) -> None:
    world = tmp_path / "bad.yaml"
    if content is not None:
        world.write_text(content)
    proc = subprocess.run([sys.executable, "-c", RUN, "--world", str(world), "--no-camera",
                           "--duration", "1"], cwd=ROOT, capture_output=True, text=True,
                          timeout=20)
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and str(world) in lines[0] and lines[0].startswith("hfsmc: error:")


class Bench:
    """The autopilot and its body in this process, stepped by hand: simulated time only."""

    def __init__(self, seed: int = 1, boot: float = 0.5) -> None:
        world = dataclasses.replace(World(), seed=seed)
        self.body = Body(world.vehicle, world.seed)
        self.sent: list[bytes] = []
        self.ap = Autopilot(world, self.body, self.sent.append, boot_time=boot)
        self.gcs = v20.MAVLink(None, 255, 190)

    def send(self, msg: Any) -> None:
        self.ap.receive(msg.pack(self.gcs))

    def command(self, cmd: int, *params: float) -> None:
        p = [*params, *[0.0] * (7 - len(params))]
        self.send(self.gcs.command_long_encode(1, 1, cmd, 0, *p))

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / self.body.dt)):
            self.ap.step()

    def run_until(self, cond: Callable[[], bool], limit: float) -> float:
        """Step until ``cond``; the simulated seconds it took (fails after ``limit``)."""
        start = self.body.t
        while not cond():
            assert self.body.t - start < limit, "not within the time limit"
            self.ap.step()
        return self.body.t - start

    def fly(self, alt: float) -> None:
        self.run(0.6)
        self.send(self.gcs.set_mode_encode(1, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED))
        self.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        self.command(ML.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt)
        self.run_until(lambda: self.body.altitude > alt - 0.01, 10)

    def state(self) -> tuple[float, ...]:
        b = self.body
        return (b.north, b.east, b.down, b.yaw, b.energy_wh, b.max_alt, b.distance,
                float(b.armed), float(b.landed))


def _scripted_flight(seed: int) -> Bench:
    bench = Bench(seed)
    bench.fly(3.0)
    bench.send(bench.gcs.set_position_target_local_ned_encode(
        0, 1, 1, ML.MAV_FRAME_LOCAL_NED, POSITION_ONLY, 6, -4, -3, 0, 0, 0, 0, 0, 0, 0, 0))
    bench.run(8)
    for _ in range(20):
        bench.send(bench.gcs.set_position_target_local_ned_encode(
            0, 1, 1, ML.MAV_FRAME_BODY_NED, VELOCITY_ONLY, 0, 0, 0, 1.5, 0.5, 0, 0, 0, 0, 0, 0.2))
        bench.run(0.1)
    bench.command(ML.MAV_CMD_NAV_LAND)
    bench.run(12)  # 3 m at LAND_SPEED (0.5 m/s), then the land detector
    return bench


def test_same_commands_at_the_same_steps_give_the_same_bytes() -> None:
    """The whole flight, noise included, is a function of the seed and the commands."""
    a, b, c = _scripted_flight(7), _scripted_flight(7), _scripted_flight(8)
    assert a.state() == b.state() and a.sent == b.sent
    assert not a.body.armed and a.body.landed and a.ap.landings == 1
    assert a.state() == c.state()  # the truth does not depend on the noise...
    assert a.sent != c.sent  # ...what is reported does


def test_rtl_climbs_returns_lands_and_disarms() -> None:
    bench = Bench()
    bench.fly(4.0)
    for _ in range(10):  # away at 5 m/s, facing the way it flies (yaw and rate ignored)
        bench.send(bench.gcs.set_position_target_local_ned_encode(
            0, 1, 1, ML.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY | ML.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE,
            0, 0, 0, 0, 5, 0, 0, 0, 0, 0, 0))
        bench.run(0.5)
    b = bench.body
    assert b.east > 15 and abs(b.yaw - math.pi / 2) < 0.01
    took = bench.run_until(lambda: b.speed() < 0.01, 12)  # the target expires after 3 s
    assert 3.0 < took < 9.0 and bench.ap.mode == GUIDED, took
    bench.command(ML.MAV_CMD_NAV_RETURN_TO_LAUNCH)
    took = bench.run_until(lambda: not b.armed, 80)
    assert (bench.ap.mode, b.landed) == (6, True)
    assert math.hypot(b.north, b.east) < 0.05 and 14.9 < b.max_alt < 15.1
    assert abs(b.yaw - math.pi / 2) < 0.01  # RTL keeps the heading (WP_YAW_BEHAVIOR 2)
    assert took > 5 + 14 / 1.5  # climbs, flies back, loiters 5 s, then descends


# ArduPilot Copter 4.7.0-dev in SITL, component seconds (project issue 13): from the
# take-off command to `altitude - 0.3`, and from LAND to disarmed, hovering at 4 m and 10 m.
ARDUCOPTER_SITL = {4.0: (6.9, 11.35), 10.0: (9.75, 23.35)}


def _takeoff_and_land(bench: Bench, alt: float) -> tuple[float, float]:
    """Seconds from the take-off command to ``alt - 0.3``, and from LAND to disarmed."""
    b = bench.body
    bench.run(0.6)
    bench.send(bench.gcs.set_mode_encode(1, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED))
    bench.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    bench.command(ML.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt)
    takeoff = bench.run_until(lambda: b.altitude > alt - 0.3, 60)
    bench.run_until(lambda: bench.ap.climbing_to is None, 30)
    bench.run(3)
    bench.command(ML.MAV_CMD_NAV_LAND)
    land = bench.run_until(lambda: not b.armed, 80)
    assert b.landed and abs(b.down) < 1e-9
    return takeoff, land


@pytest.mark.parametrize("alt", sorted(ARDUCOPTER_SITL))
def test_takeoff_and_landing_take_as_long_as_on_arducopter(alt: float) -> None:
    """Spool-up, throttle slew and a climb within WPNAV_SPEED_UP and WPNAV_ACCEL_Z; a descent
    at LAND_SPEED below LAND_ALT_LOW, then the land detector: within 15 % of SITL."""
    takeoff, land = _takeoff_and_land(Bench(), alt)
    sitl_takeoff, sitl_land = ARDUCOPTER_SITL[alt]
    assert abs(takeoff / sitl_takeoff - 1) < 0.15, (takeoff, sitl_takeoff)
    assert abs(land / sitl_land - 1) < 0.15, (land, sitl_land)


def test_parameters_shape_the_profile() -> None:
    """The profile follows its parameters: faster landing, no throttle slew, high descent."""
    base = _takeoff_and_land(Bench(), 4.0)
    bench = Bench()
    bench.ap.set_params({"LAND_SPEED": 100, "TKOFF_SLEW_TIME": 0})
    quick = _takeoff_and_land(bench, 4.0)
    assert 1.9 < base[0] - quick[0] < 2.1  # the 2 s slew is gone
    assert 3.5 < base[1] - quick[1] < 4.0  # 4 m at 1 m/s instead of 0.5 m/s
    high = Bench()
    high.ap.set_params({"LAND_ALT_LOW": 200})  # above 2 m: WPNAV_SPEED_DN (1.5 m/s)
    assert _takeoff_and_land(high, 10.0)[1] < _takeoff_and_land(Bench(), 10.0)[1] - 8
    with pytest.raises(KeyError):
        bench.ap.set_params({"NO_SUCH": 1})


def test_param_option_rejects_unknown_names() -> None:
    proc = subprocess.run([sys.executable, "-c", RUN, "--no-camera", "--param", "NO_SUCH=1"],
                          cwd=ROOT, capture_output=True, text=True, timeout=20)
    assert proc.returncode == 2
    assert proc.stderr.startswith("hfsmc: error: --param NO_SUCH: no such parameter")


def test_world_clock_armed_holds_the_objects_until_arming(tmp_path: Path) -> None:
    """By default (and with --world-clock armed) nobody arms, so the object waits; with
    --world-clock start it has moved."""
    world = tmp_path / "moving.yaml"
    world.write_text("objects:\n  - {name: g, color: [0, 200, 0], speed: 1.0, "
                     "path: [[0, 0], [30, 0]]}\n")
    where = {}
    for clock in ("armed", None, "start"):
        truth = tmp_path / f"truth-{clock}.json"
        args = ["--world-clock", clock] if clock else []
        proc = subprocess.run([sys.executable, "-c", RUN, "--no-camera", "--world", str(world),
                               "--mavlink", f"udpout:127.0.0.1:{free_port(socket.SOCK_DGRAM)}",
                               "--duration", "1.5", "--truth", str(truth), *args],
                              cwd=ROOT, capture_output=True, text=True, timeout=30)
        assert proc.returncode == 0, proc.stderr
        where[clock] = json.loads(truth.read_text())["objects"][0]["north"]
    assert where == {"armed": 0.0, None: 0.0, "start": 1.5}


# -- the link obeys its peer only ------------------------------------------------------------------
def armed(hb: Any) -> bool:
    return bool(hb.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED)


def test_only_the_peer_commands_the_vehicle(sims: Callable[..., Sim]) -> None:
    """With udpout the vehicle obeys the address it sends to: another local process that
    writes to its socket cannot change the mode, arm or take off (docs/worlds.md)."""
    sim = sims()
    sim.wait_ready()
    (vehicle,) = sim.gs.clients  # the simulator's own socket, where replies go
    stranger = mavutil.mavlink_connection(f"udpout:{vehicle[0]}:{vehicle[1]}",
                                          source_system=255, dialect="ardupilotmega")
    try:
        for _ in range(3):
            stranger.mav.set_mode_send(1, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)
            stranger.mav.command_long_send(1, 1, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                           1, 0, 0, 0, 0, 0, 0)
            stranger.mav.command_long_send(1, 1, ML.MAV_CMD_NAV_TAKEOFF, 0,
                                           0, 0, 0, 0, 0, 0, 5)
            time.sleep(0.2)
        beats = sim.collect("HEARTBEAT", 1.5)
        assert beats and not any(armed(hb) or hb.custom_mode == GUIDED for hb in beats)
        assert stranger.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.5) is None
        assert sim.latest("GLOBAL_POSITION_INT").relative_alt < 200
        stranger_port = stranger.port.getsockname()[1]
    finally:
        stranger.close()
    # The peer does.
    assert sim.set_mode(GUIDED) == ML.MAV_RESULT_ACCEPTED
    assert sim.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ML.MAV_RESULT_ACCEPTED
    status, err = sim.close()
    assert status == 0
    said = (f"ignoring MAVLink from 127.0.0.1:{stranger_port}: the vehicle obeys its peer "
            f"127.0.0.1:{sim.port} only")
    assert err.count(said) == 1, err
    assert re.search(r"ignored (\d+) MAVLink datagrams from other addresses than the peer", err)


def test_udpin_obeys_the_first_address_until_it_falls_silent(tmp_path: Path) -> None:
    """With udpin the first address that writes is the peer; another is ignored until the
    peer has been silent for PEER_QUIET_S, then takes over (a restarted ground station)."""
    from hfsmc.sim.run import PEER_QUIET_S

    port = free_port(socket.SOCK_DGRAM)
    err = tmp_path / "sim.err"
    with open(err, "w") as e:
        proc = subprocess.Popen([sys.executable, "-c", RUN, "--mavlink", f"udpin:127.0.0.1:{port}",
                                 "--no-camera", "--boot-time", "0.3"], cwd=ROOT, stderr=e)
    first = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255,
                                       dialect="ardupilotmega")
    second = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=254,
                                        dialect="ardupilotmega")
    try:
        def beat(gs: Any) -> None:
            gs.mav.heartbeat_send(ML.MAV_TYPE_GCS, ML.MAV_AUTOPILOT_INVALID, 0, 0, 0)

        deadline = time.monotonic() + 10
        while first.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2) is None:
            assert time.monotonic() < deadline and proc.poll() is None, err.read_text()
            beat(first)
        # The second writes (and asks to arm) while the first is alive: ignored, and not told.
        for _ in range(5):
            beat(first)
            beat(second)
            second.mav.command_long_send(1, 1, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                         1, 0, 0, 0, 0, 0, 0)
            time.sleep(0.2)
        assert second.recv_match(blocking=True, timeout=0.5) is None
        assert not armed(first.recv_match(type="HEARTBEAT", blocking=True, timeout=3))
        # The first falls silent: after PEER_QUIET_S the second is the peer.
        deadline = time.monotonic() + PEER_QUIET_S + 10
        while second.recv_match(type="HEARTBEAT", blocking=True, timeout=0.3) is None:
            assert time.monotonic() < deadline, err.read_text()
            beat(second)
        first_port, second_port = (c.port.getsockname()[1] for c in (first, second))
        text = err.read_text()
        assert text.count(f"ignoring MAVLink from 127.0.0.1:{second_port}: the vehicle obeys "
                          f"its peer 127.0.0.1:{first_port} only") == 1, text
        assert (f"MAVLink peer is now 127.0.0.1:{second_port} (127.0.0.1:{first_port} silent "
                f"for {PEER_QUIET_S:g} s)") in text
    finally:
        first.close()
        second.close()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0
