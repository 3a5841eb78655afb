"""The simulated autopilots' battery failsafe (docs/worlds.md, "Battery failsafe").

Both autopilots grade the battery (OK, low, critical, emergency), say it once per level
in a STATUSTEXT, report it in BATTERY_STATUS.charge_state, and act as their parameters
say. A level once reached stays (both autopilots latch it until they reboot), so a
voltage that recovers when the load drops does not flap the failsafe.

- ArduPilot Copter grades the voltage under load: BATT_LOW_VOLT, BATT_CRT_VOLT (the
  simulator's 4S pack: 14.0 V and 13.8 V, about 14 % and 7 % left in a hover), and acts
  with BATT_FS_LOW_ACT and BATT_FS_CRT_ACT (0 nothing, as ArduPilot's default; 1 LAND;
  2 RTL; 3 and 4, SmartRTL, are RTL here).
- PX4 grades the charge left: BAT_LOW_THR 0.15, BAT_CRIT_THR 0.07, BAT_EMERGEN_THR 0.05,
  and acts with COM_LOW_BAT_ACT (0 a warning only, its default; 2 Land at critical; 3
  Return at critical, Land at emergency). Emergency always lands.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

OK, LOW, CRITICAL, EMERGENCY = 0, 1, 2, 3
CHARGE_STATE = {OK: M.MAV_BATTERY_CHARGE_STATE_OK, LOW: M.MAV_BATTERY_CHARGE_STATE_LOW,
                CRITICAL: M.MAV_BATTERY_CHARGE_STATE_CRITICAL,
                EMERGENCY: M.MAV_BATTERY_CHARGE_STATE_EMERGENCY}
ARDUPILOT_PARAMS = {"BATT_LOW_VOLT": 14.0, "BATT_CRT_VOLT": 13.8, "BATT_FS_LOW_ACT": 0,
                    "BATT_FS_CRT_ACT": 0}
PX4_PARAMS = {"BAT_LOW_THR": 0.15, "BAT_CRIT_THR": 0.07, "BAT_EMERGEN_THR": 0.05,
              "COM_LOW_BAT_ACT": 0}


def ardupilot_level(params: dict[str, float], voltage: float) -> int:
    """The level ArduPilot's thresholds give a voltage (0 V thresholds are off)."""
    if 0 < voltage <= params["BATT_CRT_VOLT"]:
        return CRITICAL
    if 0 < voltage <= params["BATT_LOW_VOLT"]:
        return LOW
    return OK


def ardupilot_action(params: dict[str, float], level: int) -> str:
    """The mode ArduPilot switches to on reaching a level: "", "LAND" or "RTL"."""
    action = int(params["BATT_FS_CRT_ACT" if level >= CRITICAL else "BATT_FS_LOW_ACT"])
    return {1: "LAND", 2: "RTL", 3: "RTL", 4: "RTL"}.get(action, "")


def px4_level(params: dict[str, float], fraction: float) -> int:
    """The level PX4's thresholds give the charge left (0..1)."""
    if fraction <= params["BAT_EMERGEN_THR"]:
        return EMERGENCY
    if fraction <= params["BAT_CRIT_THR"]:
        return CRITICAL
    if fraction <= params["BAT_LOW_THR"]:
        return LOW
    return OK


def px4_action(params: dict[str, float], level: int) -> str:
    """The mode PX4 switches to on reaching a level: "", "LAND" or "RTL"."""
    action = int(params["COM_LOW_BAT_ACT"])
    if level >= EMERGENCY:
        return "LAND"
    if level >= CRITICAL:
        return {2: "LAND", 3: "RTL"}.get(action, "")
    return ""


ARDUPILOT_TEXT = {LOW: "Battery 1 is low", CRITICAL: "Battery 1 is critical"}
PX4_TEXT = {LOW: "Low battery level! Return advised",
            CRITICAL: "Critical battery level! Land now!",
            EMERGENCY: "Dangerously low battery level! Landing immediately"}
