"""What the simulated autopilot sends unasked: its streams (HEARTBEAT, SYS_STATUS,
GLOBAL_POSITION_INT, LOCAL_POSITION_NED, ATTITUDE, GPS_RAW_INT, EKF_STATUS_REPORT,
VFR_HUD) at rates a ground station may change, and the one-off messages
(HOME_POSITION, AUTOPILOT_VERSION) it answers requests with.

Positions and velocities are the body's *reported* ones (truth plus seeded noise);
timestamps are simulated time, so the same seed gives the same samples.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as M

from hfsmc.sim.failsafe import CHARGE_STATE as CHARGE_STATES
from hfsmc.sim.vehicle import CELLS, Body, wrap_pi
from hfsmc.sim.world import Home, World


class Source(Protocol):
    """What the streams read of the autopilot that sends them (hfsmc/sim/autopilot.py):
    the telemetry is written against this, so it does not import the autopilot back."""

    mav: Any  # the MAVLink encoder, whose ``*_send`` methods write to the link
    body: Body
    world: World
    mode: int
    ready: bool
    battery_level: int

    @property
    def navigating(self) -> bool: ...

EARTH_RADIUS = 6378137.0
EKF_READY = (M.EKF_ATTITUDE | M.EKF_VELOCITY_HORIZ | M.EKF_VELOCITY_VERT | M.EKF_POS_HORIZ_REL
             | M.EKF_POS_HORIZ_ABS | M.EKF_POS_VERT_ABS | M.EKF_PRED_POS_HORIZ_REL
             | M.EKF_PRED_POS_HORIZ_ABS)  # 0x33F, as SITL reports once it uses GPS
EKF_BOOTING = (M.EKF_ATTITUDE | M.EKF_VELOCITY_HORIZ | M.EKF_VELOCITY_VERT | M.EKF_POS_VERT_ABS
               | M.EKF_CONST_POS_MODE)  # 0xA7: no absolute position yet
SENSORS = (M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
           | M.MAV_SYS_STATUS_SENSOR_3D_MAG | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
           | M.MAV_SYS_STATUS_SENSOR_GPS | M.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
           | M.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION | M.MAV_SYS_STATUS_SENSOR_YAW_POSITION
           | M.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
           | M.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
           | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | M.MAV_SYS_STATUS_SENSOR_BATTERY)
DEFAULT_RATES = {  # Hz; 0: only when asked (HOME_POSITION is also sent once, when ready)
    "HEARTBEAT": 1.0, "SYS_STATUS": 1.0, "GLOBAL_POSITION_INT": 10.0,
    "LOCAL_POSITION_NED": 10.0, "ATTITUDE": 10.0, "GPS_RAW_INT": 2.0,
    "EKF_STATUS_REPORT": 2.0, "VFR_HUD": 2.0, "HOME_POSITION": 0.0, "BATTERY_STATUS": 0.0,
}
STREAMS = {  # REQUEST_DATA_STREAM's groups, as ArduPilot fills them
    M.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS", "GPS_RAW_INT"),
    M.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    M.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    M.MAV_DATA_STREAM_EXTRA2: ("VFR_HUD",),
    M.MAV_DATA_STREAM_EXTRA3: ("EKF_STATUS_REPORT",),
}


def latlon(home: Home, north: float, east: float) -> tuple[int, int]:
    """Latitude and longitude (degE7) of a point north and east of home (flat earth)."""
    lat = home.lat + math.degrees(north / EARTH_RADIUS)
    lon = home.lon + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(home.lat))))
    return round(lat * 1e7), round(lon * 1e7)


def ned(home: Home, lat_e7: int, lon_e7: int) -> tuple[float, float]:
    """North and east of home (m) of a latitude and longitude (degE7)."""
    north = math.radians(lat_e7 / 1e7 - home.lat) * EARTH_RADIUS
    east = math.radians(lon_e7 / 1e7 - home.lon) * EARTH_RADIUS * math.cos(math.radians(home.lat))
    return north, east


class Telemetry:
    """The autopilot's message streams: which are due at a step, and their rates."""

    def __init__(self, ap: Source) -> None:
        self.ap = ap
        self.intervals = {name: self.steps(hz) for name, hz in DEFAULT_RATES.items()}
        self._senders: dict[str, Callable[[], None]] = {
            "HEARTBEAT": self._heartbeat, "SYS_STATUS": self._sys_status,
            "GLOBAL_POSITION_INT": self._global_position,
            "LOCAL_POSITION_NED": self._local_position, "ATTITUDE": self._attitude,
            "GPS_RAW_INT": self._gps, "EKF_STATUS_REPORT": self._ekf,
            "VFR_HUD": self._vfr_hud, "HOME_POSITION": self._home,
            "AUTOPILOT_VERSION": self._version, "BATTERY_STATUS": self._battery_status,
        }

    def steps(self, hz: float) -> int:
        """Physics steps between two messages at ``hz`` (0: off)."""
        return max(1, round(1.0 / (hz * self.ap.body.dt))) if hz > 0 else 0

    def send_due(self) -> None:
        """Send the streams due at this step (fixed phases: deterministic instants)."""
        step = self.ap.body.steps
        for name, every in self.intervals.items():
            if every and step % every == 0:
                self._senders[name]()

    def send(self, name: str) -> None:
        self._senders[name]()

    def can_send(self, msg_id: int) -> str | None:
        """The name of a message this autopilot can send on request, or None."""
        cls = M.mavlink_map.get(msg_id)
        return cls.msgname if cls is not None and cls.msgname in self._senders else None

    def _stream(self, msg_id: int) -> str | None:
        name = self.can_send(msg_id)
        return name if name in self.intervals else None

    def set_interval(self, msg_id: int, us: float) -> bool:
        """SET_MESSAGE_INTERVAL: -1 stops, 0 restores the default; False: not a stream."""
        name = self._stream(msg_id)
        if name is None:
            return False
        if us == 0:
            self.intervals[name] = self.steps(DEFAULT_RATES[name])
        elif us < 0:
            self.intervals[name] = 0
        else:
            self.intervals[name] = max(1, round(us / 1e6 / self.ap.body.dt))
        return True

    def interval_us(self, msg_id: int) -> int | None:
        """GET_MESSAGE_INTERVAL's answer (-1: stopped); None: not a stream."""
        name = self._stream(msg_id)
        if name is None:
            return None
        every = self.intervals[name]
        return round(every * self.ap.body.dt * 1e6) if every else -1

    def request_data_stream(self, stream_id: int, hz: float, start: bool) -> None:
        """REQUEST_DATA_STREAM (MAVProxy's way): a whole group at one rate."""
        if stream_id == M.MAV_DATA_STREAM_ALL:
            names = [n for group in STREAMS.values() for n in group]
        else:
            names = list(STREAMS.get(stream_id, ()))
        every = self.steps(hz) if start else 0
        for name in names:
            self.intervals[name] = every

    # -- the messages --------------------------------------------------------------

    def _ms(self) -> int:
        return round(self.ap.body.t * 1000)

    def _heartbeat(self) -> None:
        ap, b = self.ap, self.ap.body
        base = (M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
                | M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED)
        if ap.navigating:
            base |= M.MAV_MODE_FLAG_GUIDED_ENABLED
        if b.armed:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
        state = M.MAV_STATE_ACTIVE if b.armed else M.MAV_STATE_STANDBY
        ap.mav.heartbeat_send(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                              ap.mode, state, 3)

    def _sys_status(self) -> None:
        ap, b = self.ap, self.ap.body
        health = SENSORS if ap.ready else SENSORS & ~M.MAV_SYS_STATUS_SENSOR_GPS
        health |= M.MAV_SYS_STATUS_GEOFENCE  # no fence, so never breached
        ap.mav.sys_status_send(SENSORS, SENSORS, health, 200, round(b.voltage * 1000),
                               round(b.current * 100), round(100 * b.battery_fraction),
                               0, 0, 0, 0, 0, 0)

    def _global_position(self) -> None:
        ap, b = self.ap, self.ap.body
        n, e, d = b.reported_position()
        vn, ve, vd = b.reported_velocity()
        lat, lon = latlon(ap.world.home, n, e) if ap.ready else (0, 0)
        ap.mav.global_position_int_send(
            self._ms(), lat, lon, round((ap.world.home.alt - d) * 1000), round(-d * 1000),
            round(vn * 100), round(ve * 100), round(vd * 100),
            round(math.degrees(b.yaw) % 360 * 100) % 36000)

    def _local_position(self) -> None:
        ap, b = self.ap, self.ap.body
        if not ap.ready:
            return  # no EKF origin yet: ArduPilot sends no local position either
        n, e, d = b.reported_position()
        vn, ve, vd = b.reported_velocity()
        ap.mav.local_position_ned_send(self._ms(), n, e, d, vn, ve, vd)

    def _attitude(self) -> None:
        b = self.ap.body
        roll, pitch = b.attitude()
        self.ap.mav.attitude_send(self._ms(), roll, pitch, wrap_pi(b.yaw), 0.0, 0.0, b.yaw_rate)

    def _gps(self) -> None:
        ap, b = self.ap, self.ap.body
        usec = round(b.t * 1e6)
        if not ap.ready:
            ap.mav.gps_raw_int_send(usec, M.GPS_FIX_TYPE_NO_FIX, 0, 0, 0, 65535, 65535, 0,
                                    65535, 0)
            return
        n, e, d = b.reported_position()
        vn, ve, _ = b.reported_velocity()
        lat, lon = latlon(ap.world.home, n, e)
        cog = round(math.degrees(math.atan2(ve, vn)) % 360 * 100) % 36000
        ap.mav.gps_raw_int_send(usec, M.GPS_FIX_TYPE_3D_FIX, lat, lon,
                                round((ap.world.home.alt - d) * 1000), 121, 200,
                                round(math.hypot(vn, ve) * 100), cog, 10)

    def _ekf(self) -> None:
        flags = EKF_READY if self.ap.ready else EKF_BOOTING
        self.ap.mav.ekf_status_report_send(flags, 0.02, 0.01, 0.02, 0.03, 0.0)

    def _vfr_hud(self) -> None:
        ap, b = self.ap, self.ap.body
        speed = math.hypot(b.vn, b.ve)
        throttle = 0 if b.landed else min(100, round(100 * b.power_w / (2 * b.cfg.hover_w)))
        ap.mav.vfr_hud_send(speed, speed, round(math.degrees(b.yaw)) % 360, throttle,
                            ap.world.home.alt + b.altitude, -b.vd)

    def _battery_status(self) -> None:
        """BATTERY_STATUS, with the failsafe's level as charge_state (both autopilots)."""
        ap, b = self.ap, self.ap.body
        cells = [round(b.voltage * 1000 / CELLS)] * CELLS + [65535] * (10 - CELLS)
        ap.mav.battery_status_send(0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO,
                                   32767, cells, round(b.current * 100), -1, -1,
                                   round(100 * b.battery_fraction), 0,
                                   CHARGE_STATES[ap.battery_level])

    def _home(self) -> None:
        ap = self.ap
        if not ap.ready:
            return
        lat, lon = latlon(ap.world.home, 0.0, 0.0)
        ap.mav.home_position_send(lat, lon, round(ap.world.home.alt * 1000), 0.0, 0.0, 0.0,
                                  [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, round(ap.body.t * 1e6))

    def _version(self) -> None:
        caps = (M.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT)
        version = (4 << 24) | (5 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_OFFICIAL
        self.ap.mav.autopilot_version_send(caps, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                                           0, 0, 1)
