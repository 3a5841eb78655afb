"""The simulated vehicle's autopilot as PX4 v1.16 (multicopter, SIH) answers over MAVLink.

The figures are those measured on PX4 v1.16.0 SITL with its SIH quadrotor (project
issue 29, docs/worlds.md "PX4"):

- it is system 1, component 1, autopilot type 12 (MAV_AUTOPILOT_PX4), MAVLink 2; the
  simulator sends from 127.0.0.1:18570 (hfsmc/sim/run.py);
- arming is refused (TEMPORARILY_REJECTED) until the pre-flight checks pass (``boot_time``,
  4.5 s by default), with a STATUSTEXT too long for one message: two chunks, one id;
- modes are ``custom_mode = main << 16 | sub << 24``, set with MAV_CMD_DO_SET_MODE (p1 base
  mode, p2 main, p3 sub), which v1.16 answers twice: ACCEPTED at once, then the real
  result at the next step;
- OFFBOARD needs a setpoint stream (at least 2 Hz for half a second); when it stops for
  COM_OF_LOSS_T (plus the failsafe's detection) the failsafe takes over: POSCTL by
  default (COM_OBL_RC_ACT 0), in which a vehicle without RC sinks at 0.7 m/s and drifts;
  on the ground OFFBOARD is accepted without setpoints, and then no arming is;
- NAV_TAKEOFF takes its altitude AMSL (NaN: MIS_TAKEOFF_ALT); the motors ramp up for
  MPC_TKO_RAMP_T, the climb is at most 1.3 m/s, then AUTO.LOITER by itself;
- NAV_LAND descends at MPC_LAND_SPEED; the land detector decides LAND_DETECT_S after
  touchdown, the motors stop COM_DISARM_LAND later, and the mode goes back to the one
  chosen before LAND (or RTL); armed on the ground without a take-off it disarms after
  COM_DISARM_PRFLT (plus the detector's second).

Everything else (the body, targets in the local and global frames, parameters, the
message-interval commands) is the ArduPilot autopilot's (hfsmc/sim/autopilot.py), whose
seams this class overrides.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, ClassVar

from hfsmc.sim import failsafe
from hfsmc.sim.autopilot import ACCEPTED, DENIED, FAR, UNSUPPORTED, Autopilot, M, _sane
from hfsmc.sim.mission_hooks import Px4Missions
from hfsmc.sim.telemetry import SENSORS, Telemetry
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World

SOURCE_PORT = 18570  # PX4 SITL's UDP port for a ground station's link
TEMPORARILY_REJECTED: int = M.MAV_RESULT_TEMPORARILY_REJECTED


def custom(main: int, sub: int = 0) -> int:
    """PX4's custom_mode for a main mode and a sub-mode."""
    return main << 16 | sub << 24


MANUAL, ALTCTL, POSCTL = custom(1), custom(2), custom(3)
AUTO_READY, TAKEOFF, HOLD, MISSION, RTL, LAND = (custom(4, s) for s in (1, 2, 3, 4, 5, 6))
ACRO, OFFBOARD, STABILIZED = custom(5), custom(6), custom(7)
MODE_NAMES = {MANUAL: "MANUAL", ALTCTL: "ALTCTL", POSCTL: "POSCTL", AUTO_READY: "AUTO.READY",
              TAKEOFF: "AUTO.TAKEOFF", HOLD: "AUTO.LOITER", MISSION: "AUTO.MISSION",
              RTL: "AUTO.RTL", LAND: "AUTO.LAND", ACRO: "ACRO", OFFBOARD: "OFFBOARD",
              STABILIZED: "STABILIZED"}
MANUAL_MODES = frozenset({MANUAL, ALTCTL, POSCTL, ACRO, STABILIZED})  # no RC here: they sink
AUTO_FLAGS = M.MAV_MODE_FLAG_AUTO_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED

STREAM_GAP = 0.5  # s: setpoints further apart than this (under 2 Hz) are not a stream
STREAM_WARMUP = 0.5  # s of stream before OFFBOARD is accepted (one 0.6 s later is)
FAILSAFE_DETECT = 0.4  # s: after COM_OF_LOSS_T, until the failsafe acts (1.2-1.6 s measured)
LAND_DETECT_S = 7.8  # s from touchdown to "landed" (14.8 s from LAND at 4.6 m, measured)
PREFLIGHT_DETECT_S = 1.0  # s the land detector adds to COM_DISARM_PRFLT (11 s measured)
TAKEOFF_CLIMB = 1.3  # m/s: the fastest the take-off climbs (measured, MPC_TKO_SPEED 1.5)
TAKEOFF_ACCEL = 0.5  # m/s²: how the smooth take-off trajectory gains its climb rate
SINK = 0.7  # m/s: POSCTL without RC (the failsafe's default) sinks this fast...
DRIFT = 0.15  # m/s: ...and drifts this fast along the heading it had
ARMING_TEXT = "Arming denied: Resolve system health failures first"  # 51 characters: 2 chunks
OFFBOARD_ARM_TEXT = "Arming denied: offboard control signal not present"


class Px4Telemetry(Telemetry):
    """PX4's streams: seven at 50 Hz (about 366 messages a second), no EKF_STATUS_REPORT
    (an ArduPilot message), and EXTENDED_SYS_STATE with the land detector's verdict."""

    RATES: ClassVar[dict[str, float]] = {"HEARTBEAT": 1.0, "SYS_STATUS": 5.0, "GPS_RAW_INT": 5.0,
             "EXTENDED_SYS_STATE": 5.0, "ATTITUDE": 50.0, "ATTITUDE_QUATERNION": 50.0,
             "LOCAL_POSITION_NED": 50.0, "GLOBAL_POSITION_INT": 50.0, "ALTITUDE": 50.0,
             "VFR_HUD": 50.0, "HOME_POSITION": 0.0, "POSITION_TARGET_LOCAL_NED": 50.0,
             "BATTERY_STATUS": 0.5}

    def __init__(self, ap: Px4) -> None:
        super().__init__(ap)
        self.px4 = ap
        self.defaults = dict(self.RATES)
        self.intervals = {name: self.steps(hz) for name, hz in self.RATES.items()}
        self._senders.update({"EXTENDED_SYS_STATE": self._extended, "ALTITUDE": self._altitude,
                              "ATTITUDE_QUATERNION": self._quaternion,
                              "POSITION_TARGET_LOCAL_NED": self._target})
        del self._senders["EKF_STATUS_REPORT"]

    def set_interval(self, msg_id: int, us: float) -> bool:
        name = self._stream(msg_id)
        if name is not None and us == 0:
            self.intervals[name] = self.steps(self.RATES[name])
            return True
        return super().set_interval(msg_id, us)

    def _heartbeat(self) -> None:
        ap, b = self.px4, self.px4.body
        base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if ap.mode in (TAKEOFF, HOLD, MISSION, RTL, LAND, AUTO_READY):
            base |= AUTO_FLAGS | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        elif ap.mode == OFFBOARD:
            base |= M.MAV_MODE_FLAG_GUIDED_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        else:
            base |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        if b.armed:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
        state = M.MAV_STATE_ACTIVE if b.armed else M.MAV_STATE_STANDBY
        if ap.failsafe:
            state = M.MAV_STATE_CRITICAL
        ap.mav.heartbeat_send(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, base, ap.mode, state, 3)

    def _sys_status(self) -> None:
        """PX4 sets MAV_SYS_STATUS_PREARM_CHECK in the health bits once it would arm."""
        ap, b = self.px4, self.px4.body
        sensors = SENSORS | M.MAV_SYS_STATUS_PREARM_CHECK
        health = sensors if ap.ready else sensors & ~(M.MAV_SYS_STATUS_SENSOR_GPS
                                                      | M.MAV_SYS_STATUS_PREARM_CHECK)
        ap.mav.sys_status_send(sensors, sensors, health, 200, round(b.voltage * 1000),
                               round(b.current * 100), round(100 * b.battery_fraction),
                               0, 0, 0, 0, 0, 0)

    def _extended(self) -> None:
        self.px4.mav.extended_sys_state_send(M.MAV_VTOL_STATE_UNDEFINED, self.px4.landed_state)

    def _altitude(self) -> None:
        ap, b = self.px4, self.px4.body
        amsl = ap.world.home.alt + b.altitude
        ap.mav.altitude_send(round(b.t * 1e6), amsl, amsl, b.altitude, b.altitude, math.nan,
                             math.nan)

    def _quaternion(self) -> None:
        b = self.px4.body
        roll, pitch = b.attitude()
        cr, sr = math.cos(roll / 2), math.sin(roll / 2)
        cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
        cy, sy = math.cos(b.yaw / 2), math.sin(b.yaw / 2)
        self.px4.mav.attitude_quaternion_send(
            self._ms(), cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy, 0.0, 0.0, b.yaw_rate)

    def _local_position(self) -> None:
        """SIH's estimator has a local position from the start (ArduPilot waits for GPS)."""
        b = self.px4.body
        n, e, d = b.reported_position()
        vn, ve, vd = b.reported_velocity()
        self.px4.mav.local_position_ned_send(self._ms(), n, e, d, vn, ve, vd)

    def _target(self) -> None:
        b = self.px4.body
        n, e, d = b.goal
        vn, ve, vd = b.vel_cmd
        self.px4.mav.position_target_local_ned_send(self._ms(), M.MAV_FRAME_LOCAL_NED, 0, n, e, d,
                                                    vn, ve, vd, 0, 0, 0, b.yaw, 0)

    def _version(self) -> None:
        caps = (M.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT)
        version = (1 << 24) | (16 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_OFFICIAL
        self.px4.mav.autopilot_version_send(caps, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                                            0, 0, 1)


class Px4(Px4Missions, Autopilot):
    """PX4's modes, commands, answers and failsafes over the same body as ArduPilot's."""

    TYPE = M.MAV_AUTOPILOT_PX4

    def __init__(self, world: World, body: Body, out: Callable[[bytes], None], *,
                 boot_time: float = 4.5, log: Callable[[str], None] = lambda s: None) -> None:
        super().__init__(world, body, out, boot_time=boot_time, log=log)
        self.mode = HOLD  # no RC: PX4 boots into Hold
        self.user_mode = HOLD  # the mode last chosen (by a command), restored after a landing
        self.failsafe = ""  # why the failsafe took over, while it holds
        self.sp_first = self.sp_last = -math.inf  # the setpoint stream: its start, its latest
        self.ever_flew = False  # since arming: the pre-flight auto-disarm applies until then
        self.detected_landed = True  # the land detector's verdict (lags the touchdown)
        self._late_acks: list[tuple[int, int, int, int]] = []  # DO_SET_MODE's second answer
        self._second: int | None = None  # the second answer of the command being handled
        self._text_id = 0
        self._commands.update({
            M.MAV_CMD_NAV_LAND: lambda p: self._auto_mode(LAND),
            M.MAV_CMD_NAV_RETURN_TO_LAUNCH: lambda p: self._auto_mode(RTL),
            M.MAV_CMD_DO_SET_MODE: self._cmd_do_set_mode,
            M.MAV_CMD_CONDITION_YAW: lambda p: UNSUPPORTED,  # PX4 has no CONDITION_YAW
        })
        self.telemetry = Px4Telemetry(self)

    @staticmethod
    def default_params(world: World) -> dict[str, float]:
        """PX4 v1.16's defaults (docs/worlds.md); the world's vehicle limits cap them."""
        cfg = world.vehicle
        return {
            "MAV_SYS_ID": 1, "MPC_XY_VEL_MAX": min(12.0, cfg.max_speed),
            "MPC_XY_CRUISE": min(5.0, cfg.max_speed), "MPC_Z_VEL_MAX_UP": 3.0,
            "MPC_Z_VEL_MAX_DN": 1.5, "MPC_ACC_HOR": min(3.0, cfg.max_accel),
            "MPC_TKO_SPEED": 1.5, "MPC_TKO_RAMP_T": 3.0, "MPC_LAND_SPEED": 0.7,
            "MPC_LAND_ALT1": 10.0, "MPC_LAND_ALT2": 5.0, "MIS_TAKEOFF_ALT": 2.5,
            "COM_DISARM_LAND": 2.0, "COM_DISARM_PRFLT": 10.0, "COM_OF_LOSS_T": 1.0,
            "COM_OBL_RC_ACT": 0, "RTL_RETURN_ALT": 60.0, "RTL_DESCEND_ALT": 30.0,
            "RTL_CONE_ANG": 45.0, "NAV_ACC_RAD": 2.0, "GF_ACTION": 2, **failsafe.PX4_PARAMS,
        }

    def _apply_params(self) -> None:
        b, cfg, p = self.body, self.world.vehicle, self.params
        b.speed_xy = max(0.1, min(p["MPC_XY_CRUISE"], p["MPC_XY_VEL_MAX"], cfg.max_speed))
        b.speed_up = max(0.1, min(p["MPC_Z_VEL_MAX_UP"], cfg.max_climb))
        b.speed_down = max(0.1, min(p["MPC_Z_VEL_MAX_DN"], cfg.max_climb))
        b.land_speed = max(0.1, min(p["MPC_LAND_SPEED"], b.speed_down))
        b.land_speed_high = b.speed_down  # above MPC_LAND_ALT2 PX4 descends faster
        b.land_alt_low = max(0.0, p["MPC_LAND_ALT2"])
        b.accel = max(0.1, min(p["MPC_ACC_HOR"], cfg.max_accel))
        b.accel_z = max(0.1, min(1.0, cfg.max_accel))

    # -- the loop -------------------------------------------------------------------

    def step(self) -> None:
        b = self.body
        for cmd, result, system, component in self._late_acks:
            self.mav.command_ack_send(cmd, result, 0, 0, system, component)
        self._late_acks = []
        if not self.ready and b.t >= self.boot_time:
            self.ready = True
            self.log("ready (pre-flight checks pass)")
            self.text(M.MAV_SEVERITY_INFO, "Ready for takeoff!")
            self.telemetry.send("HOME_POSITION")
        self.telemetry.send_due()
        self.missions.tick()
        self._update()
        for event in b.step():
            self._on_event(event)
        if self.mode == TAKEOFF and self.climbing_to is not None and b.nav == "goto" \
                and b.goal[2] < 0 and b.arrived(0.1):
            self.log(f"take-off complete ({self.climbing_to:.1f} m)")
            goal = b.goal
            self._enter(HOLD)
            b.goto(*goal)  # Hold where the take-off was going, not where it is

    @property
    def landed_state(self) -> int:
        """EXTENDED_SYS_STATE's MAV_LANDED_STATE."""
        b = self.body
        if self.detected_landed:
            return int(M.MAV_LANDED_STATE_ON_GROUND)
        if self.mode == TAKEOFF:
            return int(M.MAV_LANDED_STATE_TAKEOFF)
        if self.mode == LAND or (self.mode == RTL and self.rtl_stage == "land"):
            return int(M.MAV_LANDED_STATE_LANDING)
        return int(M.MAV_LANDED_STATE_IN_AIR if not b.landed else M.MAV_LANDED_STATE_ON_GROUND)

    def _update(self) -> None:
        b, t, p = self.body, self.body.t, self.params
        if self.mode == TAKEOFF and self.climbing_to is not None and b.armed and b.landed \
                and b.goal[2] == 0.0 and t >= self.spooled_at - 1e-9:
            b.goto(b.north, b.east, -self.climbing_to)  # ramped up: climb
        if self.mode == RTL:
            self._rtl_update()
        if self.mode == MISSION:
            self.auto_step()
        if self.mode == OFFBOARD and b.armed and \
                t - self.sp_last > p["COM_OF_LOSS_T"] + FAILSAFE_DETECT:
            self._offboard_lost()
        if self.mode in MANUAL_MODES and b.armed and not b.landed:
            c, s = math.cos(b.yaw), math.sin(b.yaw)  # no stick input: sink and drift
            b.fly_velocity(DRIFT * c, DRIFT * s, SINK)
        if b.armed and b.landed and not self.detected_landed and \
                t - self.landed_since >= LAND_DETECT_S - 1e-9:
            self.detected_landed = True
            self.log("land detector: landed")
        if b.armed and b.landed and self.detected_landed:
            idle = t - self.landed_since
            if self.ever_flew and idle >= LAND_DETECT_S + p["COM_DISARM_LAND"] - 1e-9:
                self._disarm("landed")
            elif not self.ever_flew and self.mode != TAKEOFF and \
                    idle >= p["COM_DISARM_PRFLT"] + PREFLIGHT_DETECT_S > PREFLIGHT_DETECT_S:
                self._disarm(f"auto-disarm after {idle:.0f} s on the ground")
        if b.armed and not b.landed and b.energy_wh <= 0 and self.mode != LAND:
            self.text(M.MAV_SEVERITY_CRITICAL, "Failsafe: battery empty, landing")
            self._enter(LAND)
        self._battery_failsafe()

    def battery_grade(self) -> int:
        return failsafe.px4_level(self.params, self.body.battery_fraction)

    def battery_action(self, level: int) -> tuple[str, int]:
        mode = {"LAND": LAND, "RTL": RTL}.get(failsafe.px4_action(self.params, level), -1)
        return failsafe.PX4_TEXT[level], mode

    def _failsafe_mode(self, mode: int) -> None:
        self.failsafe = "battery"
        self._enter(mode)

    def _on_event(self, event: str) -> None:
        super()._on_event(event)
        if event == "liftoff":
            self.ever_flew = True
            self.detected_landed = False

    def _disarm(self, why: str) -> None:
        super()._disarm(why)
        if self.mode in (LAND, RTL) or self.failsafe:
            self.failsafe = ""
            self._enter(self.user_mode if self.user_mode not in (LAND, RTL) else HOLD)

    # -- modes --------------------------------------------------------------------------

    @property
    def navigating(self) -> bool:
        return self.mode not in MANUAL_MODES

    @property
    def mode_name(self) -> str:
        return MODE_NAMES.get(self.mode, f"0x{self.mode:08x}")

    def offboard_available(self) -> bool:
        """A setpoint stream: at least 2 Hz, for STREAM_WARMUP s, the latest recent."""
        t = self.body.t
        return t - self.sp_last <= STREAM_GAP and t - self.sp_first >= STREAM_WARMUP - 1e-9

    def set_mode(self, mode: int) -> bool:
        """A mode chosen by command; False (and a STATUSTEXT) when refused."""
        if mode == self.mode:
            return True
        name = MODE_NAMES.get(mode)
        if name is None:
            return False
        b = self.body
        if not self.ready and mode not in MANUAL_MODES:
            self.text(M.MAV_SEVERITY_CRITICAL, f"Switching to {name} is currently not possible")
            return False
        if mode == OFFBOARD and (b.armed or not b.landed) and not self.offboard_available():
            self.text(M.MAV_SEVERITY_CRITICAL, "Switching to Offboard is currently not possible")
            return False
        if mode == TAKEOFF:
            return self._takeoff(math.nan)
        why = self.auto_refusal() if mode == MISSION else ""
        if why:
            self.text(M.MAV_SEVERITY_CRITICAL, why)
            return False
        self.user_mode = mode
        self.failsafe = ""
        self._enter(mode)
        return True

    def _enter(self, mode: int) -> None:
        """Fly a mode (chosen, by itself after a take-off, or by a failsafe)."""
        self.mode = mode
        b = self.body
        if mode != TAKEOFF:
            self.climbing_to = None
            self._apply_params()  # the take-off's own climb limits end with it
        self.rtl_stage = ""
        if mode == LAND:
            b.land()
        elif mode == RTL:
            self._rtl_start()
        elif mode in (HOLD, OFFBOARD, AUTO_READY, MISSION):
            b.hold()
            if mode == MISSION:
                self.missions.restart_if_done()  # OFFBOARD flies the latest setpoint from the next one on
        b.hold_heading()
        self.log(f"mode {MODE_NAMES.get(mode, mode)}")

    def _auto_mode(self, mode: int) -> int:
        if not self.ready:
            return TEMPORARILY_REJECTED
        return ACCEPTED if self.set_mode(mode) else TEMPORARILY_REJECTED

    def _cmd_do_set_mode(self, p: tuple[float, ...]) -> int:
        """v1.16 answers ACCEPTED at once, the real result at the next step."""
        if not int(p[0]) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return DENIED
        mode = custom(int(p[1]), int(p[2]) if int(p[1]) == 4 else 0)
        ok = mode in MODE_NAMES and self.set_mode(mode)
        self._second = DENIED if mode not in MODE_NAMES else ACCEPTED if ok else \
            TEMPORARILY_REJECTED
        return ACCEPTED

    def _set_mode_common(self, base_mode: int, custom_mode: int) -> int:
        """SET_MODE (the message): one answer."""
        if not base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or custom_mode not in MODE_NAMES:
            return DENIED
        return ACCEPTED if self.set_mode(custom_mode) else TEMPORARILY_REJECTED

    def _command(self, m: Any, p: tuple[float, ...]) -> None:
        self._second = None
        super()._command(m, p)
        if self._second is not None:
            self._late_acks.append((m.command, self._second, m.get_srcSystem(),
                                    m.get_srcComponent()))

    def _offboard_lost(self) -> None:
        action = int(self.params["COM_OBL_RC_ACT"])
        mode = {0: POSCTL, 1: ALTCTL, 2: MANUAL, 3: RTL, 4: LAND, 5: HOLD}.get(action, POSCTL)
        self.failsafe = "offboard signal lost"
        self.text(M.MAV_SEVERITY_CRITICAL,
                  f"Failsafe activated: no offboard signal, switching to {MODE_NAMES[mode]}")
        self.log(f"failsafe: no setpoint for {self.body.t - self.sp_last:.1f} s")
        self._enter(mode)

    # -- commands -----------------------------------------------------------------------

    def _cmd_arm(self, p: tuple[float, ...]) -> int:
        b = self.body
        if p[0] == 1.0 and not b.armed:
            if not self.ready:
                self.text(M.MAV_SEVERITY_CRITICAL, ARMING_TEXT)
                return TEMPORARILY_REJECTED
            if self.mode == OFFBOARD and not self.offboard_available():
                self.text(M.MAV_SEVERITY_CRITICAL, OFFBOARD_ARM_TEXT)
                return TEMPORARILY_REJECTED
            if self.mode in (LAND, RTL):
                self.text(M.MAV_SEVERITY_CRITICAL, "Arming denied: not in an armable mode")
                return TEMPORARILY_REJECTED
            b.armed = True
            self.ever_flew = False
            self.detected_landed = True
            self.landed_since = b.t
            self.log("armed")
            if self.mode == TAKEOFF and self.climbing_to is not None:
                self.spooled_at = b.t + max(0.0, self.params["MPC_TKO_RAMP_T"])
            else:
                b.hold()
            return ACCEPTED
        if p[0] == 0.0 and b.armed and not b.landed and p[1] != 21196.0:
            self.text(M.MAV_SEVERITY_CRITICAL, "Disarming denied: not landed")
            return TEMPORARILY_REJECTED
        return super()._cmd_arm(p) if p[0] in (0.0, 1.0) else UNSUPPORTED

    def _cmd_takeoff(self, p: tuple[float, ...]) -> int:
        if not self.ready:
            return TEMPORARILY_REJECTED
        amsl = p[6]
        if math.isnan(amsl):
            return ACCEPTED if self._takeoff(math.nan) else TEMPORARILY_REJECTED
        if not _sane(FAR, amsl):
            return DENIED
        return ACCEPTED if self._takeoff(amsl - self.world.home.alt) else TEMPORARILY_REJECTED

    def _takeoff(self, alt: float) -> bool:
        """AUTO.TAKEOFF to ``alt`` m above home (NaN: MIS_TAKEOFF_ALT)."""
        b = self.body
        if not b.landed:
            return False
        if math.isnan(alt):
            alt = self.params["MIS_TAKEOFF_ALT"]
        if alt <= 0.5:
            self.text(M.MAV_SEVERITY_CRITICAL, "Takeoff altitude too low")
            return False
        self.user_mode = HOLD
        self.failsafe = ""
        self._enter(TAKEOFF)
        b.goto(b.north, b.east, 0.0)
        self.climbing_to = alt
        self.spooled_at = b.t + max(0.0, self.params["MPC_TKO_RAMP_T"])
        b.speed_up = max(0.1, min(TAKEOFF_CLIMB, self.params["MPC_TKO_SPEED"], b.speed_up))
        b.accel_z = TAKEOFF_ACCEL
        self.log(f"take-off to {alt:.1f} m")
        return True

    def _rtl_start(self) -> None:
        b, p = self.body, self.params
        if b.landed:
            self.rtl_stage = "land"
            b.land()
            return
        dist = math.hypot(b.north, b.east)
        cone = math.tan(math.radians(max(1.0, min(89.0, p["RTL_CONE_ANG"]))))
        # the cone lowers the return near home, never below RTL_DESCEND_ALT (nor above
        # RTL_RETURN_ALT, which may be the lower of the two)
        floor = min(p["RTL_DESCEND_ALT"], p["RTL_RETURN_ALT"])
        wanted = max(floor, min(p["RTL_RETURN_ALT"], dist / cone))
        self.rtl_alt = max(b.altitude, wanted)
        n, e, _ = b.stopping_point()
        b.goto(n, e, -self.rtl_alt)
        self.rtl_stage = "climb"

    def _rtl_update(self) -> None:
        b = self.body
        if self.rtl_stage == "climb" and b.arrived(0.3):
            b.goto(0.0, 0.0, -self.rtl_alt)
            b.face_travel()
            self.rtl_stage = "return"
        elif self.rtl_stage == "return" and b.arrived(0.3):
            self.rtl_stage = "land"
            b.hold_heading()
            b.land()

    # -- setpoints ----------------------------------------------------------------------

    def _accepts_targets(self, m: Any) -> bool:
        """Every setpoint counts for the stream; only OFFBOARD flies it."""
        if not self._for_me(m):
            return False
        t = self.body.t
        if t - self.sp_last > STREAM_GAP:
            self.sp_first = t
        self.sp_last = t
        return self.mode == OFFBOARD and self.body.armed

    def _target_yaw(self, mask: int, yaw: float, rate: float, relative: bool) -> None:
        """PX4 keeps its heading when a setpoint gives neither yaw nor yaw rate."""
        use_yaw = not mask & M.POSITION_TARGET_TYPEMASK_YAW_IGNORE and math.isfinite(yaw)
        use_rate = not mask & M.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE and math.isfinite(rate)
        if use_yaw or use_rate:
            super()._target_yaw(mask, yaw, rate, relative)
        else:
            self.body.hold_heading()

    def text(self, severity: int, text: str) -> None:
        """A STATUSTEXT; longer than 50 bytes, in chunks of one id (as PX4 sends them)."""
        data = text.encode()
        if len(data) <= 50:
            self.mav.statustext_send(severity, data)
            return
        self._text_id = self._text_id % 0xFFFF + 1
        for seq, start in enumerate(range(0, len(data), 50)):
            self.mav.statustext_send(severity, data[start:start + 50], self._text_id, seq)

    def _text(self, severity: int, text: str) -> None:
        self.text(severity, text)

