"""The simulated autopilot's missions and geofence (docs/worlds.md, "Missions and fences").

- The MISSION_ITEM_INT protocol, the vehicle's side: MISSION_COUNT starts an upload of a
  mission (type 0) or a fence (type 1); each item is asked for with MISSION_REQUEST_INT,
  asked again when it does not come within ``REQUEST_RETRY_S`` (at most ``RETRIES``
  times), and the upload ends with one MISSION_ACK: ACCEPTED, or the first item's fault
  (NO_SPACE, UNSUPPORTED, UNSUPPORTED_FRAME, INVALID_PARAM1/5_X/6_Y/7,
  OPERATION_CANCELLED when the items stop coming). A refused upload leaves the plan that
  was there. MISSION_REQUEST_LIST and MISSION_CLEAR_ALL answer from the same store.
- The mission, flown in AUTO (ArduPilot's AUTO, PX4's AUTO.MISSION): NAV_WAYPOINT (with
  its acceptance radius and, on PX4, its yaw), NAV_TAKEOFF, NAV_LAND (where it says, or
  where the vehicle is), NAV_RETURN_TO_LAUNCH, CONDITION_YAW (ArduPilot's heading for the
  next leg); MISSION_CURRENT at 1 Hz and on each change, MISSION_ITEM_REACHED for each
  item reached. ArduPilot's item 0 is home and is never flown.
- The fence: inclusion polygons (NAV_FENCE_POLYGON_VERTEX_INCLUSION, ``param1`` the vertex
  count) and circles (NAV_FENCE_CIRCLE_INCLUSION, ``param1`` the radius); while it is
  active and the vehicle armed, leaving every inclusion zone is a breach, acted on once
  per breach by the autopilot (``Host.fence_action``); FENCE_STATUS at 1 Hz and on each
  change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as M

from hfsmc.sim.telemetry import ned
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World

MISSION, FENCE = int(M.MAV_MISSION_TYPE_MISSION), int(M.MAV_MISSION_TYPE_FENCE)
REQUEST_RETRY_S = 1.5  # an item asked for and not come by then is asked again
RETRIES = 4  # ... this many times, then the upload is cancelled
MAX_ITEMS = {MISSION: 700, FENCE: 80}  # what the store holds (NO_SPACE beyond)
STATUS_PERIOD_S = 1.0  # MISSION_CURRENT and FENCE_STATUS, unasked
WAYPOINT, TAKEOFF, LAND, RTL = (int(M.MAV_CMD_NAV_WAYPOINT), int(M.MAV_CMD_NAV_TAKEOFF),
                                int(M.MAV_CMD_NAV_LAND), int(M.MAV_CMD_NAV_RETURN_TO_LAUNCH))
CONDITION_YAW = int(M.MAV_CMD_CONDITION_YAW)
POLYGON = int(M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION)
CIRCLE = int(M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION)
NAV_COMMANDS = frozenset({WAYPOINT, TAKEOFF, LAND, RTL})
GLOBAL_FRAMES = frozenset({int(M.MAV_FRAME_GLOBAL), int(M.MAV_FRAME_GLOBAL_INT),
                           int(M.MAV_FRAME_GLOBAL_RELATIVE_ALT),
                           int(M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)})
RELATIVE_FRAMES = frozenset({int(M.MAV_FRAME_GLOBAL_RELATIVE_ALT),
                             int(M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)})
FAR = 1e5  # m: an item further than this from home is refused (INVALID_PARAM5_X)


class Host(Protocol):
    """What the missions need of the autopilot (hfsmc/sim/autopilot.py, px4.py)."""

    mav: Any
    body: Body
    world: World
    px4: bool  # item 0 is a mission item (PX4), not home (ArduPilot)

    def log(self, text: str) -> None: ...
    def status(self, severity: int, text: str) -> None: ...
    def mission_landed(self) -> None: ...  # the mission's LAND: the autopilot's landing
    def mission_rtl(self) -> None: ...  # the mission's RTL: the autopilot's return
    def mission_done(self) -> None: ...  # the last item reached
    def fence_action(self) -> None: ...  # a breach began
    def fence_on(self) -> bool: ...  # the autopilot's fence is on (a fence uploaded or not)
    def default_radius(self) -> float: ...  # m: a waypoint's acceptance radius when 0


@dataclass(frozen=True, slots=True)
class Item:
    """One MISSION_ITEM_INT as stored."""

    command: int
    frame: int
    params: tuple[float, float, float, float]
    x: int
    y: int
    z: float


def item_fault(kind: int, m: Any, home_alt: float) -> int | None:
    """The MAV_MISSION_RESULT that refuses an item, or None when it is fine."""
    command, frame = int(m.command), int(m.frame)
    if kind == FENCE:
        if command not in (POLYGON, CIRCLE):
            return int(M.MAV_MISSION_UNSUPPORTED)
        if command == POLYGON and not (3 <= m.param1 <= MAX_ITEMS[FENCE]):
            return int(M.MAV_MISSION_INVALID_PARAM1)
        if command == CIRCLE and not (0 < m.param1 <= FAR):
            return int(M.MAV_MISSION_INVALID_PARAM1)
    elif command not in NAV_COMMANDS and command != CONDITION_YAW:
        return int(M.MAV_MISSION_UNSUPPORTED)
    if command == CONDITION_YAW:
        return None if math.isfinite(m.param1) else int(M.MAV_MISSION_INVALID_PARAM1)
    if command == RTL and kind == MISSION:
        return None  # no position
    if frame not in GLOBAL_FRAMES:
        return int(M.MAV_MISSION_UNSUPPORTED_FRAME)
    if abs(m.x) > 90e7 or (command != LAND and m.x == 0 and m.y == 0):
        return int(M.MAV_MISSION_INVALID_PARAM5_X)
    if abs(m.y) > 180e7:
        return int(M.MAV_MISSION_INVALID_PARAM6_Y)
    alt = m.z if frame in RELATIVE_FRAMES else m.z - home_alt
    if not math.isfinite(m.z) or abs(alt) > FAR:
        return int(M.MAV_MISSION_INVALID_PARAM7)
    return None


def inside_polygon(p: tuple[float, float], vertices: list[tuple[float, float]]) -> bool:
    """Ray casting, (north, east) in m."""
    inside = False
    n = len(vertices)
    for i in range(n):
        (a_n, a_e), (b_n, b_e) = vertices[i], vertices[(i + 1) % n]
        if (a_e > p[1]) != (b_e > p[1]):
            cross = a_n + (p[1] - a_e) * (b_n - a_n) / (b_e - a_e)
            if p[0] < cross:
                inside = not inside
    return inside


class Missions:
    """The mission and fence store, the upload's vehicle side, AUTO's executor, the fence."""

    def __init__(self, host: Host) -> None:
        self.host = host
        self.plans: dict[int, list[Item]] = {MISSION: [], FENCE: []}
        self.upload: dict[int, tuple[int, list[Item], float, int, int, int]] = {}
        # kind -> (count, items so far, asked at, retries, system, component)
        self.current = 0 if host.px4 else 1  # the item AUTO flies (or will fly)
        self.stage = ""  # the current item's progress: "", "fly", "hold", "land", "done"
        self.stage_since = 0.0
        self.heading: float | None = None  # ArduPilot: CONDITION_YAW for the next leg
        self.landing = False  # the mission's LAND or RTL is under way
        self.breached = False
        self.breaches = 0
        self.status_at = -math.inf

    # -- the protocol ---------------------------------------------------------------

    def on_message(self, kind: str, m: Any) -> bool:
        """Handle one mission-protocol message; False when it is not one."""
        handler = {"MISSION_COUNT": self._on_count, "MISSION_ITEM_INT": self._on_item,
                   "MISSION_REQUEST_LIST": self._on_list,
                   "MISSION_CLEAR_ALL": self._on_clear,
                   "MISSION_SET_CURRENT": self._on_set_current}.get(kind)
        if handler is None:
            return False
        handler(m)
        return True

    def _kind(self, m: Any) -> int | None:
        kind = int(getattr(m, "mission_type", 0))
        return kind if kind in self.plans else None

    def _ack(self, to: tuple[int, int], kind: int, result: int) -> None:
        self.host.mav.mission_ack_send(to[0], to[1], result, kind)

    def _on_count(self, m: Any) -> None:
        kind, to = self._kind(m), (m.get_srcSystem(), m.get_srcComponent())
        if kind is None:
            self._ack(to, int(getattr(m, "mission_type", 0)), int(M.MAV_MISSION_UNSUPPORTED))
            return
        if m.count > MAX_ITEMS[kind]:
            self.host.status(int(M.MAV_SEVERITY_WARNING),
                             f"Mission: {m.count} items, the most is {MAX_ITEMS[kind]}")
            self._ack(to, kind, int(M.MAV_MISSION_NO_SPACE))
            return
        if m.count == 0:
            self._store(kind, [])
            self._ack(to, kind, int(M.MAV_MISSION_ACCEPTED))
            return
        self.upload[kind] = (int(m.count), [], self.host.body.t, 0, *to)
        self.host.mav.mission_request_int_send(to[0], to[1], 0, kind)

    def _on_item(self, m: Any) -> None:
        kind = self._kind(m)
        if kind is None or kind not in self.upload:
            return
        count, items, _, _, system, component = self.upload[kind]
        if m.seq != len(items):
            return  # a repeat or one ahead: the request for the one wanted is resent
        fault = None if (kind == MISSION and m.seq == 0 and not self.host.px4) else \
            item_fault(kind, m, self.host.world.home.alt)
        if fault is not None:
            del self.upload[kind]
            self.host.status(int(M.MAV_SEVERITY_WARNING), f"Mission: item {m.seq} refused")
            self._ack((system, component), kind, fault)
            return
        items.append(Item(int(m.command), int(m.frame),
                          (m.param1, m.param2, m.param3, m.param4), int(m.x), int(m.y),
                          float(m.z)))
        if len(items) < count:
            self.upload[kind] = (count, items, self.host.body.t, 0, system, component)
            self.host.mav.mission_request_int_send(system, component, len(items), kind)
            return
        del self.upload[kind]
        if kind == FENCE and not self._polygons_whole(items):
            self._ack((system, component), kind, int(M.MAV_MISSION_INVALID_PARAM1))
            return
        self._store(kind, items)
        self._ack((system, component), kind, int(M.MAV_MISSION_ACCEPTED))

    @staticmethod
    def _polygons_whole(items: list[Item]) -> bool:
        """Each polygon's vertices come together, as many as each says."""
        i = 0
        while i < len(items):
            if items[i].command == CIRCLE:
                i += 1
                continue
            n = int(items[i].params[0])
            group = items[i:i + n]
            if len(group) != n or any(g.command != POLYGON or int(g.params[0]) != n
                                      for g in group):
                return False
            i += n
        return True

    def _store(self, kind: int, items: list[Item]) -> None:
        self.plans[kind] = items
        what = "mission" if kind == MISSION else "fence"
        self.host.log(f"{what}: {len(items)} items stored")
        if kind == MISSION:
            self.current = 0 if self.host.px4 else 1
            self.stage = ""
            self.send_current()
        elif self.breached:
            self.breached = False
            self.send_fence_status(change=True)

    def _on_list(self, m: Any) -> None:
        kind = self._kind(m)
        if kind is not None:
            self.host.mav.mission_count_send(m.get_srcSystem(), m.get_srcComponent(),
                                             len(self.plans[kind]), kind)

    def _on_clear(self, m: Any) -> None:
        kinds = list(self.plans) if m.mission_type == M.MAV_MISSION_TYPE_ALL else \
            [k for k in (self._kind(m),) if k is not None]
        for kind in kinds:
            self._store(kind, [])
        self._ack((m.get_srcSystem(), m.get_srcComponent()), kinds[0] if len(kinds) == 1
                  else int(M.MAV_MISSION_TYPE_ALL), int(M.MAV_MISSION_ACCEPTED))

    def _on_set_current(self, m: Any) -> None:
        if 0 <= m.seq < len(self.plans[MISSION]):
            self.current = int(m.seq)
            self.stage = ""
            self.send_current()

    def tick(self) -> None:
        """Each step: items not come asked again, the status messages, the fence."""
        t = self.host.body.t
        for kind, (count, items, at, retries, system, component) in list(self.upload.items()):
            if t - at < REQUEST_RETRY_S:
                continue
            if retries >= RETRIES:
                del self.upload[kind]
                self._ack((system, component), kind, int(M.MAV_MISSION_OPERATION_CANCELLED))
                continue
            self.upload[kind] = (count, items, t, retries + 1, system, component)
            self.host.mav.mission_request_int_send(system, component, len(items), kind)
        self._check_fence()
        if t - self.status_at >= STATUS_PERIOD_S:
            self.send_current()
            self.send_fence_status()

    def send_current(self) -> None:
        self.status_at = self.host.body.t
        total = len(self.plans[MISSION])
        state = (int(M.MISSION_STATE_NO_MISSION) if total == 0 else
                 int(M.MISSION_STATE_COMPLETE) if self.current >= total else
                 int(M.MISSION_STATE_ACTIVE) if self.stage else int(M.MISSION_STATE_NOT_STARTED))
        self.host.mav.mission_current_send(min(self.current, max(total - 1, 0)), total, state)

    def send_fence_status(self, change: bool = False) -> None:
        """Once a second while the fence is on; at a change (a breach, its end, the fence
        turned off or removed) whatever the fence."""
        if change or self.fence_active():
            self.host.mav.fence_status_send(int(self.breached), self.breaches,
                                            int(M.FENCE_BREACH_BOUNDARY) if self.breached else 0,
                                            0)

    # -- AUTO -----------------------------------------------------------------------

    def fly(self) -> None:
        """AUTO's step: start the current item, or see whether it is done."""
        plan, b = self.plans[MISSION], self.host.body
        if self.current >= len(plan) or self.stage == "done" or not b.armed:
            return
        if b.landed and plan[self.current].command != TAKEOFF:
            return  # on the ground only a take-off starts the mission
        item = plan[self.current]
        if self.stage == "":
            self._start(item)
            return
        if self.stage == "fly" and self._arrived(item):
            if item.params[0] > 0 and item.command == WAYPOINT:
                self.stage, self.stage_since = "hold", b.t
            else:
                self._next()
        elif self.stage == "hold" and b.t - self.stage_since >= item.params[0]:
            self._next()

    def _goal(self, item: Item) -> tuple[float, float, float]:
        home, b = self.host.world.home, self.host.body
        n, e = ned(home, item.x, item.y) if (item.x or item.y) else (b.north, b.east)
        up = item.z if item.frame in RELATIVE_FRAMES else item.z - home.alt
        return n, e, -up

    def _start(self, item: Item) -> None:
        b = self.host.body
        self.stage = "fly"
        if item.command == CONDITION_YAW:
            self.heading = math.radians(item.params[0])
            self._next()
        elif item.command == WAYPOINT:
            b.goto(*self._goal(item))
            yaw = self.heading if not self.host.px4 else (
                math.radians(item.params[3]) if math.isfinite(item.params[3]) else None)
            if yaw is None:
                b.face_travel()
            else:
                b.turn_to(yaw)
        elif item.command == TAKEOFF:
            n, e, d = self._goal(item)
            b.goto(b.north, b.east, min(d, b.down))
            b.hold_heading()
        elif item.command == LAND:
            n, e, _ = self._goal(item)
            b.goto(n, e, b.down)
            self.stage = "to_land"
        elif item.command == RTL:
            self.stage, self.landing = "done", True
            self.host.mission_rtl()

    def _arrived(self, item: Item) -> bool:
        b = self.host.body
        if item.command == TAKEOFF:
            return b.arrived(0.3)
        radius = item.params[1] if item.params[1] > 0 else self.host.default_radius()
        n, e, d = self._goal(item)
        return math.sqrt((b.north - n) ** 2 + (b.east - e) ** 2 + (b.down - d) ** 2) <= radius

    def landing_step(self) -> None:
        """The mission's LAND: once over its point, land (called in AUTO each step)."""
        if self.stage == "to_land" and self.host.body.arrived(0.3):
            self.stage, self.landing = "done", True
            self.host.body.land()
            self.host.mission_landed()

    def _next(self) -> None:
        self.host.mav.mission_item_reached_send(self.current)
        self.host.log(f"mission: item {self.current} reached")
        self.current += 1
        self.stage = ""
        self.heading = None if self.plans[MISSION][self.current - 1].command != CONDITION_YAW \
            else self.heading
        self.send_current()
        if self.current >= len(self.plans[MISSION]):
            self.stage = "done"
            self.host.mission_done()

    def restart_if_done(self) -> None:
        """Entering AUTO again after the end starts the mission over (MIS_RESTART-like)."""
        if self.current >= len(self.plans[MISSION]) or self.stage == "done":
            self.current = 0 if self.host.px4 else 1
        self.stage = ""
        self.heading = None
        self.landing = False

    # -- the fence --------------------------------------------------------------------

    def fence_active(self) -> bool:
        return bool(self.plans[FENCE]) and self.host.fence_on()

    def outside(self, north: float, east: float) -> bool:
        """A point outside every inclusion zone of the fence (False without a fence)."""
        home, items = self.host.world.home, self.plans[FENCE]
        if not items:
            return False
        i = 0
        while i < len(items):
            it = items[i]
            if it.command == CIRCLE:
                n, e = ned(home, it.x, it.y)
                if math.hypot(north - n, east - e) <= it.params[0]:
                    return False
                i += 1
            else:
                k = int(it.params[0])
                if inside_polygon((north, east), [ned(home, v.x, v.y)
                                                  for v in items[i:i + k]]):
                    return False
                i += k
        return True

    def _check_fence(self) -> None:
        b = self.host.body
        now = self.fence_active() and b.armed and self.outside(b.north, b.east)
        if now == self.breached:
            return
        self.breached = now
        self.send_fence_status(change=True)
        if now:
            self.breaches += 1
            self.host.log(f"fence breached at north {b.north:.1f} m, east {b.east:.1f} m")
            self.host.fence_action()
        else:
            self.host.log("fence: back inside")
