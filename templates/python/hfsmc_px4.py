"""What the ``mavlink`` interface does differently on PX4 (docs/interfaces.md, "PX4 and
ArduPilot"): copied beside a component with hfsmc_mavlink.py, which uses it once a
HEARTBEAT says autopilot 12 (or the option ``autopilot: px4`` says so).

- Mode names: PX4's ``custom_mode`` is ``main << 16 | sub << 24``. The names that
  ArduPilot has too mean the same thing: ``GUIDED`` is OFFBOARD (the ground station flies
  the vehicle), ``LAND``, ``RTL``, ``AUTO`` (the mission); PX4's own are ``HOLD``
  (AUTO.LOITER), ``TAKEOFF``, ``POSCTL``, ``ALTCTL``, ``MANUAL``, ``STABILIZED``,
  ``ACRO``, ``READY``, ``FOLLOW``, ``PRECLAND``.
- OFFBOARD needs a setpoint stream (2 Hz at least) before PX4 accepts it and falls to a
  failsafe when the stream stops: ``Offboard`` keeps the snippet's latest target going at
  10 Hz from the driver's own thread, and switches to OFFBOARD once the stream has run
  for 0.6 s, but only while the model has asked for GUIDED (``set_mode("GUIDED")`` or a
  take-off). When PX4 leaves OFFBOARD by itself (a failsafe, a pilot), the driver stops:
  it never fights the autopilot; ``set_mode("GUIDED")`` takes the vehicle back. An
  accepted switch counts as OFFBOARD reached even when no HEARTBEAT said so before the
  link dropped (PX4 sends one a second): a later HEARTBEAT in another mode is PX4 leaving.
- STATUSTEXT may come in chunks (one id, ``chunk_seq`` 0, 1, ...): ``Texts`` joins them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

AUTOPILOT_PX4 = 12  # MAV_AUTOPILOT_PX4
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_LAND, MAV_CMD_NAV_RETURN_TO_LAUNCH = 22, 21, 20
MAV_CMD_COMPONENT_ARM_DISARM = 400
RESULTS: dict[int, str] = {}  # MAV_RESULT names, filled in by hfsmc_mavlink
MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_FRAME_BODY_NED = 8  # PX4 turns velocities in this frame by the heading
RESEND_S = 0.1  # the stream's period when the snippet sends less often (10 Hz)
WARMUP_S = 0.6  # stream this long before asking for OFFBOARD (PX4 wants 0.5 s)
SWITCH_RETRY_S = 1.0  # a refused switch is asked again after this
SETTLE_S = 0.5  # a HEARTBEAT this long after an accepted switch shows PX4's real mode
TEXT_WAIT_S = 1.0  # a chunked STATUSTEXT whose last chunk never comes is said as it is
SEVERITY_WARNING = 4  # STATUSTEXT severities up to this one are said on stderr
MODE_FLAG_SAFETY_ARMED = 128  # HEARTBEAT.base_mode


def custom(main: int, sub: int = 0) -> int:
    """PX4's custom_mode for a main mode and a sub-mode."""
    return main << 16 | sub << 24


OFFBOARD, HOLD, TAKEOFF = custom(6), custom(4, 3), custom(4, 2)
MODES = {  # name -> custom_mode
    "GUIDED": OFFBOARD, "HOLD": HOLD, "TAKEOFF": TAKEOFF, "LAND": custom(4, 6),
    "RTL": custom(4, 5), "AUTO": custom(4, 4), "READY": custom(4, 1), "FOLLOW": custom(4, 8),
    "PRECLAND": custom(4, 9), "POSCTL": custom(3), "ALTCTL": custom(2), "MANUAL": custom(1),
    "ACRO": custom(5), "STABILIZED": custom(7),
}
ALIASES = {"OFFBOARD": "GUIDED", "LOITER": "HOLD", "MISSION": "AUTO"}  # PX4's own spellings
NAMES = {number: name for name, number in MODES.items()}


def mode_name(custom_mode: int) -> str:
    """The driver's name of a PX4 custom_mode."""
    return NAMES.get(custom_mode, f"MODE{custom_mode:#010x}")


def mode_number(name: str) -> int | None:
    """A mode name (any case, PX4's spellings too) as PX4's custom_mode; None if PX4 lacks it."""
    wanted = name.strip().upper()
    return MODES.get(ALIASES.get(wanted, wanted))


def checked_mode(vehicle: str, name: str) -> int:
    """PX4's custom_mode for a mode name; ValueError naming PX4's modes if it lacks it."""
    number = mode_number(name)
    if number is None:
        raise ValueError(f"{vehicle}: PX4 has no mode `{name}` (modes: {', '.join(MODES)})")
    return number


def set_mode_params(custom_mode: int) -> tuple[float, float, float]:
    """MAV_CMD_DO_SET_MODE's p1, p2 (main) and p3 (sub) for a custom_mode."""
    return (float(MODE_FLAG_CUSTOM_MODE_ENABLED), float(custom_mode >> 16 & 0xFF),
            float(custom_mode >> 24 & 0xFF))


class Offboard:
    """The setpoint stream and the OFFBOARD switch of one vehicle. ``send`` sends a
    target again (its arguments as given to ``target``); ``switch`` asks for OFFBOARD;
    ``say`` writes a line on stderr."""

    def __init__(self, send: Callable[..., None], switch: Callable[[], None],
                 say: Callable[[str], None]) -> None:
        self.send, self.switch, self.say = send, switch, say
        self.wanted = False  # the model asked for GUIDED: targets put the vehicle in OFFBOARD
        self.args: tuple[Any, ...] | None = None  # the latest target
        self.started = math.inf  # when the stream (re)started
        self.sent_at = -math.inf
        self.asked_at = -math.inf
        self.mode = -1  # the vehicle's mode at the last look
        self.lost = False  # PX4 left OFFBOARD by itself (failsafe()); until the model acts

    def want(self, on: bool) -> None:
        """GUIDED asked for (True) or another mode, a landing, RTL (False: the stream stops)."""
        if not on and self.args is not None:
            self.say("PX4: setpoint stream stopped")
        if on:
            self.lost = False
            if not self.wanted:
                self.asked_at = -math.inf  # an earlier switch's answer is not this one's
        self.wanted = on
        if not on:
            self.args = None
            self.started = math.inf

    def target(self, now: float, args: tuple[Any, ...]) -> None:
        """The snippet sent a target (already sent once): keep it going."""
        if not self.wanted:
            return
        if self.args is None:
            self.started = now
            self.say("PX4: keeping a setpoint stream at 10 Hz (OFFBOARD needs one)")
        self.args = args
        self.sent_at = now

    def tick(self, now: float, mode: int, armed: bool, heartbeat_at: float = -math.inf,
             switch_ack: str | None = None) -> None:
        """The reader's timed work: resend the target, switch to OFFBOARD when it is time,
        and let go when PX4 leaves OFFBOARD by itself. ``heartbeat_at``: when the HEARTBEAT
        that said ``mode`` came; ``switch_ack``: the last answer to set_mode (the switch's,
        once asked)."""
        was, self.mode = self.mode, mode
        # PX4 accepted the switch (its last answer), and a HEARTBEAT since says otherwise.
        accepted = self.asked_at > -math.inf and switch_ack == "accepted"
        left = was == OFFBOARD or (accepted and heartbeat_at > self.asked_at + SETTLE_S)
        if left and mode != OFFBOARD and self.wanted:
            self.say(f"PX4 left OFFBOARD for {mode_name(mode)} (a failsafe or a pilot): the "
                     "driver stops its stream; set_mode(\"GUIDED\") takes the vehicle back")
            self.want(False)
            self.lost = True
            return
        if self.args is None:
            return
        if now - self.sent_at >= RESEND_S:
            self.send(*self.args)
            self.sent_at = now
        if mode != OFFBOARD and armed and not accepted and now - self.started >= WARMUP_S \
                and now - self.asked_at >= SWITCH_RETRY_S:
            self.asked_at = now
            self.say("PX4: setpoints streaming: switching to OFFBOARD")
            self.switch()


class Texts:
    """STATUSTEXT, joined when it comes in chunks (MAVLink 2: ``id`` and ``chunk_seq``)."""

    def __init__(self) -> None:
        self.parts: dict[int, tuple[float, int, list[str]]] = {}

    def add(self, now: float, severity: int, text: str, text_id: int, seq: int) -> list[
            tuple[int, str]]:
        """The whole texts this chunk completes (a chunk shorter than 50 bytes ends one)."""
        done: list[tuple[int, str]] = []
        for key, (at, sev, parts) in list(self.parts.items()):
            if now - at > TEXT_WAIT_S:
                del self.parts[key]
                done.append((sev, "".join(parts)))
        if not text_id:
            return [*done, (severity, text)]
        at, sev, parts = self.parts.get(text_id, (now, severity, []))
        if seq == len(parts):
            parts.append(text)
        if len(text.encode()) < 50:
            self.parts.pop(text_id, None)
            done.append((sev, "".join(parts)))
        else:
            self.parts[text_id] = (at, sev, parts)
        return done


class Px4Vehicle:
    """The PX4 side of hfsmc_mavlink.Vehicle, which mixes it in (its attributes are the
    vehicle's: ``_offboard``, ``_acks``, ``_command``, ``_say``...)."""

    _offboard: Offboard
    _texts: Texts
    _acks: dict[str, str]
    _answered: dict[int, tuple[str, str, bool, float]]
    _home_amsl: float | None
    _heartbeat: tuple[int, int, int, int]
    _heartbeat_at: float | None
    _ack_timeout: float
    _px4: bool
    _prearm: bool
    _autopilot: str
    _send_setpoint: Any
    _command: Any
    _say: Any
    now: Any
    armed: Any
    hold: Any

    def _px4_init(self, options: dict[str, str]) -> None:
        """The option ``autopilot`` (auto, ardupilot, px4) and the PX4 side's state."""
        self._autopilot = str(options.get("autopilot", "auto")).lower()
        if self._autopilot not in ("auto", "ardupilot", "px4"):
            self._say(f"option autopilot: `{self._autopilot}` is not auto, ardupilot or px4; "
                      "auto used")
            self._autopilot = "auto"
        self._px4 = self._autopilot == "px4"  # else known from the first heartbeat
        self._prearm = False  # SYS_STATUS says the pre-flight checks pass
        self._home_amsl = None  # m: PX4's take-off wants its altitude AMSL
        self._answered = {}  # command id -> the last answer's (name, label, quiet, until)
        self._texts = Texts()
        self._offboard = Offboard(self._send_setpoint, self._switch_offboard, self._say)

    def _px4_tick(self, now: float) -> None:
        """The reader's timed work on PX4: the setpoint stream and the OFFBOARD switch."""
        hb, at = self._heartbeat, self._heartbeat_at
        self._offboard.tick(now, hb[3], bool(hb[2] & MODE_FLAG_SAFETY_ARMED),
                            -math.inf if at is None else at, self._acks.get("set_mode"))

    def _px4_mode(self, name: str, number: int) -> None:
        """GUIDED on PX4: Hold on the ground (armable; targets switch to OFFBOARD once
        their stream runs), in the air a stream holding where the vehicle is, then OFFBOARD."""
        guided = number == OFFBOARD
        self._offboard.want(guided)
        if guided and self.armed():
            if self._offboard.args is None:
                self.hold()
            return  # the switch comes from the stream (last_ack("set_mode") says its answer)
        if guided:
            number = HOLD
            self._say("PX4: GUIDED on the ground is Hold; targets switch to OFFBOARD in flight")
        self._command("set_mode", f"set_mode {name}", MAV_CMD_DO_SET_MODE,
                      *set_mode_params(number))

    def _switch_offboard(self) -> None:
        self._command("set_mode", "set_mode GUIDED (OFFBOARD)", MAV_CMD_DO_SET_MODE,
                      *set_mode_params(OFFBOARD))

    def _px4_command(self, name: str, command: int,
                     p: tuple[float, ...]) -> tuple[float, ...] | None:
        """A command as PX4 wants it (take-off altitude AMSL); the stream stops for a
        landing, RTL or a disarm. None: not to be sent (said why)."""
        if command == MAV_CMD_NAV_TAKEOFF:
            if self._home_amsl is None:
                self._acks[name] = "not_sent"
                self._say("takeoff: not sent, PX4 wants the altitude AMSL and no global "
                          "position has come yet")
                return None
            self._offboard.want(True)
            return (*p[:3], math.nan, *p[4:6], p[6] + self._home_amsl)
        if command in (MAV_CMD_NAV_LAND, MAV_CMD_NAV_RETURN_TO_LAUNCH) or \
                (command == MAV_CMD_COMPONENT_ARM_DISARM and p[0] == 0):
            self._offboard.want(False)
        return p

    def _late_ack(self, msg: Any) -> None:
        """A second answer (PX4 v1.16 answers DO_SET_MODE at once, then for real): the last
        answer counts. Called with the lock held."""
        name, label, quiet, until = self._answered.get(msg.command, ("", "", True, 0.0))
        result = RESULTS.get(int(msg.result), f"result_{msg.result}")
        if not name or self.now() > until or (quiet and result == "accepted"):
            return
        if not quiet:
            if self._acks.get(name) == result:
                return
            self._acks[name] = result
        self._say(f"{label} {result if result == 'accepted' else result.upper()} "
                  "(second answer)")

