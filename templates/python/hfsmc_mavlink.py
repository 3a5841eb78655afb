"""The ``mavlink`` interface of Python components (docs/interfaces.md): a vehicle flown
the ArduPilot Copter way (GUIDED mode), over pymavlink.

Copied beside a generated component that declares an interface of type
``mavlink``; the runtime imports it and calls ``connect(name, url, options)``.
pymavlink is imported with the module: without it the import fails and the
runtime turns the interface into one that says "cannot be loaded" when used.

One daemon thread owns the receiving side (hfsmc_mavlink_reader.py, mixed into
``Vehicle``): it reads the socket, keeps the latest telemetry as immutable values (a
float or a tuple, replaced whole, so that readers need no lock), watches the
heartbeat, requests the message rates, matches COMMAND_ACKs to the commands waiting
for them (resending once, as MAVProxy does with ``confirmation`` + 1) and logs each
outcome once on stderr. The automaton's thread never waits on the network: queries return
the state at hand, commands send one datagram on a non-blocking socket and
return. One lock orders the pymavlink calls of the two threads (the parser
can swap its protocol object when MAVLink 2 shows up); it is held for a
send or for the parsing of datagrams already received, never while waiting.

With ``--clock sim`` (lockstep with ``hfsmc sim``) there is no reader thread: before
each instant the automaton's thread reads the datagrams the simulator says it has sent
and does the reader's timed work (heartbeat, resends, link watch) at simulated time,
so that what is sent and received depends on nothing else (``lockstep_sync``, in
hfsmc_mavlink_reader.py too). Missions and the geofence (the MISSION_ITEM_INT protocol)
are hfsmc_mission_upload.py's, the mission API's helpers hfsmc_mission.py's, PX4's
specifics hfsmc_px4.py's.
"""

from __future__ import annotations

import atexit
import math
import threading
from typing import Any, ClassVar

from pymavlink import mavutil

try:  # beside the component, or in the hfsmc package
    from . import hfsmc_driver as _driver
    from . import hfsmc_mavlink_link as _link
    from . import hfsmc_mavlink_reader as _reader
    from . import hfsmc_mavlink_send as _send
    from . import hfsmc_mission as _mission
    from . import hfsmc_mission_upload as _upload
    from . import hfsmc_px4 as _px4
except ImportError:
    import hfsmc_driver as _driver  # type: ignore[import-not-found, no-redef]
    import hfsmc_mavlink_link as _link  # type: ignore[import-not-found, no-redef]
    import hfsmc_mavlink_reader as _reader  # type: ignore[import-not-found, no-redef]
    import hfsmc_mavlink_send as _send  # type: ignore[import-not-found, no-redef]
    import hfsmc_mission as _mission  # type: ignore[import-not-found, no-redef]
    import hfsmc_mission_upload as _upload  # type: ignore[import-not-found, no-redef]
    import hfsmc_px4 as _px4  # type: ignore[import-not-found, no-redef]

_MAV: Any = mavutil.mavlink

DEFAULT_URL = "udpin:127.0.0.1:14550"  # the vehicle sends there, as ArduPilot SITL does for a GCS
LINK_TIMEOUT_S = _reader.LINK_TIMEOUT_S  # no heartbeat for that long: the link is lost
ACK_TIMEOUT_S = 3.0  # a command without COMMAND_ACK by then has failed; resent once halfway
POLL_S = _reader.POLL_S  # longest wait of the reader: bounds ack deadlines and close()
FAST_RATE_HZ = _send.FAST_RATE_HZ  # position, velocity, attitude (option `rate`)

# SET_POSITION_TARGET_LOCAL_NED.type_mask: a set bit means "ignore that field"
# (MAVLink POSITION_TARGET_TYPEMASK; bit 9, force, stays clear).
IGNORE_POSITION = 0b0000_0000_0111  # x, y, z
IGNORE_VELOCITY = 0b0000_0011_1000  # vx, vy, vz
IGNORE_ACCELERATION = 0b0001_1100_0000  # afx, afy, afz
IGNORE_YAW = 0b0100_0000_0000
IGNORE_YAW_RATE = 0b1000_0000_0000
VELOCITY_MASK = IGNORE_POSITION | IGNORE_ACCELERATION | IGNORE_YAW  # 0x05C7: vx vy vz yaw_rate
POSITION_MASK = IGNORE_VELOCITY | IGNORE_ACCELERATION | IGNORE_YAW | IGNORE_YAW_RATE  # 0x0DF8
STOP_FACING_MASK = IGNORE_POSITION | IGNORE_ACCELERATION | IGNORE_YAW_RATE  # 0x09C7: v = 0, yaw

MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_BODY_OFFSET_NED = 9  # velocities along the vehicle's heading: forward, right, down

# ArduPilot's GUIDED needs an absolute horizontal position from the EKF; while
# disarmed a predicted one will do, once armed not in constant-position mode
# (Copter::ekf_has_absolute_position). EKF_STATUS_FLAGS bits:
EKF_POS_HORIZ_ABS = 16
EKF_CONST_POS_MODE = 128
EKF_PRED_POS_HORIZ_ABS = 512
GPS_FIX_3D = 3  # GPS_RAW_INT.fix_type
MODE_FLAG_SAFETY_ARMED = 128  # HEARTBEAT.base_mode
MODE_FLAG_CUSTOM_MODE_ENABLED = 1


def connect(name: str, url: str | None, options: dict[str, str], sim: Any = None) -> Vehicle:
    """Open the link to a vehicle and start its reader; returns at once. ``sim``: the
    simulator's clock (hfsmc_simclock.SimClock), which the vehicle then follows."""
    vehicle = Vehicle.connect(name, url, options, sim)
    assert isinstance(vehicle, Vehicle)
    return vehicle


class VehicleQueries(_driver.Driver):
    """What snippets call, declared as a driver's (hfsmc_driver.py, docs/drivers.md), and
    the vehicle of ``hfsmc replay`` and ``hfsmc test`` (``fake``: its snapshot from the
    script). Queries return the snapshot taken when the instant began
    (docs/recording.md), so that every call of an instant sees the same vehicle; commands
    are checked, told to ``on_command`` (a recording, a playback), then sent by
    ``_command`` and ``_target_local``, which a fake vehicle leaves empty."""

    KIND = "mavlink"
    LOCKSTEP = True  # with --clock sim: no reader thread, lockstep_sync (hfsmc_mavlink_reader)
    VIEW = "vehicle"  # the live views' vehicle panel (hfsmc_monitor.vehicle_message)
    PUBLIC = ("warning_at_stop", "close")
    SNAPSHOT: ClassVar[dict[str, Any]] = {  # a vehicle not heard yet
        "heartbeat_age": math.inf, "ready": False, "armed": False, "mode": "",
        "position": (math.nan, math.nan, math.nan), "altitude": math.nan,
        "velocity": (math.nan, math.nan, math.nan), "yaw": math.nan, "battery": -1,
        "acks": {}, "vehicle": False, "type": 0, "autopilot": 0,
        "location": (math.nan, math.nan, math.nan), "home": (math.nan, math.nan, math.nan),
        "status_text": "", "battery_failsafe": "", "mission": (0, 0), "fence_breached": False,
        "failsafe": ""}
    OPTIONS: ClassVar[dict[str, Any]] = {"rate": 20.0, "ack_timeout": 3.0,
                                         "source_system": 255, "autopilot": "auto"}

    _aim: tuple[str, float, float, float] | None = None  # the latest position target

    def read_options(self, options: dict[str, Any]) -> dict[str, Any]:
        """As given: a bad or unknown option is said and replaced (Vehicle.__init__)."""
        return dict(options)

    def apply(self, values: dict[str, Any]) -> None:
        """A fake: the script's entry (hfsmc_playback has converted its fields)."""
        self._scripted = {**self._scripted, **values}

    def __getattr__(self, attr: str) -> Any:
        """Only for a name the class does not have: say which interface lacks it (the
        error a snippet calling ``drone.fly_to()`` gets), not which Python class."""
        name = self.__dict__.get("name", "?")
        raise AttributeError(f"the mavlink interface `{name}` has no method or attribute "
                             f"`{attr}` (docs/interfaces.md)", name=attr, obj=self)

    # -- state (the instant's snapshot) ----------------------------------------------
    @_driver.query(reads="heartbeat_age")
    def connected(self) -> bool:
        """A heartbeat from the vehicle within the last 2 s."""
        return bool(self._snap["heartbeat_age"] < LINK_TIMEOUT_S)

    @_driver.query(reads="heartbeat_age")
    def heartbeat_age(self) -> float:
        """Seconds since the vehicle's last heartbeat; inf before the first."""
        return float(self._snap["heartbeat_age"])

    @_driver.query(reads="ready")
    def ready(self) -> bool:
        """The vehicle would accept GUIDED: connected, a 3D GPS fix, an absolute EKF position."""
        return bool(self._snap["ready"])

    @_driver.query(reads="armed")
    def armed(self) -> bool:
        """The vehicle's last heartbeat says its motors are armed."""
        return bool(self._snap["armed"])

    @_driver.query(reads="mode")
    def mode(self) -> str:
        """The flight mode's name (GUIDED, LAND, RTL, ...); "" before the first heartbeat."""
        return str(self._snap["mode"])

    @_driver.query(reads="position")
    def position(self) -> tuple[float, float, float]:
        """(north, east, down) in m from the EKF origin (LOCAL_POSITION_NED); NaN before any."""
        return self._snap["position"]  # type: ignore[no-any-return]

    @_driver.query(reads="altitude")
    def altitude(self) -> float:
        """m above home (GLOBAL_POSITION_INT.relative_alt, else -down); NaN before any."""
        return float(self._snap["altitude"])

    @_driver.query(reads="velocity")
    def velocity(self) -> tuple[float, float, float]:
        """(vn, ve, vd) in m/s (LOCAL_POSITION_NED); NaN before any."""
        return self._snap["velocity"]  # type: ignore[no-any-return]

    @_driver.query(reads="yaw")
    def yaw(self) -> float:
        """Heading in rad (ATTITUDE), 0 north, positive clockwise; NaN before any."""
        return float(self._snap["yaw"])

    @_driver.query(reads="battery")
    def battery(self) -> int:
        """Battery remaining in percent (SYS_STATUS); -1 when unknown."""
        return int(self._snap["battery"])

    @_driver.query(reads="location")
    def location(self) -> tuple[float, float, float]:
        """(lat, lon) in degrees and m above home (GLOBAL_POSITION_INT); NaN before a GPS fix."""
        return self._snap["location"]  # type: ignore[no-any-return]

    @_driver.query(reads="home")
    def home(self) -> tuple[float, float, float]:
        """Home: (lat, lon) in degrees and m above mean sea level (HOME_POSITION); NaN before."""
        return self._snap["home"]  # type: ignore[no-any-return]

    @_driver.query(reads="position")
    def distance_to(self, north: float, east: float, alt: float | None = None) -> float:
        """m from the vehicle to a local point (m from the EKF origin); with ``alt`` (m above
        home) in 3-D, else horizontally. NaN before a position."""
        return _mission.local_distance(self._snap["position"], float(self._snap["altitude"]),
                                       north, east, None if alt is None else float(alt))

    @_driver.query(reads="location")
    def distance_to_location(self, lat: float, lon: float, alt: float | None = None) -> float:
        """m from the vehicle to a point by latitude and longitude (degrees); with ``alt`` (m
        above home) in 3-D, else horizontally. NaN before a GPS fix."""
        la, lo, al = _mission.checked_location(self.name, lat, lon, 0.0 if alt is None else alt)
        return _mission.distance(self._snap["location"], (la, lo, None if alt is None else al))

    @_driver.query(reads="position")
    def reached(self, north: float, east: float, alt: float,
                tolerance: float = _mission.DEFAULT_TOLERANCE) -> bool:
        """Within ``tolerance`` m (1 by default) of a local point, in 3-D."""
        return bool(self.distance_to(north, east, alt) <= float(tolerance))

    @_driver.query(reads="location")
    def reached_location(self, lat: float, lon: float, alt: float,
                         tolerance: float = _mission.DEFAULT_TOLERANCE) -> bool:
        """Within ``tolerance`` m (1 by default) of a point by latitude, longitude and altitude
        above home, in 3-D."""
        return bool(self.distance_to_location(lat, lon, alt) <= float(tolerance))

    @_driver.query(reads="status_text")
    def status_text(self) -> str:
        """The autopilot's latest STATUSTEXT (chunks joined); "" before any."""
        return str(self._snap["status_text"])

    @_driver.query(reads="battery_failsafe")
    def battery_failsafe(self) -> str:
        """The battery's failsafe level (BATTERY_STATUS.charge_state): "" (none), low,
        critical, emergency, failed, unhealthy."""
        return str(self._snap["battery_failsafe"])

    @_driver.query(reads="failsafe")
    def failsafe(self) -> str:
        """A failsafe the driver meets, for the model to react to: "link_lost" (no heartbeat
        for 2 s), "offboard_lost" (PX4 left OFFBOARD by itself: its setpoints stopped
        reaching it; until the model asks for a mode, a landing or RTL), "fence" (breached),
        "battery" (a battery failsafe level); "" when none."""
        return str(self._snap["failsafe"])

    @_driver.query(reads="acks")
    def last_ack(self, command: str) -> str:
        """The last outcome of a command (arm, disarm, takeoff, land, rtl, set_mode,
        upload_mission, upload_fence, enable_fence):
        accepted, denied, temporarily_rejected, unsupported, failed, cancelled,
        pending, timeout, not_sent; "" when never sent."""
        return str(self._snap["acks"].get(command, ""))

    # -- commands (send and return) --------------------------------------------
    @_driver.command(checked=True, ack=True)
    def set_mode(self, name: str) -> None:
        """Ask for a flight mode by name (MAV_CMD_DO_SET_MODE with the custom mode)."""
        wanted = name.strip().upper()
        if self._snap.get("autopilot") == _px4.AUTOPILOT_PX4:  # PX4's names: hfsmc_px4.py
            number = _px4.checked_mode(self.name, name)
            self._issue("set_mode", [name], ack=True)
            self._px4_mode(wanted, number)
            return
        numbers = {v: k for k, v in modes(int(self._snap["type"])).items()}
        if wanted not in numbers:
            raise ValueError(f"{self.name}: unknown mode `{name}` (modes: {', '.join(numbers)})")
        self._issue("set_mode", [name], ack=True)
        self._command("set_mode", f"set_mode {wanted}", _MAV.MAV_CMD_DO_SET_MODE,
                      MODE_FLAG_CUSTOM_MODE_ENABLED, numbers[wanted])

    @_driver.command(checked=True, ack=True)
    def arm(self) -> None:
        """Arm the motors (MAV_CMD_COMPONENT_ARM_DISARM 1)."""
        self._issue("arm", [], ack=True)
        self._command("arm", "arm", _MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1)

    @_driver.command(checked=True, ack=True)
    def disarm(self) -> None:
        """Disarm the motors (MAV_CMD_COMPONENT_ARM_DISARM 0; the vehicle refuses in flight)."""
        self._issue("disarm", [], ack=True)
        self._command("disarm", "disarm", _MAV.MAV_CMD_COMPONENT_ARM_DISARM, 0)

    @_driver.command(checked=True, ack=True)
    def takeoff(self, alt: float) -> None:
        """Climb to ``alt`` m above home (MAV_CMD_NAV_TAKEOFF; GUIDED and armed)."""
        self._issue("takeoff", [float(alt)], ack=True)
        self._command("takeoff", "takeoff", _MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, float(alt))

    @_driver.command(checked=True, ack=True)
    def land(self) -> None:
        """Land where the vehicle is (MAV_CMD_NAV_LAND: LAND mode)."""
        self._issue("land", [], ack=True)
        self._command("land", "land", _MAV.MAV_CMD_NAV_LAND)

    @_driver.command(checked=True, ack=True)
    def rtl(self, alt: float | None = None) -> None:
        """Return to launch and land there (MAV_CMD_NAV_RETURN_TO_LAUNCH: RTL mode); with
        ``alt``, at that altitude above home (RTL_ALT, PX4: RTL_RETURN_ALT, set first)."""
        if alt is not None:
            a = float(alt)
            if not 0.0 < a <= _mission.MAX_TARGET:
                raise ValueError(f"{self.name}: rtl altitude {a:g} m is not above home")
            self._issue("rtl", [a], ack=True)
            self._rtl_altitude(a)
        else:
            self._issue("rtl", [], ack=True)
        self._command("rtl", "rtl", _MAV.MAV_CMD_NAV_RETURN_TO_LAUNCH)

    @_driver.command(checked=True)
    def hold(self) -> None:
        """Stop where the vehicle is: a zero velocity target (GUIDED)."""
        self._issue("hold", [])
        self._aim = None
        self._target_local(MAV_FRAME_BODY_OFFSET_NED, VELOCITY_MASK,
                           (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)

    @_driver.command(checked=True)
    def set_velocity(self, vx: float, vy: float, vz: float, yaw_rate: float) -> None:
        """Velocity target in the body frame: m/s forward, right, down; rad/s clockwise.
        ArduPilot stops the vehicle when no new target comes for 3 s."""
        v = (float(vx), float(vy), float(vz))
        self._issue("set_velocity", [*v, float(yaw_rate)])
        self._aim = None
        self._target_local(MAV_FRAME_BODY_OFFSET_NED, VELOCITY_MASK, (0.0, 0.0, 0.0), v,
                           float(yaw_rate))

    @_driver.command(checked=True)
    def goto(self, north: float, east: float, alt: float, heading: float | None = None) -> None:
        """Position target in m from the EKF origin (MAV_FRAME_LOCAL_NED, down = -alt); with
        ``heading`` (rad, 0 north, clockwise) the vehicle faces it."""
        h = _mission.checked_heading(self.name, heading)
        n, e, a = float(north), float(east), float(alt)
        self._issue("goto", [n, e, a] if h is None else [n, e, a, h])
        self._aim = ("local", n, e, a)
        self._goto_local(n, e, a, h)

    @_driver.command(checked=True)
    def goto_location(self, lat: float, lon: float, alt: float,
                      heading: float | None = None) -> None:
        """Position target by latitude and longitude (degrees) and m above home
        (SET_POSITION_TARGET_GLOBAL_INT); with ``heading`` (rad) the vehicle faces it."""
        la, lo, a = _mission.checked_location(self.name, lat, lon, alt)
        h = _mission.checked_heading(self.name, heading)
        self._issue("goto_location", [la, lo, a] if h is None else [la, lo, a, h])
        self._aim = ("global", la, lo, a)
        self._goto_global(la, lo, a, h)

    @_driver.command(checked=True)
    def set_yaw(self, heading: float) -> None:
        """Turn to a heading (rad, 0 north, clockwise): on the way to the latest goto or
        goto_location target, else stopped where the vehicle is (a velocity target ends)."""
        h = _mission.checked_heading(self.name, heading)
        if h is None:
            raise ValueError(f"{self.name}: set_yaw needs a heading in rad, not {heading!r}")
        self._issue("set_yaw", [h])
        aim = self._aim
        if aim is not None and aim[0] == "local":
            self._goto_local(aim[1], aim[2], aim[3], h)
        elif aim is not None:
            self._goto_global(aim[1], aim[2], aim[3], h)
        else:
            self._target_local(MAV_FRAME_LOCAL_NED, STOP_FACING_MASK, (0.0, 0.0, 0.0),
                               (0.0, 0.0, 0.0), 0.0, h)

    def _goto_local(self, n: float, e: float, alt: float, heading: float | None) -> None:
        mask = POSITION_MASK if heading is None else POSITION_MASK & ~IGNORE_YAW
        self._target_local(MAV_FRAME_LOCAL_NED, mask, (n, e, -alt), (0.0, 0.0, 0.0), 0.0,
                           heading or 0.0)

    @_driver.command(checked=True, ack=True)
    def upload_mission(self, points: Any, end: str = "hold") -> None:
        """Upload a mission: points (lat, lon, alt above home[, heading in rad]), then
        ``end`` (hold, land, rtl); its outcome is last_ack("upload_mission")."""
        px4 = self._snap.get("autopilot") == _px4.AUTOPILOT_PX4
        items, users = _upload.mission_items(self.name, points, str(end), px4, self._snap["home"])
        self._issue("upload_mission", [_upload.plain(points), str(end)], ack=True)
        self._upload(_upload.MISSION, items, users)

    @_driver.command(checked=True, ack=True)
    def upload_fence(self, vertices: Any) -> None:
        """Upload an inclusion polygon of (lat, lon) vertices (3 at least; none clears the
        fence); its outcome is last_ack("upload_fence")."""
        items = _upload.fence_items(self.name, vertices)
        self._issue("upload_fence", [_upload.plain(vertices)], ack=True)
        self._upload(_upload.FENCE, items, [])

    @_driver.command(checked=True, ack=True)
    def enable_fence(self, on: bool = True) -> None:
        """Turn the fence on or off (ArduPilot: DO_FENCE_ENABLE; PX4: on once uploaded)."""
        self._issue("enable_fence", [bool(on)], ack=True)
        self._fence_enable(bool(on))

    @_driver.query(reads="mission")
    def mission_progress(self) -> tuple[int, int]:
        """(index of the point being flown to, number of points); (n, n): all reached."""
        m = self._snap["mission"]
        return (int(m[0]), int(m[1]))

    @_driver.query(reads="fence_breached")
    def fence_breached(self) -> bool:
        """The vehicle says it is outside its fence (FENCE_STATUS)."""
        return bool(self._snap["fence_breached"])

    def warning_at_stop(self) -> str | None:
        """What the component says when it stops with the vehicle still armed (then nothing
        lands it: --until, an error without on_interrupt...); None when disarmed. Read from
        the last instant's snapshot, as the automaton saw the vehicle when it stopped (so a
        replay says the same)."""
        self.quiet = True  # the runtime reads the last snapshot: no snippet asks (a replay)
        try:
            if not self.armed():
                return None
            link = "" if self.connected() else f" (link lost {self.heartbeat_age():.0f} s ago)"
            return (f"WARNING: ARMED in {self.mode()} at {self.altitude():.1f} m{link} "
                    "as the component stops: nothing lands the vehicle now")
        finally:
            self.quiet = False

    def close(self) -> None:
        """Stop the reader and close the socket (also run at exit)."""
        super().close()  # a fake: nothing to stop

    def _issue(self, call: str, args: list[Any], ack: bool = False) -> None:
        """Tell the command to whoever listens; a command that is acknowledged says
        `pending` (or `not_sent`: no vehicle heard) from now on in this instant."""
        self.tell(call, args)
        if ack:
            status = "pending" if self._snap["vehicle"] else "not_sent"
            self._snap = {**self._snap, "acks": {**self._snap["acks"], call: status}}

    def _command(self, name: str, label: str, command: int, *params: float,
                 quiet: bool = False) -> None:
        """Send a COMMAND_LONG (the live vehicle)."""

    def _target_local(self, frame: int, mask: int, pos: tuple[float, float, float],
                      vel: tuple[float, float, float], yaw_rate: float, yaw: float = 0.0) -> None:
        """Send a SET_POSITION_TARGET_LOCAL_NED (the live vehicle)."""

    def _goto_global(self, lat: float, lon: float, alt: float, heading: float | None) -> None:
        """Send a SET_POSITION_TARGET_GLOBAL_INT (the live vehicle)."""

    def _rtl_altitude(self, alt: float) -> None:
        """Set RTL's altitude (the live vehicle)."""

    def _upload(self, kind: int, items: list[Any], users: list[int]) -> None:
        """Start an upload (the live vehicle)."""

    def _fence_enable(self, on: bool) -> None:
        """Turn the fence on or off (the live vehicle)."""

    def _px4_mode(self, name: str, number: int) -> None:
        """Ask PX4 for a mode (the live vehicle)."""


NEVER_HEARD: dict[str, Any] = VehicleQueries.SNAPSHOT  # the snapshot of a vehicle not heard yet


def modes(vehicle_type: int) -> dict[int, str]:
    """Flight modes by number for a HEARTBEAT type (Copter's when unknown)."""
    table = mavutil.mode_mapping_bynumber(vehicle_type) if vehicle_type else None
    return dict(table or mavutil.mode_mapping_acm)


class Vehicle(_send.Sender, _px4.Px4Vehicle, _mission.MissionVehicle, _upload.UploadVehicle,
              _reader.Reader, VehicleQueries):
    """A MAVLink vehicle with ArduPilot Copter conventions (docs/interfaces.md): the live
    driver (``connect``: made, then opened), with the simulator's clock in lockstep."""

    def __init__(self, name: str, url: str | None, options: dict[str, Any],
                 playback: Any = None, sim: Any = None) -> None:
        """The live vehicle (``connect``: made, then opened): its options read, a bad one
        said and replaced; ``sim``: the simulator's clock in lockstep (LOCKSTEP)."""
        super().__init__(name, url or DEFAULT_URL, options, playback, sim)
        self._snap = NEVER_HEARD
        self._rate = _link.option(name, options, "rate", FAST_RATE_HZ)
        self._ack_timeout = _link.option(name, options, "ack_timeout", ACK_TIMEOUT_S)
        sysid = int(_link.option(name, options, "source_system", 255.0))
        if sysid > 255:
            self._say(f"option source_system: {sysid} is not 1..255, 255 used")
            sysid = 255
        self._px4_init(options)
        self._mission_init()
        self._upload_init()
        for key in sorted(set(options) - {"rate", "ack_timeout", "source_system", "autopilot"}):
            self._say(f"unknown option `{key}` ignored (options: rate, ack_timeout, source_system, "
                      "autopilot)")
        self._sysid = sysid

    def open(self) -> None:
        """The link (a bad URL: said, exit 1), then the reader thread, or in lockstep the
        datagrams counted."""
        url = self.url
        try:
            self._conn: Any = mavutil.mavlink_connection(  # as a ground station: component 190
                url, source_system=self._sysid, source_component=190)
        except (OSError, ValueError) as e:
            _link.close_half_open(e)
            self._say(f"cannot open {url}: {e}")
            raise SystemExit(1) from None
        self._start = self.now()
        self._lock = threading.Lock()  # pymavlink calls and the pending commands
        self._pending: list[_reader.Pending] = []
        self._acks: dict[str, str] = {}
        # Latest telemetry, each replaced whole by the reader.
        self._target: tuple[int, int] | None = None  # (system, component) of the autopilot
        self._heartbeat_at: float | None = None
        self._heartbeat: tuple[int, int, int, int] = (0, 0, 0, 0)  # type, autopilot, base_mode, custom_mode
        self._lost = False
        self._position = (math.nan, math.nan, math.nan)
        self._velocity = (math.nan, math.nan, math.nan)
        self._relative_alt: float | None = None
        self._yaw = math.nan
        self._battery = -1
        self._gps_fix = 0
        self._ekf_flags = 0
        self._duplicates = _link.Duplicates()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"mavlink {self.name}",
                                        daemon=True)
        self._counted: _link.Counted | None = None  # lockstep: datagrams sent and received
        self._next_heartbeat = 0.0
        if self.sim is None:
            self._thread.start()
        else:
            self._count_datagrams()
        atexit.register(self.close)

    def __repr__(self) -> str:
        return f"<mavlink {self.name} {self.url}>"

    def snapshot(self) -> dict[str, Any]:
        """Read the vehicle once for the instant that begins; queries return this."""
        at = self._heartbeat_at
        age = math.inf if at is None else self.now() - at
        flags, hb = self._ekf_flags, self._heartbeat
        armed = bool(hb[2] & MODE_FLAG_SAFETY_ARMED)
        if self._px4:
            position = self._prearm
        elif armed:
            position = bool(flags & EKF_POS_HORIZ_ABS) and not flags & EKF_CONST_POS_MODE
        else:
            position = bool(flags & (EKF_POS_HORIZ_ABS | EKF_PRED_POS_HORIZ_ABS))
        rel = self._relative_alt
        pos = self._position
        failsafe = ("link_lost" if at is not None and age >= LINK_TIMEOUT_S else
                    "offboard_lost" if self._offboard.lost else
                    "fence" if self._breached else "battery" if self._charge else "")
        self._snap = {
            "heartbeat_age": age,
            "ready": age < LINK_TIMEOUT_S and self._gps_fix >= GPS_FIX_3D and position,
            "armed": armed,
            "mode": "" if at is None else self._mode_name(hb),
            "position": pos, "altitude": -pos[2] if rel is None else rel,
            "velocity": self._velocity, "yaw": self._yaw, "battery": self._battery,
            "acks": dict(self._acks), "vehicle": self._target is not None, "type": hb[0],
            "autopilot": _px4.AUTOPILOT_PX4 if self._px4 else hb[1], **self._mission_snapshot(),
            **self._upload_snapshot(), "failsafe": failsafe}
        return self._snap

    def _mode_name(self, hb: tuple[int, int, int, int]) -> str:
        return _px4.mode_name(hb[3]) if self._px4 else modes(hb[0]).get(hb[3], f"MODE{hb[3]}")

    def close(self) -> None:
        """Stop the reader and close the socket (also run at exit)."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
        with self._lock:
            self._conn.close()

    def _target_local(self, frame: int, mask: int, pos: tuple[float, float, float],
                      vel: tuple[float, float, float], yaw_rate: float, yaw: float = 0.0) -> None:
        if self._px4 and frame == MAV_FRAME_BODY_OFFSET_NED:
            frame = _px4.MAV_FRAME_BODY_NED  # PX4 turns velocities by the heading
        self._send_target(frame, mask, pos, vel, yaw_rate, yaw)
        if self._px4 and self._target is not None:
            self._offboard.target(self.now(), ("local", frame, mask, pos, vel, yaw_rate, yaw))

    def _goto_global(self, lat: float, lon: float, alt: float, heading: float | None) -> None:
        self._fence_check(lat, lon)
        self._send_global(lat, lon, alt, heading)
        if self._px4 and self._target is not None:
            self._offboard.target(self.now(), ("global", lat, lon, alt, heading))

    def _rtl_altitude(self, alt: float) -> None:
        self._send_rtl_altitude(alt)
