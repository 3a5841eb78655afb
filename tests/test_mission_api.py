"""The mission API of the mavlink interface (docs/interfaces.md, "Missions"), flown by the
Python driver against `hfsmc sim` as ArduPilot and as PX4: goto by latitude and longitude
with a heading, set_yaw, distance_to / reached, home(), RTL at an altitude, the
autopilot's STATUSTEXT, the battery failsafe; bad input refused before anything is sent.
The simulator's battery failsafe is stepped by hand (simulated time only)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from hfsmc.sim import failsafe, px4
from hfsmc.sim.autopilot import LAND, RTL, Autopilot, parse_datagram
from hfsmc.sim.telemetry import latlon
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World
from tests.support import python_vehicle, until_snapshot

pytestmark = pytest.mark.timeout(240)
AUTOPILOTS = ("ardupilot", "px4")


@pytest.fixture(params=AUTOPILOTS)
def vehicle(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[Any, str]]:
    """The Python driver (templates/python) on a simulator in real time."""
    with python_vehicle(tmp_path, request.param, "4") as v:
        yield v, request.param


_until = until_snapshot


def _heading_error(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def test_goto_location_heading_yaw_home_rtl_and_texts(vehicle: tuple[Any, str],
                                                      capfd: pytest.CaptureFixture[str]) -> None:
    v, autopilot = vehicle
    home = World().home
    assert _until(v, lambda: v.ready() and not math.isnan(v.home()[0]), 30)
    assert v.home() == pytest.approx((home.lat, home.lon, home.alt), abs=1e-6)
    assert v.battery_failsafe() == ""
    assert v.status_text() in ("Ready for takeoff!", "EKF3 IMU0 is using GPS")
    v.set_mode("GUIDED")
    v.arm()
    v.takeoff(5.0)
    assert _until(v, lambda: v.altitude() > 4.5, 40)
    lat, lon = (x / 1e7 for x in latlon(home, 12.0, 9.0))  # 15 m away
    assert v.distance_to_location(lat, lon) == pytest.approx(15.0, abs=0.5)
    v.goto_location(lat, lon, 7.0, math.pi / 2)
    assert _until(v, lambda: v.reached_location(lat, lon, 7.0, 0.5), 40)
    # The same point in local metres: the conversions differ by centimetres, so the first
    # instant within 0.5 m of one may be just outside the other; the flight settles.
    assert _until(v, lambda: v.reached(12.0, 9.0, 7.0, tolerance=0.5), 10)
    assert v.distance_to(12.0, 9.0) < 0.5 and v.location()[2] == pytest.approx(7.0, abs=0.5)
    assert _until(v, lambda: _heading_error(v.yaw(), math.pi / 2) < 0.05, 10)
    v.set_yaw(math.pi)  # turns where it is going: the target stays
    assert _until(v, lambda: _heading_error(v.yaw(), math.pi) < 0.05, 10)
    assert v.reached(12.0, 9.0, 7.0, tolerance=0.5)
    v.goto(12.0, 9.0, 7.0, heading=-math.pi / 2)
    assert _until(v, lambda: _heading_error(v.yaw(), -math.pi / 2) < 0.05, 10)
    for bad, message in (((91.0, lon, 5.0), "latitude 91 is out of range"),
                         ((lat, -190.0, 5.0), "longitude -190 is out of range"),
                         ((lat, lon, math.inf), "altitude inf m is not a finite number")):
        with pytest.raises(ValueError, match=message):
            v.goto_location(*bad)
    with pytest.raises(ValueError, match="rtl altitude -3 m is not above home"):
        v.rtl(-3.0)
    v.rtl(12.0)
    assert _until(v, lambda: v.mode() == "RTL", 5)
    assert _until(v, lambda: v.altitude() > 11.5, 30)
    assert v.distance_to(12.0, 9.0) < 3.0  # it climbs first, where it was
    assert _until(v, lambda: not v.armed(), 120)
    assert v.distance_to(0.0, 0.0) < 1.0
    err = capfd.readouterr().err
    name = "RTL_RETURN_ALT set to 12" if autopilot == "px4" else "RTL_ALT set to 1200"
    assert f"drone: rtl: {name}" in err


class Bench:
    """An autopilot and its body in this process, stepped by hand."""

    def __init__(self, cls: type[Autopilot], battery_wh: float, **params: float) -> None:
        world = dataclasses.replace(World(), seed=3)
        world = dataclasses.replace(world, vehicle=dataclasses.replace(world.vehicle,
                                                                       battery_wh=battery_wh))
        self.body = Body(world.vehicle, world.seed)
        self.sent: list[Any] = []
        self.ap = cls(world, self.body, lambda d: self.sent.extend(parse_datagram(d)),
                      boot_time=1.0)
        self.ap.set_params(params)

    def fly_until(self, cond: Callable[[], bool], limit: float) -> None:
        b = self.body
        while not cond():
            assert b.t < limit, f"not within {limit} s"
            if self.ap.ready and not b.armed and b.landed and self.ap.takeoffs == 0:
                if isinstance(self.ap, px4.Px4):
                    b.armed = True
                    self.ap._takeoff(10.0)
                else:
                    self.ap.set_mode(4)
                    b.armed = True
                    self.ap._cmd_takeoff((0, 0, 0, 0, 0, 0, 10.0))
            self.ap.step()

    def texts(self) -> list[str]:
        return [m.text for m in self.sent if m.get_type() == "STATUSTEXT"]

    def charge(self) -> int:
        self.ap.telemetry.send("BATTERY_STATUS")
        return int(next(m for m in reversed(self.sent)
                        if m.get_type() == "BATTERY_STATUS").charge_state)


@pytest.mark.parametrize(("cls", "params", "mode"), [
    (Autopilot, {"BATT_FS_LOW_ACT": 2, "BATT_FS_CRT_ACT": 1}, RTL),
    (px4.Px4, {"COM_LOW_BAT_ACT": 3}, px4.RTL)])
def test_the_battery_failsafe_is_reported_and_acted_on(cls: type[Autopilot],
                                                       params: dict[str, float],
                                                       mode: int) -> None:
    """A small pack drains in the air: low, then critical, each said once, reported in
    BATTERY_STATUS.charge_state, and the failsafe's mode flown as the parameters say."""
    bench = Bench(cls, 1.0, **params)  # 1 Wh: a few seconds of hover
    assert bench.charge() == failsafe.CHARGE_STATE[failsafe.OK]
    bench.fly_until(lambda: bench.ap.battery_level >= failsafe.LOW, 120)
    assert bench.charge() == failsafe.CHARGE_STATE[failsafe.LOW]
    bench.fly_until(lambda: bench.ap.battery_level >= failsafe.CRITICAL, 120)
    assert bench.charge() == failsafe.CHARGE_STATE[failsafe.CRITICAL]
    bench.ap.step()
    assert bench.ap.mode in (mode, LAND, px4.LAND)
    texts = bench.texts()
    low = "Battery 1 is low" if cls is Autopilot else "Low battery level! Return advised"
    assert texts.count(low) == 1, texts


def test_no_failsafe_action_by_default_only_the_report() -> None:
    """ArduPilot's BATT_FS_*_ACT default to 0: the level is reported, the mode kept."""
    bench = Bench(Autopilot, 1.0)
    bench.fly_until(lambda: bench.ap.battery_level >= failsafe.LOW, 120)
    assert bench.ap.mode == 4 and "Battery 1 is low" in bench.texts()
