"""The mission side of the ``mavlink`` interface (docs/interfaces.md, "Missions"): copied
beside a component with hfsmc_mavlink.py, the same on ArduPilot and PX4.

- Geography: latitudes and longitudes in degrees (WGS84), checked before anything is
  sent; distances on a local flat earth around the points (an error under 0.1 % within
  10 km, far below GPS's), as the autopilots themselves compute them for waypoints.
- Targets by latitude and longitude: SET_POSITION_TARGET_GLOBAL_INT in
  MAV_FRAME_GLOBAL_RELATIVE_ALT_INT (altitude above home, as ``takeoff`` and
  ``altitude()``), with a heading when one is given.
- RTL's altitude: a PARAM_SET before the RTL command (ArduPilot's RTL_ALT in cm, PX4's
  RTL_RETURN_ALT in m).
- What the autopilot says (STATUSTEXT, chunks joined), its home (HOME_POSITION) and its
  battery failsafe (BATTERY_STATUS.charge_state) are kept for the snapshot.
"""

from __future__ import annotations

import math
from typing import Any

EARTH_RADIUS = 6378137.0  # m, WGS84's equatorial radius (the simulator's too)
DEFAULT_TOLERANCE = 1.0  # m: reached() within this
MAX_TARGET = 1e5  # m: a target further than this from home is refused (a typo, not a goal)
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
IGNORE_VELOCITY_ACCELERATION = 0b0001_1111_1000  # vx vy vz afx afy afz
IGNORE_YAW = 0b0100_0000_0000
IGNORE_YAW_RATE = 0b1000_0000_0000
MAV_PARAM_TYPE_REAL32 = 9
MAV_PARAM_TYPE_INT16 = 4
# BATTERY_STATUS.charge_state (MAV_BATTERY_CHARGE_STATE) -> battery_failsafe()
CHARGE_STATES = {2: "low", 3: "critical", 4: "emergency", 5: "failed", 6: "unhealthy"}
NAN3 = (math.nan, math.nan, math.nan)


def checked_location(vehicle: str, lat: Any, lon: Any, alt: Any) -> tuple[float, float, float]:
    """(lat, lon, alt) as floats; ValueError saying which is out of range."""
    try:
        la, lo, al = float(lat), float(lon), float(alt)
    except (TypeError, ValueError):
        raise ValueError(f"{vehicle}: a location is three numbers (lat, lon, alt), not "
                         f"({lat!r}, {lon!r}, {alt!r})") from None
    if not -90.0 <= la <= 90.0:
        raise ValueError(f"{vehicle}: latitude {la:g} is out of range -90..90 (degrees)")
    if not -180.0 <= lo <= 180.0:
        raise ValueError(f"{vehicle}: longitude {lo:g} is out of range -180..180 (degrees)")
    if not math.isfinite(al) or abs(al) > MAX_TARGET:
        raise ValueError(f"{vehicle}: altitude {al:g} m is not a finite number within "
                         f"{MAX_TARGET:g} m")
    return la, lo, al


def checked_heading(vehicle: str, heading: Any) -> float | None:
    """A heading in rad, or None (none given, or NaN); ValueError for anything else."""
    if heading is None:
        return None
    try:
        h = float(heading)
    except (TypeError, ValueError):
        raise ValueError(f"{vehicle}: a heading is a number in rad, not {heading!r}") from None
    if math.isnan(h):
        return None
    if math.isinf(h):
        raise ValueError(f"{vehicle}: heading {h} is not finite")
    return h


def offset(lat1: float, lon1: float, lat2: float, lon2: float) -> tuple[float, float]:
    """North and east (m) from the first point to the second (local flat earth)."""
    north = math.radians(lat2 - lat1) * EARTH_RADIUS
    dlon = (lon2 - lon1 + 180.0) % 360.0 - 180.0  # across the antimeridian the short way
    east = math.radians(dlon) * EARTH_RADIUS * math.cos(math.radians((lat1 + lat2) / 2))
    return north, east


def distance(here: tuple[float, float, float], there: tuple[float, float, float | None]
             ) -> float:
    """Metres between two (lat, lon, alt) points; horizontal when ``there`` has no alt."""
    north, east = offset(here[0], here[1], there[0], there[1])
    if there[2] is None:
        return math.hypot(north, east)
    return math.sqrt(north * north + east * east + (there[2] - here[2]) ** 2)


def local_distance(position: tuple[float, float, float], altitude: float, north: float,
                   east: float, alt: float | None) -> float:
    """Metres from a local position (NED, and altitude above home) to a point."""
    dn, de = float(north) - position[0], float(east) - position[1]
    if alt is None:
        return math.hypot(dn, de)
    return math.sqrt(dn * dn + de * de + (float(alt) - altitude) ** 2)


class MissionVehicle:
    """The live side of the mission API, mixed into hfsmc_mavlink.Vehicle (its attributes
    are the vehicle's: ``_conn``, ``_lock``, ``_target``, ``_say``...)."""

    _conn: Any
    _lock: Any
    _target: tuple[int, int] | None
    _start: float
    _px4: bool
    now: Any
    _say: Any
    _texts: Any

    def _mission_init(self) -> None:
        self._home: tuple[float, float, float] = NAN3
        self._location: tuple[float, float, float] = NAN3
        self._charge = ""
        self._text = ""

    def _send_global(self, lat: float, lon: float, alt: float, heading: float | None) -> None:
        """A SET_POSITION_TARGET_GLOBAL_INT (altitude above home)."""
        target = self._target
        if target is None:
            return
        mask = IGNORE_VELOCITY_ACCELERATION | IGNORE_YAW_RATE | (
            IGNORE_YAW if heading is None else 0)
        boot_ms = int((self.now() - self._start) * 1000) & 0xFFFFFFFF
        with self._lock:
            self._conn.mav.set_position_target_global_int_send(
                boot_ms, target[0], target[1], MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mask,
                round(lat * 1e7), round(lon * 1e7), float(alt), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                float(heading or 0.0), 0.0)

    def _send_rtl_altitude(self, alt: float) -> None:
        """RTL's altitude: a PARAM_SET of the autopilot's own parameter."""
        target = self._target
        if target is None:
            return
        name, value, kind = (("RTL_RETURN_ALT", alt, MAV_PARAM_TYPE_REAL32) if self._px4
                             else ("RTL_ALT", round(alt * 100), MAV_PARAM_TYPE_INT16))
        with self._lock:
            self._conn.mav.param_set_send(target[0], target[1], name.encode(), float(value),
                                          kind)
        self._say(f"rtl: {name} set to {value:g}")

    def _mission_message(self, kind: str, msg: Any) -> bool:
        """HOME_POSITION, BATTERY_STATUS, GLOBAL_POSITION_INT's lat/lon, STATUSTEXT; True
        when the message was one of them."""
        if kind == "HOME_POSITION":
            self._home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
        elif kind == "BATTERY_STATUS":
            self._charge = CHARGE_STATES.get(int(msg.charge_state), "")
        elif kind == "GLOBAL_POSITION_INT":
            self._location = ((msg.lat / 1e7, msg.lon / 1e7, msg.relative_alt / 1000.0)
                              if msg.lat or msg.lon else NAN3)
            return False  # hfsmc_mavlink reads the rest
        elif kind == "STATUSTEXT":
            who = "PX4" if self._px4 else "ArduPilot"
            for severity, text in self._texts.add(self.now(), int(msg.severity), msg.text,
                                                  int(getattr(msg, "id", 0)),
                                                  int(getattr(msg, "chunk_seq", 0))):
                self._text = text
                if severity <= 4:  # MAV_SEVERITY_WARNING and worse: said
                    self._say(f"{who}: {text}")
        else:
            return False
        return True

    def _mission_snapshot(self) -> dict[str, Any]:
        return {"location": self._location, "home": self._home, "status_text": self._text,
                "battery_failsafe": self._charge}
