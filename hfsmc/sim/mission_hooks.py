"""What each simulated autopilot does with its missions and fence (hfsmc/sim/missions.py):
the ``Host`` hooks, mixed into the ArduPilot autopilot (``ArduPilotMissions``) and PX4's
(``Px4Missions``), whose attributes they use.

- ArduPilot: AUTO (custom mode 3) needs a mission (item 0 is home) and, armed on the
  ground, one that starts with a take-off; its RTL and LAND items run inside AUTO; at
  the end it holds where it is. The fence is on with DO_FENCE_ENABLE 1 (or FENCE_ENABLE
  1), refused (FAILED) without a fence uploaded; a breach does FENCE_ACTION (0 report, 1
  and 3 RTL, 2 LAND, 4 BRAKE, 5 LAND) and a GUIDED target outside the fence is ignored
  (Copter's ``check_destination_within_fence``).
- PX4: AUTO.MISSION needs a mission; its RTL item is the RTL mode; at the end it holds
  (AUTO.LOITER). The fence is on as soon as one is uploaded (GF_ACTION 0 turns it off);
  DO_FENCE_ENABLE is UNSUPPORTED; a breach does GF_ACTION (1 a warning, 2 Hold, 3 RTL,
  4 flight termination, simulated as LAND and said so, 5 LAND); a setpoint outside the
  fence is flown, and breaches.
"""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from hfsmc.sim.missions import MISSION, TAKEOFF, Missions
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World

AUTO, AP_RTL, AP_LAND, AP_BRAKE = 3, 6, 9, 17  # Copter's (hfsmc/sim/autopilot.py)
PX4_HOLD, PX4_RTL, PX4_LAND = (s << 24 | 4 << 16 for s in (3, 5, 6))  # hfsmc/sim/px4.py
PX4_NAMES = {PX4_HOLD: "AUTO.LOITER", PX4_RTL: "AUTO.RTL", PX4_LAND: "AUTO.LAND"}
ACCEPTED, FAILED, UNSUPPORTED = (int(M.MAV_RESULT_ACCEPTED), int(M.MAV_RESULT_FAILED),
                                 int(M.MAV_RESULT_UNSUPPORTED))
MISSION_MESSAGES = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_REQUEST_LIST",
                    "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT")


class ArduPilotMissions:
    """ArduPilot Copter's side (mixed into hfsmc.sim.autopilot.Autopilot)."""

    px4 = False
    missions: Missions
    mav: Any
    body: Body
    world: World
    params: dict[str, float]
    mode: int
    rtl_stage: str
    _handlers: dict[str, Any]
    _commands: dict[int, Any]
    log: Any
    _text: Any
    _rtl_start: Any
    set_mode: Any
    _for_me: Any

    def _missions_init(self) -> None:
        self.missions = Missions(self)
        for name in MISSION_MESSAGES:
            self._handlers[name] = self._on_mission_message
        self._commands[int(M.MAV_CMD_DO_FENCE_ENABLE)] = self._cmd_fence_enable

    def _on_mission_message(self, m: Any) -> None:
        if self._for_me(m):
            self.missions.on_message(m.get_type(), m)

    def status(self, severity: int, text: str) -> None:
        self._text(severity, text)

    def mission_landed(self) -> None:
        self.log("mission: landing")

    def mission_rtl(self) -> None:
        self.log("mission: return to launch")
        self._rtl_start()

    def mission_done(self) -> None:
        self._text(int(M.MAV_SEVERITY_INFO), "Mission complete")
        if not self.body.landed and not self.missions.landing:
            self.body.hold()

    def default_radius(self) -> float:
        return max(0.05, self.params["WPNAV_RADIUS"] / 100.0)

    def fence_on(self) -> bool:
        return self.params["FENCE_ENABLE"] != 0

    def fence_action(self) -> None:
        action = int(self.params["FENCE_ACTION"])
        self._text(int(M.MAV_SEVERITY_CRITICAL), "Fence Breached")
        target = {1: "RTL", 2: "LAND", 3: "RTL", 4: "BRAKE", 5: "LAND"}.get(action)
        if target is None or self.body.landed:
            return
        mode = {"RTL": AP_RTL, "LAND": AP_LAND, "BRAKE": AP_BRAKE}[target]
        if self.mode not in (AP_LAND, mode):
            self.log(f"fence: {target} (FENCE_ACTION {action})")
            self.set_mode(mode)

    def fence_refuses(self, north: float, east: float) -> bool:
        """A GUIDED position target outside the fence: Copter ignores it."""
        if self.missions.fence_active() and self.missions.outside(north, east):
            self.log(f"guided target north {north:.1f} m, east {east:.1f} m is outside the "
                     "fence: ignored")
            return True
        return False

    def _cmd_fence_enable(self, p: tuple[float, ...]) -> int:
        if p[0] == 0:
            self.params["FENCE_ENABLE"] = 0
            return ACCEPTED
        if p[0] == 1:
            if not self.missions.plans[1]:
                return FAILED  # nothing to enable
            self.params["FENCE_ENABLE"] = 1
            return ACCEPTED
        return FAILED

    def auto_refusal(self) -> str:
        """Why AUTO may not start now ("" when it may)."""
        plan = self.missions.plans[MISSION]
        if len(plan) <= 1:
            return "Mode change to AUTO failed: no mission"
        b = self.body
        first = next((i for i in plan[1:] if i.command != 115), None)
        if b.armed and b.landed and (first is None or first.command != TAKEOFF):
            return "Auto: Missing Takeoff Cmd"
        return ""

    def auto_step(self) -> None:
        """AUTO's work each step (the mission, its landing, its RTL)."""
        self.missions.fly()
        self.missions.landing_step()


class Px4Missions(ArduPilotMissions):
    """PX4's side (mixed into hfsmc.sim.px4.Px4, before the ArduPilot one)."""

    px4 = True
    _enter: Any
    user_mode: int
    failsafe: str
    text: Any

    def _missions_init(self) -> None:
        super()._missions_init()
        self._commands[int(M.MAV_CMD_DO_FENCE_ENABLE)] = lambda p: UNSUPPORTED

    def mission_rtl(self) -> None:
        self.log("mission: return to launch (RTL mode)")
        self._enter(PX4_RTL)

    def mission_done(self) -> None:
        self.text(int(M.MAV_SEVERITY_INFO), "Mission finished")
        if not self.body.landed and not self.missions.landing:
            self.user_mode = PX4_HOLD
            self._enter(PX4_HOLD)

    def default_radius(self) -> float:
        return max(0.05, self.params["NAV_ACC_RAD"])

    def fence_on(self) -> bool:
        return self.params["GF_ACTION"] != 0

    def fence_action(self) -> None:
        action = int(self.params["GF_ACTION"])
        mode = {2: PX4_HOLD, 3: PX4_RTL, 4: PX4_LAND, 5: PX4_LAND}.get(action)
        what = {1: "warning only", 2: "holding", 3: "returning", 4: "flight termination "
                "(simulated as a landing)", 5: "landing"}.get(action, "")
        self.text(int(M.MAV_SEVERITY_CRITICAL), f"Geofence breached, {what}")
        if mode is None or self.body.landed or self.mode in (PX4_LAND, mode):
            return
        self.log(f"fence: {PX4_NAMES[mode]} (GF_ACTION {action})")
        self.failsafe = "geofence"
        self._enter(mode)

    def fence_refuses(self, north: float, east: float) -> bool:
        return False  # PX4 flies it, and breaches

    def auto_refusal(self) -> str:
        if not self.missions.plans[MISSION]:
            return "Switching to Mission is currently not possible: no valid mission"
        return ""
