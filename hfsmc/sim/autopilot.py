"""The simulated vehicle's autopilot: an ArduPilot Copter seen through MAVLink.

It speaks as system 1, component 1, in MAVLink 2, with Copter's custom mode
numbers (STABILIZE 0, GUIDED 4, LOITER 5, RTL 6, LAND 9, BRAKE 17) and Copter's
answers: a mode that needs a position estimate, or arming, is refused (FAILED,
with a STATUSTEXT saying why) until the vehicle is *ready* (GPS 3D fix and the
EKF's absolute position flags, ``boot_time`` seconds after start); arming is
accepted in GUIDED only; every COMMAND_LONG and COMMAND_INT addressed to it gets
exactly one COMMAND_ACK (UNSUPPORTED for commands it does not know), and
SET_MODE gets the COMMAND_ACK ArduPilot sends for it (command 11).

The autopilot owns no socket and no clock: ``receive`` takes a datagram,
``step`` runs one physics step (mode logic, the body, telemetry due at that
step) and sends through the ``out`` callable given at construction.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from hfsmc.sim import failsafe
from hfsmc.sim.mission_hooks import ArduPilotMissions
from hfsmc.sim.telemetry import Telemetry, ned
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World

SYSID, COMPID = 1, 1
STABILIZE, AUTO, GUIDED, LOITER, RTL, LAND, BRAKE = 0, 3, 4, 5, 6, 9, 17
MODE_NAMES = {STABILIZE: "STABILIZE", AUTO: "AUTO", GUIDED: "GUIDED", LOITER: "LOITER", RTL: "RTL",
              LAND: "LAND", BRAKE: "BRAKE"}
NEEDS_POSITION = frozenset({AUTO, GUIDED, LOITER, RTL, BRAKE})
NAVIGATING = NEEDS_POSITION  # the modes ArduPilot flags MAV_MODE_FLAG_GUIDED_ENABLED

GUIDED_TIMEOUT = 3.0  # s: a velocity target without a successor expires (then hold)
# After touchdown, LAND and RTL disarm once the land detector has decided: the throttle
# winds down to its lower limit (LAND_SETTLE), the detector holds that for its trigger
# time (1 s in Copter), then the motors spool down to ground idle (MOT_SPOOL_TIME).
LAND_SETTLE = 1.0  # s
LAND_DETECTOR_TRIGGER = 1.0  # s
FORCE_DISARM = 21196.0  # param2 that disarms in the air (ArduPilot's magic number)
FAR, FAST = 1e5, 1e3  # m, m/s: targets beyond these are ignored
SET_MODE_ACK = mavlink.MAVLINK_MSG_ID_SET_MODE  # ArduPilot acks SET_MODE as "command 11"
# MAVLink FTP opcodes and error code (the message carries them in its payload bytes)
FTP_TERMINATE_SESSION, FTP_RESET_SESSIONS, FTP_ACK, FTP_NAK, FTP_FILE_NOT_FOUND = 1, 2, 128, 129, 10

M = mavlink
TYPEMASK_POS = (M.POSITION_TARGET_TYPEMASK_X_IGNORE | M.POSITION_TARGET_TYPEMASK_Y_IGNORE
                | M.POSITION_TARGET_TYPEMASK_Z_IGNORE)
TYPEMASK_VEL = (M.POSITION_TARGET_TYPEMASK_VX_IGNORE | M.POSITION_TARGET_TYPEMASK_VY_IGNORE
                | M.POSITION_TARGET_TYPEMASK_VZ_IGNORE)
TYPEMASK_ACC = (M.POSITION_TARGET_TYPEMASK_AX_IGNORE | M.POSITION_TARGET_TYPEMASK_AY_IGNORE
                | M.POSITION_TARGET_TYPEMASK_AZ_IGNORE)
LOCAL_FRAMES = (M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_OFFSET_NED, M.MAV_FRAME_BODY_NED,
                M.MAV_FRAME_BODY_OFFSET_NED)
BODY_FRAMES = (M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_OFFSET_NED)
GLOBAL_FRAMES = (M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                 M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT)
ACCEPTED: int = M.MAV_RESULT_ACCEPTED
FAILED: int = M.MAV_RESULT_FAILED
DENIED: int = M.MAV_RESULT_DENIED
UNSUPPORTED: int = M.MAV_RESULT_UNSUPPORTED


def parse_datagram(data: bytes) -> list[Any]:
    """The MAVLink messages in one UDP datagram; nothing for garbage.

    A fresh parser per datagram: a torn or forged header in one datagram must
    not swallow the start of the next one.
    """
    parser = mavlink.MAVLink(None, SYSID, COMPID)
    parser.robust_parsing = True
    try:
        msgs = parser.parse_buffer(data) or []
    except Exception:  # pymavlink raises assorted errors on hostile bytes; drop them all
        return []
    return [m for m in msgs if m.get_type() != "BAD_DATA"]


def _finite(*xs: float) -> bool:
    return all(math.isfinite(x) for x in xs)


def _sane(limit: float, *xs: float) -> bool:
    """Finite and within ``limit``: a target 1e38 m away is a bug or an attack, not a goal."""
    return all(math.isfinite(x) and abs(x) <= limit for x in xs)


class _Out:
    """The file-like object pymavlink writes packed messages to."""

    def __init__(self, send: Callable[[bytes], None]) -> None:
        self.send = send

    def write(self, buf: bytes | bytearray) -> None:
        self.send(bytes(buf))


class Autopilot(ArduPilotMissions):
    """Copter's modes, commands and acknowledgements over a ``Body``; what it streams
    is in ``self.telemetry``."""

    def __init__(self, world: World, body: Body, out: Callable[[bytes], None], *,
                 boot_time: float = 3.0, log: Callable[[str], None] = lambda s: None) -> None:
        self.world = world
        self.body = body
        self.boot_time = boot_time
        self.log = log
        self.mav = mavlink.MAVLink(_Out(out), SYSID, COMPID)
        self.mode = STABILIZE
        self.ready = False
        self.params = self.default_params(world)
        self.rtl_stage = ""
        self.rtl_alt = 0.0
        self.rtl_since = 0.0
        self.vel_time = -math.inf
        self.landed_since = 0.0
        self.climbing_to: float | None = None  # a take-off in progress, to this altitude
        self.spooled_at = 0.0  # a take-off leaves the ground at this time (motors spooled up)
        self.takeoff_point: tuple[float, float] | None = None
        self.landing_point: tuple[float, float] | None = None
        self.takeoffs = self.landings = 0
        self.battery_level = failsafe.OK  # the battery failsafe's level, latched
        self._after_ack: list[str] = []
        self._handlers: dict[str, Callable[[Any], None]] = {
            "COMMAND_LONG": self._on_command_long, "COMMAND_INT": self._on_command_int,
            "SET_MODE": self._on_set_mode,
            "SET_POSITION_TARGET_LOCAL_NED": self._on_target_local,
            "SET_POSITION_TARGET_GLOBAL_INT": self._on_target_global,
            "REQUEST_DATA_STREAM": self._on_request_data_stream,
            "PARAM_REQUEST_LIST": self._on_param_list, "PARAM_REQUEST_READ": self._on_param_read,
            "PARAM_SET": self._on_param_set,
            "FILE_TRANSFER_PROTOCOL": self._on_ftp,
        }
        self._commands: dict[int, Callable[[tuple[float, ...]], int]] = {
            M.MAV_CMD_COMPONENT_ARM_DISARM: self._cmd_arm,
            M.MAV_CMD_NAV_TAKEOFF: self._cmd_takeoff,
            M.MAV_CMD_NAV_LAND: lambda p: self._mode_result(self.set_mode(LAND)),
            M.MAV_CMD_NAV_RETURN_TO_LAUNCH: lambda p: self._mode_result(self.set_mode(RTL)),
            M.MAV_CMD_DO_SET_MODE: lambda p: self._set_mode_common(int(p[0]), int(p[1])),
            M.MAV_CMD_SET_MESSAGE_INTERVAL: self._cmd_set_interval,
            M.MAV_CMD_GET_MESSAGE_INTERVAL: self._cmd_get_interval,
            M.MAV_CMD_REQUEST_MESSAGE: self._cmd_request_message,
            M.MAV_CMD_GET_HOME_POSITION: lambda p: self._queue("HOME_POSITION"),
            M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: lambda p: self._queue("AUTOPILOT_VERSION"),
            M.MAV_CMD_CONDITION_YAW: self._cmd_condition_yaw,
            M.MAV_CMD_DO_CHANGE_SPEED: self._cmd_change_speed,
        }
        self.telemetry = Telemetry(self)
        self._missions_init()
        self._apply_params()

    @staticmethod
    def default_params(world: World) -> dict[str, float]:
        """Copter's defaults (docs/worlds.md); the world's ``vehicle`` limits cap them."""
        cfg = world.vehicle
        return {
            "SYSID_THISMAV": 1, "FRAME_CLASS": 1, "FRAME_TYPE": 1,
            "WPNAV_SPEED": cfg.max_speed * 100, "WPNAV_SPEED_UP": 250, "WPNAV_SPEED_DN": 150,
            "WPNAV_ACCEL": cfg.max_accel * 100, "WPNAV_ACCEL_Z": 100,
            "LAND_SPEED": 50, "LAND_SPEED_HIGH": 0, "LAND_ALT_LOW": 1000,
            "MOT_SPOOL_TIME": 0.5, "TKOFF_SLEW_TIME": 2.0,
            "RTL_ALT": 1500, "RTL_LOIT_TIME": 5000, "WPNAV_RADIUS": 200,
            "FENCE_ENABLE": 0, "FENCE_ACTION": 1,
            "DISARM_DELAY": 10, "WP_YAW_BEHAVIOR": 2, "ARMING_CHECK": 1,
            **failsafe.ARDUPILOT_PARAMS,
        }

    # -- the loop's two entry points -----------------------------------------------

    def receive(self, datagram: bytes) -> None:
        """Handle the messages of one datagram (garbage is ignored)."""
        for msg in parse_datagram(datagram):
            handler = self._handlers.get(msg.get_type())
            if handler is None:
                continue
            try:
                handler(msg)
            except (ValueError, OverflowError, TypeError):
                continue  # a well-formed message with absurd values (NaN as an int...)

    def step(self) -> None:
        """One physics step: the telemetry due now, mode logic, then the body."""
        b = self.body
        if not self.ready and b.t >= self.boot_time:
            self.ready = True
            self.log("ready (GPS 3D fix, EKF using GPS)")
            self._text(M.MAV_SEVERITY_INFO, "EKF3 IMU0 is using GPS")
            self.telemetry.send("HOME_POSITION")
        self.telemetry.send_due()
        self.missions.tick()
        self._update()
        for event in b.step():
            self._on_event(event)
        if self.climbing_to is not None and b.nav == "goto" and b.goal[2] < 0 and b.arrived(0.1):
            self.log(f"take-off complete ({self.climbing_to:.1f} m)")
            self.climbing_to = None

    # -- modes -----------------------------------------------------------------------

    @property
    def navigating(self) -> bool:
        """A mode ArduPilot flags MAV_MODE_FLAG_GUIDED_ENABLED for."""
        return self.mode in NAVIGATING

    @property
    def mode_name(self) -> str:
        return MODE_NAMES.get(self.mode, str(self.mode))

    def set_mode(self, mode: int) -> bool:
        """Change mode as Copter does; False (and a STATUSTEXT) when refused."""
        if mode == self.mode:
            return True
        name = MODE_NAMES.get(mode)
        if name is None:
            self._text(M.MAV_SEVERITY_WARNING, f"No such mode {mode}")
            return False
        if mode in NEEDS_POSITION and not self.ready:
            self._text(M.MAV_SEVERITY_WARNING, f"Mode change to {name} failed: requires position")
            return False
        why = self.auto_refusal() if mode == AUTO else ""
        if why:
            self._text(M.MAV_SEVERITY_WARNING, why)
            return False
        self.mode = mode
        self.climbing_to = None
        self.rtl_stage = ""
        b = self.body
        if mode == LAND:
            b.land()
        elif mode == RTL:
            self._rtl_start()
        else:
            if mode == AUTO:
                self.missions.restart_if_done()
            b.hold(boost=3.0 if mode == BRAKE else 1.0)
        self.log(f"mode {name}")
        return True

    def _update(self) -> None:
        b, t = self.body, self.body.t
        if self.mode == GUIDED and b.nav == "velocity" and t - self.vel_time > GUIDED_TIMEOUT:
            b.hold()
        if self.mode == RTL or (self.mode == AUTO and self.rtl_stage):
            self._rtl_update()
        if self.mode == AUTO:
            self.auto_step()
        if self.climbing_to is not None and b.landed and b.goal[2] == 0.0 \
                and t >= self.spooled_at - 1e-9:
            b.goto(b.north, b.east, -self.climbing_to)  # spooled up: climb
        if b.armed and b.landed:
            idle = t - self.landed_since
            if (self.mode in (LAND, RTL) or (self.mode == AUTO and self.missions.landing)) \
                    and idle >= self.land_detect_time - 1e-9:
                self._disarm("landed")
            elif idle >= self.params["DISARM_DELAY"] > 0:
                self._disarm(f"auto-disarm after {idle:.0f} s on the ground")
        if b.armed and not b.landed and b.energy_wh <= 0 and self.mode != LAND:
            self._text(M.MAV_SEVERITY_CRITICAL, "Battery empty: LAND")
            self.set_mode(LAND)
        self._battery_failsafe()

    def battery_grade(self) -> int:
        """The battery failsafe's level now (failsafe.OK ... EMERGENCY)."""
        return failsafe.ardupilot_level(self.params, self.body.voltage)

    def battery_action(self, level: int) -> tuple[str, int]:
        """What reaching a level does: (STATUSTEXT, the mode to switch to or -1)."""
        mode = {"LAND": LAND, "RTL": RTL}.get(failsafe.ardupilot_action(self.params, level), -1)
        return failsafe.ARDUPILOT_TEXT.get(min(level, failsafe.CRITICAL), ""), mode

    def _battery_failsafe(self) -> None:
        """A new, worse level: said once, acted on as the parameters say (in the air)."""
        b = self.body
        level = self.battery_grade() if b.armed else failsafe.OK
        if level <= self.battery_level:
            return
        self.battery_level = level
        text, mode = self.battery_action(level)
        self.log(f"battery failsafe: level {level} ({text})")
        self._text(M.MAV_SEVERITY_CRITICAL, text)
        if mode >= 0 and not b.landed and self.mode != mode and self.mode != LAND:
            self._failsafe_mode(mode)

    def _failsafe_mode(self, mode: int) -> None:
        self.set_mode(mode)

    @property
    def land_detect_time(self) -> float:
        """Seconds from touchdown to disarming in LAND and RTL."""
        return LAND_SETTLE + LAND_DETECTOR_TRIGGER + max(0.0, self.params["MOT_SPOOL_TIME"])

    def _rtl_start(self) -> None:
        b = self.body
        if b.landed:
            self.rtl_stage = "land"
            b.land()
            return
        self.rtl_alt = max(self.params["RTL_ALT"] / 100.0, b.altitude)
        n, e, _ = b.stopping_point()
        b.goto(n, e, -self.rtl_alt)
        b.hold_heading()
        self.rtl_stage = "climb"

    def _rtl_update(self) -> None:
        b = self.body
        if self.rtl_stage == "climb" and b.arrived(0.3):
            b.goto(0.0, 0.0, -self.rtl_alt)
            if self.params["WP_YAW_BEHAVIOR"] in (1, 3):  # 2: "except RTL"
                b.face_travel()
            self.rtl_stage = "return"
        elif self.rtl_stage == "return" and b.arrived(0.1):
            self.rtl_stage = "loiter"
            self.rtl_since = b.t
        elif self.rtl_stage == "loiter" and \
                b.t - self.rtl_since >= self.params["RTL_LOIT_TIME"] / 1000.0:
            self.rtl_stage = "land"
            b.land()

    def _on_event(self, event: str) -> None:
        b = self.body
        if event == "liftoff":
            self.takeoffs += 1
            self.takeoff_point = (b.north, b.east)
        elif event == "touchdown":
            self.landings += 1
            self.landed_since = b.t
            self.landing_point = (b.north, b.east)
            self.log(f"landed at north {b.north:.2f} m, east {b.east:.2f} m")

    def _disarm(self, why: str) -> None:
        self.body.armed = False
        self.climbing_to = None
        self.log(f"disarmed ({why})")

    # -- commands ----------------------------------------------------------------------

    def _for_me(self, m: Any) -> bool:
        return m.target_system in (0, SYSID) and getattr(m, "target_component", 0) in (0, COMPID)

    def _on_command_long(self, m: Any) -> None:
        if self._for_me(m):
            self._command(m, (m.param1, m.param2, m.param3, m.param4, m.param5, m.param6,
                              m.param7))

    def _on_command_int(self, m: Any) -> None:
        if self._for_me(m):
            self._command(m, (m.param1, m.param2, m.param3, m.param4, float(m.x), float(m.y),
                              m.z))

    def _command(self, m: Any, p: tuple[float, ...]) -> None:
        handler = self._commands.get(m.command)
        self._after_ack = []
        try:
            result = UNSUPPORTED if handler is None else handler(p)
        except (ValueError, OverflowError):
            result = DENIED  # NaN or infinite where a number was needed
        self.mav.command_ack_send(m.command, result, 0, 0, m.get_srcSystem(),
                                  m.get_srcComponent())
        for name in self._after_ack:
            self.telemetry.send(name)

    def _queue(self, name: str) -> int:
        """Send a message right after the ACK (REQUEST_MESSAGE and its kin)."""
        if name == "HOME_POSITION" and not self.ready:
            return FAILED  # no home before the EKF has its origin
        self._after_ack.append(name)
        return ACCEPTED

    def _mode_result(self, ok: bool) -> int:
        return ACCEPTED if ok else FAILED

    def _set_mode_common(self, base_mode: int, custom_mode: int) -> int:
        if base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return self._mode_result(self.set_mode(custom_mode))
        return DENIED  # only custom modes, as ArduPilot

    def _on_set_mode(self, m: Any) -> None:
        if m.target_system not in (0, SYSID):
            return
        result = self._set_mode_common(m.base_mode, m.custom_mode)
        self.mav.command_ack_send(SET_MODE_ACK, result, 0, 0, m.get_srcSystem(),
                                  m.get_srcComponent())

    def _cmd_arm(self, p: tuple[float, ...]) -> int:
        b = self.body
        if p[0] == 1.0:
            if b.armed:
                return ACCEPTED
            if not self.ready:
                self._text(M.MAV_SEVERITY_CRITICAL, "PreArm: Need Position Estimate")
                return FAILED
            if self.mode != GUIDED:
                self._text(M.MAV_SEVERITY_CRITICAL, f"Arm: Mode {self.mode_name} not armable")
                return FAILED
            b.armed = True
            b.hold()
            self.landed_since = b.t
            self.log("armed")
            return ACCEPTED
        if p[0] == 0.0:
            if not b.armed:
                return ACCEPTED
            if not b.landed and p[1] != FORCE_DISARM:
                self._text(M.MAV_SEVERITY_CRITICAL, "Disarm: vehicle is flying")
                return FAILED
            self._disarm("by command" if b.landed else "forced, in the air")
            return ACCEPTED
        return UNSUPPORTED

    def _cmd_takeoff(self, p: tuple[float, ...]) -> int:
        b, alt = self.body, p[6]
        if self.mode != GUIDED or not b.armed or not b.landed or not _sane(FAR, alt) or alt <= 0:
            return FAILED
        # Copter spools the motors up, slews the throttle to hover (TKOFF_SLEW_TIME), then
        # climbs at WPNAV_SPEED_UP within WPNAV_ACCEL_Z; the climb starts in _update.
        b.goto(b.north, b.east, 0.0)
        b.hold_heading()
        self.climbing_to = alt
        spool, slew = self.params["MOT_SPOOL_TIME"], self.params["TKOFF_SLEW_TIME"]
        self.spooled_at = b.t + max(0.0, spool) + max(0.0, slew)
        self.log(f"take-off to {alt:.1f} m")
        return ACCEPTED

    def _cmd_set_interval(self, p: tuple[float, ...]) -> int:
        if not self.telemetry.set_interval(int(p[0]), p[1]):
            self._text(M.MAV_SEVERITY_INFO, f"No ap_message for mavlink id ({int(p[0])})")
            return DENIED
        return ACCEPTED

    def _cmd_get_interval(self, p: tuple[float, ...]) -> int:
        us = self.telemetry.interval_us(int(p[0]))
        if us is None:
            return DENIED
        self.mav.message_interval_send(int(p[0]), us)
        return ACCEPTED

    def _cmd_request_message(self, p: tuple[float, ...]) -> int:
        name = self.telemetry.can_send(int(p[0]))
        return DENIED if name is None else self._queue(name)

    def _cmd_condition_yaw(self, p: tuple[float, ...]) -> int:
        if self.mode != GUIDED or not _sane(FAR, p[0], p[1], p[2], p[3]):
            return FAILED
        b = self.body
        direction = -1 if p[2] < 0 else 1 if p[2] > 0 else 0
        # relative (param4): param3 says which way to turn by param1
        target = b.yaw + math.radians(p[0]) * (direction or 1) if p[3] else math.radians(p[0])
        b.turn_to(target, math.radians(p[1]), direction)
        return ACCEPTED

    def _cmd_change_speed(self, p: tuple[float, ...]) -> int:
        if not _finite(p[1]) or p[1] <= 0:
            return FAILED
        self.body.speed_xy = min(p[1], self.world.vehicle.max_speed)
        return ACCEPTED

    # -- guided targets ----------------------------------------------------------------

    def _accepts_targets(self, m: Any) -> bool:
        b = self.body
        return self._for_me(m) and self.mode == GUIDED and b.armed and not b.landed

    def _on_target_local(self, m: Any) -> None:
        if not self._accepts_targets(m):
            return
        self.climbing_to = None  # a new target ends the take-off
        b, mask, frame = self.body, m.type_mask, m.coordinate_frame
        if frame not in LOCAL_FRAMES:
            b.hold()  # ArduPilot stops on a frame it does not know
            return
        rotate = frame in BODY_FRAMES
        if not mask & TYPEMASK_POS:
            if not _sane(FAR, m.x, m.y, m.z):
                return
            x, y = self._rotate(m.x, m.y) if rotate else (m.x, m.y)
            z = m.z
            if frame != M.MAV_FRAME_LOCAL_NED:  # offsets from where the vehicle is
                x, y, z = x + b.north, y + b.east, z + b.down
            if self.fence_refuses(x, y):
                return
            b.goto(x, y, z)
        elif not mask & TYPEMASK_VEL:
            if not _sane(FAST, m.vx, m.vy, m.vz):
                return
            vx, vy = self._rotate(m.vx, m.vy) if rotate else (m.vx, m.vy)
            b.fly_velocity(vx, vy, m.vz)
            self.vel_time = b.t
        else:
            b.hold()  # acceleration-only or nothing: not flown here, stop
        self._target_yaw(mask, m.yaw, m.yaw_rate, rotate)

    def _on_target_global(self, m: Any) -> None:
        if not self._accepts_targets(m):
            return
        self.climbing_to = None
        b, mask, frame = self.body, m.type_mask, m.coordinate_frame
        if frame not in GLOBAL_FRAMES:
            b.hold()
            return
        if not mask & TYPEMASK_POS:
            n, e = ned(self.world.home, m.lat_int, m.lon_int)
            if not _sane(FAR, n, e, m.alt - self.world.home.alt):
                return
            up = m.alt - self.world.home.alt if frame == M.MAV_FRAME_GLOBAL_INT else m.alt
            if self.fence_refuses(n, e):
                return
            b.goto(n, e, -up)
        elif not mask & TYPEMASK_VEL:
            if not _sane(FAST, m.vx, m.vy, m.vz):
                return
            b.fly_velocity(m.vx, m.vy, m.vz)
            self.vel_time = b.t
        else:
            b.hold()
        self._target_yaw(mask, m.yaw, m.yaw_rate, False)

    def _target_yaw(self, mask: int, yaw: float, rate: float, relative: bool) -> None:
        """Heading from a target: angle, rate, or (neither) ArduPilot's default."""
        b = self.body
        use_yaw = not mask & M.POSITION_TARGET_TYPEMASK_YAW_IGNORE and _finite(yaw)
        use_rate = not mask & M.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE and _finite(rate)
        if use_yaw:
            b.turn_to(yaw + (b.yaw if relative else 0.0), abs(rate) if use_rate else 0.0)
        elif use_rate:
            b.turn_rate(rate)
        elif self.params["WP_YAW_BEHAVIOR"] != 0:
            b.face_travel()  # both ignored: face the way it goes (Copter 4.1+)
        else:
            b.hold_heading()

    def _rotate(self, forward: float, right: float) -> tuple[float, float]:
        c, s = math.cos(self.body.yaw), math.sin(self.body.yaw)
        return (forward * c - right * s, forward * s + right * c)

    # -- parameters, mission, files --------------------------------------------------

    def _on_request_data_stream(self, m: Any) -> None:
        if self._for_me(m):
            self.telemetry.request_data_stream(m.req_stream_id, m.req_message_rate,
                                               bool(m.start_stop))

    def set_params(self, values: dict[str, float]) -> None:
        """Set parameters by name (``hfsmc sim --param``); KeyError names an unknown one."""
        for name, value in values.items():
            if name not in self.params:
                raise KeyError(name)
            self.params[name] = value
        self._apply_params()

    def _apply_params(self) -> None:
        b, cfg, p = self.body, self.world.vehicle, self.params
        b.speed_xy = max(0.1, min(p["WPNAV_SPEED"] / 100, cfg.max_speed))
        b.speed_up = max(0.1, min(p["WPNAV_SPEED_UP"] / 100, cfg.max_climb))
        b.speed_down = max(0.1, min(p["WPNAV_SPEED_DN"] / 100, cfg.max_climb))
        b.land_speed = max(0.1, min(p["LAND_SPEED"] / 100, b.speed_down))
        high = p["LAND_SPEED_HIGH"] / 100 or b.speed_down  # 0: WPNAV_SPEED_DN
        b.land_speed_high = max(b.land_speed, min(high, cfg.max_climb))
        b.land_alt_low = max(0.0, p["LAND_ALT_LOW"] / 100)
        b.accel = max(0.1, min(p["WPNAV_ACCEL"] / 100, cfg.max_accel))
        b.accel_z = max(0.1, min(p["WPNAV_ACCEL_Z"] / 100, cfg.max_accel))

    def _send_param(self, name: str) -> None:
        names = list(self.params)
        self.mav.param_value_send(name.encode(), float(self.params[name]),
                                  M.MAV_PARAM_TYPE_REAL32, len(names), names.index(name))

    def _on_param_list(self, m: Any) -> None:
        if self._for_me(m):
            for name in self.params:
                self._send_param(name)

    def _on_param_read(self, m: Any) -> None:
        if not self._for_me(m):
            return
        names = list(self.params)
        if 0 <= m.param_index < len(names):
            self._send_param(names[m.param_index])
        elif m.param_id in self.params:
            self._send_param(m.param_id)

    def _on_param_set(self, m: Any) -> None:
        if self._for_me(m) and m.param_id in self.params and _sane(FAR, m.param_value):
            self.params[m.param_id] = m.param_value
            self._apply_params()
            self._send_param(m.param_id)

    def _on_ftp(self, m: Any) -> None:
        """MAVLink FTP: no files here. Answer at once (a NAK, "file not found") so that a
        ground station falls back to the parameter protocol instead of timing out."""
        if m.target_system not in (0, SYSID) or m.target_component not in (0, COMPID):
            return
        seq, session, opcode = struct.unpack_from("<HBB", bytes(m.payload))
        if opcode in (FTP_TERMINATE_SESSION, FTP_RESET_SESSIONS):
            head = struct.pack("<HBBBBBBI", seq + 1 & 0xFFFF, session, FTP_ACK, 0, opcode, 0, 0, 0)
        else:
            head = struct.pack("<HBBBBBBI", seq + 1 & 0xFFFF, session, FTP_NAK, 1, opcode, 0, 0,
                               0) + bytes([FTP_FILE_NOT_FOUND])
        self.mav.file_transfer_protocol_send(0, m.get_srcSystem(), m.get_srcComponent(),
                                             list(head.ljust(251, b"\0")))

    def _text(self, severity: int, text: str) -> None:
        self.mav.statustext_send(severity, text.encode()[:50])
