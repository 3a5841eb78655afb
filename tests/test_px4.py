"""`hfsmc sim --autopilot px4`: the simulator answers as PX4 v1.16 (SIH quadrotor) does.

The figures are those the project measured on PX4 v1.16.0 SITL (issue 29; docs/worlds.md,
"PX4"). Most tests step the autopilot in this process (simulated time only); one starts
the simulator to see its link as a ground station does.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as v20

from hfsmc.sim import px4
from hfsmc.sim.autopilot import parse_datagram
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World
from tests import test_missions
from tests.support import flight, free_port, wait_until

ROOT = Path(__file__).resolve().parent.parent
RUN = "import sys; from hfsmc.sim.run import main; sys.exit(main(sys.argv[1:]))"
M = v20
VELOCITY = 0b0000_1101_1100_0111  # vx vy vz only (yaw and yaw rate ignored)
ACCEPTED, TEMP_REJECTED = M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_TEMPORARILY_REJECTED


class Bench:
    """A PX4 autopilot and its body in this process, stepped by hand."""

    def __init__(self, **params: float) -> None:
        self.world = dataclasses.replace(World(), seed=3)
        self.body = Body(self.world.vehicle, self.world.seed)
        self.sent: list[Any] = []
        self.ap = px4.Px4(self.world, self.body, lambda d: self.sent.extend(parse_datagram(d)))
        self.ap.set_params(params)
        self.gcs = v20.MAVLink(None, 255, 190)

    def send(self, msg: Any) -> None:
        self.ap.receive(msg.pack(self.gcs))

    def command(self, cmd: int, *params: float) -> None:
        p = [*params, *[0.0] * (7 - len(params))]
        self.send(self.gcs.command_long_encode(1, 1, cmd, 0, *p))

    def set_mode(self, main: int, sub: int = 0) -> None:
        self.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub)

    def setpoint(self, vn: float = 0.0, ve: float = 0.0, vd: float = 0.0) -> None:
        self.send(self.gcs.set_position_target_local_ned_encode(
            0, 1, 1, M.MAV_FRAME_LOCAL_NED, VELOCITY, 0, 0, 0, vn, ve, vd, 0, 0, 0, 0, 0))

    def run(self, seconds: float, each: Callable[[], None] | None = None) -> None:
        for i in range(round(seconds / self.body.dt)):
            if each is not None and i % 5 == 0:  # 10 Hz
                each()
            self.ap.step()

    def run_until(self, cond: Callable[[], bool], limit: float) -> float:
        start = self.body.t
        while not cond():
            assert self.body.t - start < limit, "not within the time limit"
            self.ap.step()
        return self.body.t - start

    def acks(self, command: int) -> list[int]:
        return [m.result for m in self.sent if m.get_type() == "COMMAND_ACK"
                and m.command == command]

    def texts(self) -> list[Any]:
        return [m for m in self.sent if m.get_type() == "STATUSTEXT"]

    def take_off(self, alt: float = 5.0) -> float:
        """Arm and take off (altitude AMSL, as PX4 wants it); seconds to 95 % of ``alt``."""
        self.run_until(lambda: self.ap.ready, 10)
        self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        self.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, self.world.home.alt + alt)
        took = self.run_until(lambda: self.body.altitude >= 0.95 * alt, 30)
        self.run_until(lambda: self.ap.mode == px4.HOLD, 10)
        self.run(3)  # Hold goes on to the take-off's altitude
        return took


def test_link_sends_from_18570_mavlink2_autopilot_px4(tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as gcs:
        gcs.bind(("127.0.0.1", port))
        gcs.settimeout(10)
        proc = subprocess.Popen([sys.executable, "-c", RUN, "--autopilot", "px4", "--no-camera",
                                 "--mavlink", f"udpout:127.0.0.1:{port}", "--duration", "30"],
                                cwd=ROOT, stderr=subprocess.PIPE)
        try:
            data, addr = gcs.recvfrom(65535)
            heartbeat = None
            while heartbeat is None:
                assert data[0] == 0xFD  # MAVLink 2
                heartbeat = next((m for m in parse_datagram(data)
                                  if m.get_type() == "HEARTBEAT"), None)
                if heartbeat is None:
                    data, addr = gcs.recvfrom(65535)
        finally:
            proc.terminate()
            _, err = proc.communicate(timeout=10)
    assert addr == ("127.0.0.1", px4.SOURCE_PORT)
    assert heartbeat.autopilot == M.MAV_AUTOPILOT_PX4 == 12
    assert heartbeat.custom_mode == px4.HOLD == 0x03040000
    assert proc.returncode == 0 and b"from port 18570" in err


def test_about_366_messages_a_second_seven_streams_at_50hz() -> None:
    bench = Bench()
    bench.run(10)
    rate = len(bench.sent) / 10
    assert 330 < rate < 400, rate
    counts: dict[str, int] = {}
    for m in bench.sent:
        counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
    assert sum(1 for n in counts.values() if n >= 490) == 7, counts
    assert "EKF_STATUS_REPORT" not in counts  # ArduPilot's, not PX4's


def test_arming_refused_before_the_checks_pass_with_a_two_chunk_text() -> None:
    bench = Bench()
    bench.run(1)
    bench.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert bench.acks(M.MAV_CMD_COMPONENT_ARM_DISARM) == [TEMP_REJECTED]
    chunks = [t for t in bench.texts() if t.id]
    assert [c.chunk_seq for c in chunks] == [0, 1] and chunks[0].id == chunks[1].id
    assert "".join(c.text for c in chunks) == px4.ARMING_TEXT
    took = bench.run_until(lambda: bench.ap.ready, 10)
    assert abs(1 + took - 4.5) < 0.05
    bench.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert bench.acks(M.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == ACCEPTED and bench.body.armed


def test_do_set_mode_is_answered_twice_the_second_time_for_real() -> None:
    bench = Bench()
    bench.take_off()
    bench.sent.clear()
    bench.set_mode(6)  # OFFBOARD in the air without setpoints: refused, but ACCEPTED first
    bench.run(0.1)
    assert bench.acks(M.MAV_CMD_DO_SET_MODE) == [ACCEPTED, TEMP_REJECTED]
    assert bench.ap.mode == px4.HOLD
    bench.sent.clear()
    bench.set_mode(3)  # POSCTL: accepted twice
    bench.run(0.1)
    assert bench.acks(M.MAV_CMD_DO_SET_MODE) == [ACCEPTED, ACCEPTED]
    bench.run(1.1)
    heartbeat = [m for m in bench.sent if m.get_type() == "HEARTBEAT"]
    assert heartbeat[-1].custom_mode == px4.POSCTL == 0x00030000


def test_offboard_needs_a_stream_and_its_loss_is_a_failsafe_to_posctl() -> None:
    bench = Bench()
    bench.take_off()
    bench.setpoint(0, 0, 0)
    bench.set_mode(6)  # with the first setpoint: refused
    bench.run(0.6, bench.setpoint)
    assert bench.acks(M.MAV_CMD_DO_SET_MODE)[-1] == TEMP_REJECTED
    bench.set_mode(6)  # 0.6 s of stream later: accepted
    bench.run(0.1, lambda: bench.setpoint(1.0, 0, 0))
    assert bench.acks(M.MAV_CMD_DO_SET_MODE)[-2:] == [ACCEPTED, ACCEPTED]
    assert bench.ap.mode == px4.OFFBOARD
    bench.run(3, lambda: bench.setpoint(1.0, 0, 0))
    assert bench.body.vn > 0.9  # flies the setpoint, held as long as the stream goes on
    alt = bench.body.altitude
    took = bench.run_until(lambda: bench.ap.mode != px4.OFFBOARD, 5)  # the stream stops
    assert 1.2 <= took <= 1.6 and bench.ap.mode == px4.POSCTL
    assert any("no offboard signal" in t.text for t in bench.texts())
    bench.run(4)
    assert abs(bench.body.vd - px4.SINK) < 0.05 and bench.body.altitude < alt - 2.0


def test_offboard_loss_holds_with_com_obl_rc_act_5() -> None:
    bench = Bench(COM_OBL_RC_ACT=5)
    bench.take_off()
    bench.run(0.7, bench.setpoint)
    bench.set_mode(6)
    bench.run(0.2, bench.setpoint)
    assert bench.ap.mode == px4.OFFBOARD
    bench.run(3)
    assert bench.ap.mode == px4.HOLD
    alt = bench.body.altitude
    bench.run(4)
    assert abs(bench.body.altitude - alt) < 0.1


def test_offboard_on_the_ground_without_setpoints_then_no_arming() -> None:
    bench = Bench()
    bench.run_until(lambda: bench.ap.ready, 10)
    bench.set_mode(6)
    bench.run(0.1)
    assert bench.acks(M.MAV_CMD_DO_SET_MODE) == [ACCEPTED, ACCEPTED]
    assert bench.ap.mode == px4.OFFBOARD
    for _ in range(3):
        bench.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        bench.run(1)
    assert bench.acks(M.MAV_CMD_COMPONENT_ARM_DISARM) == [TEMP_REJECTED] * 3
    assert not bench.body.armed


# PX4 v1.16.0 SITL (SIH), issue 29: 95 % of 5 m 8-11 s after NAV_TAKEOFF; from 4.6 m,
# on the ground ~14.8 s after NAV_LAND, disarmed 2.0 s later (COM_DISARM_LAND).
PX4_TAKEOFF_S, PX4_LANDED_S, PX4_DISARM_S = 9.5, 14.8, 2.0


def test_takeoff_and_landing_profiles_within_15_percent() -> None:
    bench = Bench()
    took = bench.take_off(5.0)
    assert abs(took / PX4_TAKEOFF_S - 1) < 0.15, took
    assert abs(bench.body.altitude - 5.0) < 0.05  # Hold at the take-off's altitude
    climb = max(-m.vz / 100 for m in bench.sent if m.get_type() == "GLOBAL_POSITION_INT")
    assert 1.1 < climb < 1.45, climb
    bench.set_mode(3)  # POSCTL: sinks, to start the landing at 4.6 m
    bench.run_until(lambda: bench.body.altitude < 4.6, 5)
    bench.set_mode(4, 3)
    bench.run(2)
    assert bench.ap.mode == px4.HOLD
    bench.command(M.MAV_CMD_NAV_LAND)
    assert bench.ap.mode == px4.LAND
    landed = bench.run_until(lambda: bench.ap.detected_landed, 40)
    assert abs(landed / PX4_LANDED_S - 1) < 0.15, landed
    disarmed = bench.run_until(lambda: not bench.body.armed, 10)
    assert abs(disarmed - PX4_DISARM_S) < 0.05
    assert bench.ap.mode == px4.HOLD  # back to the mode chosen before LAND


def test_armed_on_the_ground_disarms_after_about_11_s() -> None:
    bench = Bench()
    bench.run_until(lambda: bench.ap.ready, 10)
    bench.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    took = bench.run_until(lambda: not bench.body.armed, 20)
    assert abs(took - 11.0) < 0.2, took


def test_takeoff_altitude_is_amsl_and_nan_means_mis_takeoff_alt() -> None:
    bench = Bench()
    bench.run_until(lambda: bench.ap.ready, 10)
    bench.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    bench.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, math.nan)
    bench.run_until(lambda: bench.ap.mode == px4.HOLD, 20)
    bench.run(3)
    assert abs(bench.body.altitude - 2.5) < 0.05


def test_unknown_px4_param_is_refused_by_the_command_line() -> None:
    proc = subprocess.run([sys.executable, "-c", RUN, "--autopilot", "px4", "--no-camera",
                           "--param", "LAND_SPEED=50"], cwd=ROOT, capture_output=True,
                          text=True, timeout=20)
    assert proc.returncode == 2
    assert proc.stderr.startswith("hfsmc: error: --param LAND_SPEED: no such parameter (px4 knows")


@pytest.mark.parametrize("main,sub", [(9, 0), (4, 9)])
def test_a_mode_px4_lacks_is_denied(main: int, sub: int) -> None:
    bench = Bench()
    bench.run_until(lambda: bench.ap.ready, 10)
    bench.set_mode(main, sub)
    bench.run(0.1)
    assert bench.acks(M.MAV_CMD_DO_SET_MODE) == [ACCEPTED, M.MAV_RESULT_DENIED]
    assert bench.ap.mode == px4.HOLD


cpp_follow_colors = test_missions.cpp_follow_colors  # the fixture: follow_colors_cpp compiled


def fly_px4(tmp_path: Path, command: list[str] | None = None) -> tuple[Path, str]:
    """follow_colors (Python, or ``command``) against the PX4 simulator in lockstep: the
    flight's folder and the component's log, once it ended with status 0."""
    with flight(tmp_path, "--autopilot", "px4", "--source-port", "0", command=command,
                lockstep=True) as f:
        status = f.component.wait(timeout=900)  # PX4's 366 messages/s, on a shared machine
        f.sim.wait(timeout=30)
        log = (f.folder / "component.log").read_text()
        assert status == 0, log[-3000:]
    return f.folder, log


@pytest.mark.slow
@pytest.mark.parametrize("language", ["python", pytest.param(
    "cpp", marks=pytest.mark.timeout(test_missions.CPP_BUILD_TIMEOUT + 900))])
def test_follow_colors_flies_unchanged_on_px4_in_lockstep(
        tmp_path: Path, language: str, request: pytest.FixtureRequest) -> None:
    """The ArduPilot mission, not a line changed, against the PX4 simulator (Python, and
    follow_colors_cpp with the C++ driver)."""
    command = request.getfixturevalue("cpp_follow_colors") if language == "cpp" else None
    folder, log = fly_px4(tmp_path, command)
    report = json.loads((folder / "report.json").read_text())
    assert report["stages"] == ["green", "blue", "green", "red"], log[-3000:]
    truth = json.loads((folder / "truth.json").read_text())
    assert truth["armed"] is False and truth["landed"] is True
    red = next(o for o in truth["objects"] if o["name"] == "red")
    landing = truth["landing"]
    assert math.dist((landing["north"], landing["east"]), (red["north"], red["east"])) < 1.0
    assert "drone: PX4 vehicle 1/1" in log
    assert "drone: PX4: setpoints streaming: switching to OFFBOARD" in log
    assert "drone: set_mode GUIDED (OFFBOARD) accepted" in log
    assert "drone: PX4: GUIDED on the ground is Hold" in log


@pytest.mark.slow
@pytest.mark.timeout(test_missions.CPP_BUILD_TIMEOUT + 900)
def test_python_and_cpp_fly_the_same_trace_on_px4_in_lockstep(
        tmp_path: Path, cpp_follow_colors: list[str]) -> None:
    """Both drivers send PX4 the same datagrams at the same simulated instants (the
    setpoint stream, the OFFBOARD switch): the same trace, the same truth, the same lines."""
    py, py_log = fly_px4(tmp_path / "python")
    cpp, cpp_log = fly_px4(tmp_path / "cpp", cpp_follow_colors)
    py_trace = (py / "trace.jsonl").read_text().replace(str(py), "DIR")
    cpp_trace = (cpp / "trace.jsonl").read_text().replace(str(cpp), "DIR") \
        .replace("follow_colors_cpp", "follow_colors")
    assert cpp_trace == py_trace
    assert (cpp / "truth.json").read_bytes() == (py / "truth.json").read_bytes()

    def said(log: str) -> list[str]:  # the driver's lines, ports taken out
        return [re.sub(r"127\.0\.0\.1:\d+", "PORT", line) for line in log.splitlines()
                if line.startswith("drone: ")]
    assert said(cpp_log) == said(py_log)


@pytest.fixture
def px4_vehicle(tmp_path: Path) -> Any:
    """The Python driver (from templates/python) on a PX4 simulator in real time."""
    sys.path.insert(0, str(ROOT / "templates" / "python"))
    import hfsmc_mavlink  # type: ignore[import-not-found]
    port = free_port(socket.SOCK_DGRAM)
    log = (tmp_path / "sim.log").open("wb")
    sim = subprocess.Popen([sys.executable, "-c", RUN, "--autopilot", "px4", "--no-camera",
                            "--source-port", "0", "--boot-time", "1",
                            "--mavlink", f"udpout:127.0.0.1:{port}"],
                           cwd=ROOT, stderr=log)
    vehicle = hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {})
    try:
        yield vehicle, sim
    finally:
        vehicle.close()
        sim.terminate()
        sim.wait(timeout=20)
        log.close()
        sys.path.remove(str(ROOT / "templates" / "python"))


def _until(vehicle: Any, cond: Callable[[dict[str, Any]], bool], timeout: float) -> bool:
    return wait_until(lambda: cond(vehicle.snapshot()), timeout, 0.05)


def test_driver_keeps_the_stream_up_and_never_fights_the_failsafe(
        px4_vehicle: Any, capfd: pytest.CaptureFixture[str]) -> None:
    """A target set once flies in OFFBOARD (the driver streams it); when the link drops, PX4's
    failsafe takes the vehicle to POSCTL, and the driver, once the link is back, leaves it
    there and says so."""
    vehicle, sim = px4_vehicle
    assert _until(vehicle, lambda s: s["ready"], 20)
    vehicle.set_mode("GUIDED")
    vehicle.arm()
    vehicle.takeoff(3.0)
    assert _until(vehicle, lambda s: s["mode"] == "HOLD" and s["altitude"] > 2.8, 30)
    vehicle.set_velocity(1.0, 0.0, 0.0, 0.0)  # once
    assert _until(vehicle, lambda s: s["mode"] == "GUIDED" and s["velocity"][0] > 0.8, 10)
    time.sleep(2.0)  # far longer than PX4's COM_OF_LOSS_T: the driver's thread streams
    assert _until(vehicle, lambda s: s["mode"] == "GUIDED", 1)
    sim.send_signal(signal.SIGUSR1)  # the link drops: no setpoint reaches PX4
    time.sleep(3.0)
    sim.send_signal(signal.SIGUSR1)
    assert _until(vehicle, lambda s: s["heartbeat_age"] < 1.0 and s["mode"] == "POSCTL", 10)
    time.sleep(2.0)
    assert vehicle.snapshot()["mode"] == "POSCTL"  # not taken back
    err = capfd.readouterr().err
    assert "drone: PX4 left OFFBOARD for POSCTL (a failsafe or a pilot)" in err
    with pytest.raises(ValueError, match="PX4 has no mode `BRAKE`"):
        vehicle.set_mode("BRAKE")
    vehicle.land()
    assert _until(vehicle, lambda s: s["mode"] == "LAND", 5)


mission = test_missions.mission  # follow_colors to fly, by language


@pytest.mark.slow
@pytest.mark.parametrize("mission", test_missions.LANGUAGES, indirect=True)
def test_stop_paths_end_landed_and_disarmed_on_px4(tmp_path: Path,
                                                   mission: list[str] | None) -> None:
    """Issue 29 item 5 on PX4, both languages: --time-limit and Ctrl+C both go through
    on_interrupt to Land (NAV_LAND, PX4's AUTO.LAND): the vehicle is on the ground and
    disarmed (PX4's COM_DISARM_LAND) when the component stops, nothing left armed."""
    px4_args = ("--autopilot", "px4", "--source-port", "0")
    with flight(tmp_path / "limit", *px4_args, command=mission, lockstep=True,
                component_args=("--time-limit", "30s")) as f:
        status = f.component.wait(timeout=300)
        f.sim.wait(timeout=30)
        log = (f.folder / "component.log").read_text()
        assert status == 124, log[-3000:]
        truth = f.truth()
    assert [r for r in f.trace if r["ev"] == "interrupt"] == [
        {"t": 30000, "ev": "interrupt", "reason": "time_limit", "to": "Land"}]
    assert [r["state"] for r in f.trace if r["ev"] == "enter"][-4:] == [
        "Land", "Land/Landing", "Land/Landed", "Done"]
    assert truth["armed"] is False and truth["landed"] is True, truth
    assert "WARNING: ARMED" not in log and "drone: land accepted" in log
    with flight(tmp_path / "sigint", *px4_args, "--speedup", "5", command=mission,
                lockstep=True) as f:
        f.wait_for("enter", "state", "Mission/FollowGreen/Track", timeout=120)
        time.sleep(0.4)
        f.component.send_signal(signal.SIGINT)
        status = f.component.wait(timeout=300)
        f.sim.wait(timeout=30)
        log = (f.folder / "component.log").read_text()
        assert status == 130, log[-3000:]
        truth = f.truth()
    events = [(r["ev"], r.get("to") or r.get("state")) for r in f.trace]
    assert ("interrupt", "Land") in events and f.trace[-1]["reason"] == "sigint"
    assert truth["armed"] is False and truth["landed"] is True, truth
    assert "WARNING: ARMED" not in log
