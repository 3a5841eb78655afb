"""The web view's bridge: one monitor client that keeps what the pages show.

The bridge reads a running component's monitor (schemas/monitor.md) with
asyncio, applies every message to one ``ViewState`` (the same view model the
terminal viewer and the component's ``--display`` use), and hands each page
a ``model`` and a ``state`` message when it connects, then ``delta`` messages:
what became active or inactive, the transitions taken, new log lines,
variables, overruns. What is active is decided here, once; the pages only
draw it. The messages are described in docs/web.md.

Each page has a bounded queue: a page that does not keep up is dropped (its
queue emptied and closed); it never holds up the bridge or the other pages.
When the component stops or disappears the pages are told, and the bridge
connects again with a growing delay (RETRY_FIRST_S .. RETRY_MAX_S) until the
component is back.

A component of monitor minor version 1 also sends its vehicles' state and, to
a client that asked for them, its cameras' frames: the bridge asks for frames
only while a page is open, keeps the latest of each for a late page and passes
them on as ``vehicle`` and ``frame`` messages. Minor version 3 adds a ``ros2``
interface's topics, passed on as ``ros2`` messages with the odometry's trail kept
here, and its laser scans (asked for while a page is open) as ``scan`` messages;
with a world file the pages also get its walls in the odom frame (hfsmc/web/ros2.py).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import sys
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any, TextIO

from hfsmc.errors import UsageError
from hfsmc.ir import Model

# The component's own modules, shipped as the data package hfsmc.templates (see hfsmc/commands/view.py).
from hfsmc.templates.python import hfsmc_driverview as driverview  # type: ignore[import-not-found]
from hfsmc.templates.python import hfsmc_monitor as monitor
from hfsmc.templates.python import hfsmc_viewstate as viewstate
from hfsmc.web.picture import svg_of
from hfsmc.web.ros2 import Trail, WorldMap, odometry, ros2_record, scan_record, world_message

QUEUE_LIMIT = 256  # messages waiting for one page; beyond, the page is dropped
RETRY_FIRST_S = 0.2  # first delay before connecting again; doubled up to RETRY_MAX_S
RETRY_MAX_S = 2.0
CONNECT_TIMEOUT_S = 3.0
# Records that arrive this close together go to the pages in one delta: a transition's
# fire, exits and entries come one by one, and a page should not draw the states between.
COALESCE_S = 0.01
FRAME_LIMIT = 1 << 20  # characters of base64 JPEG; a larger frame is not passed on


@dataclass
class Picture:
    """The diagram the pages show, and where it came from."""

    svg: str | None
    drawn_from: str  # "model", "structure" or "" (no picture)
    problem: str | None = None  # why it is not the model's drawing, or why there is none
    source: Model | None = None  # the model drawn: its sub-automata are drawn from it


class Page:
    """One browser's connection: a bounded queue of JSON texts; None ends it."""

    def __init__(self, limit: int = QUEUE_LIMIT) -> None:
        self.queue: asyncio.Queue[str | None] = asyncio.Queue(limit + 1)  # +1: room for the end
        self.limit = limit
        self.dropped = False

    def offer(self, text: str) -> bool:
        """Queue ``text``; False (and the page ended) when the page is too far behind."""
        if self.dropped:
            return False
        if self.queue.qsize() >= self.limit:
            self.end(dropped=True)
            return False
        self.queue.put_nowait(text)
        return True

    def end(self, dropped: bool = False) -> None:
        """Throw away what waits and queue the end (the server then closes the socket)."""
        self.dropped = self.dropped or dropped
        while not self.queue.empty():
            self.queue.get_nowait()
        self.queue.put_nowait(None)


@dataclass
class _Pending:
    """What happened since the pages were last told."""

    fired: list[dict[str, Any]] = field(default_factory=list)
    logs: list[dict[str, Any]] = field(default_factory=list)
    scheduled: bool = False


class Bridge:
    """Watches the monitor at ``host:port`` and keeps every page up to date.

    ``paint(structure)`` is awaited for a component's structure the first time
    it is seen (and again if it changes): it gives the picture.
    """

    def __init__(self, host: str, port: int, paint: Callable[[dict[str, Any]], Awaitable[Picture]], *,
                 autofocus: bool = True, log: TextIO | None = None,
                 queue_limit: int = QUEUE_LIMIT, world: WorldMap | None = None) -> None:
        self.host, self.port = host, port
        self.label: str = monitor.format_address(host, port)
        self.watching = f"component {self.label}"  # what the server's first line names
        self._paint = paint
        self.autofocus = autofocus
        self._log = log if log is not None else sys.stderr
        self._queue_limit = queue_limit
        self.view = viewstate.ViewState()
        self.structure: dict[str, Any] | None = None
        self.picture = Picture(None, "")
        self.status = "connecting"  # connecting | connected | stopped | disconnected | error
        self.note = f"connecting to {self.label}"
        self.pages: set[Page] = set()
        self._told_active: dict[str, int] = {}
        self._told_values: dict[str, str] = {}
        self._told: dict[str, Any] = {}
        self._told_t = -1
        self._pending = _Pending()
        self._said = ""  # the last status line written to the log
        self._subs_of: Picture | None = None  # the picture the sub-automata below were drawn for
        self._subs: dict[str, str | None] = {}
        self._drawable: frozenset[str] = frozenset()  # the picture's composite states and regions
        self.feeds: dict[str, list[str]] = {"vehicle": [], "camera": [], "ros2": [],
                                            "driver": []}  # hello's
        self.vehicles: dict[str, dict[str, Any]] = {}  # the latest vehicle message of each
        self.frames: dict[str, dict[str, Any]] = {}  # the latest frame of each camera
        self._writer: asyncio.StreamWriter | None = None  # to the component, while connected
        self._subscribed: tuple[bool, bool] = (False, False)  # asked for: frames, scans
        self.world = world
        self.ros2: dict[str, dict[str, Any]] = {}  # the latest ros2 message of each
        self.drivers: dict[str, dict[str, Any]] = {}  # the latest driver message of each
        self.scans: dict[str, dict[str, Any]] = {}  # the latest scan of each interface
        self.trails: dict[str, Trail] = {}
        self.worlds: dict[str, dict[str, Any]] = {}  # per interface, the world in its odom frame

    # -- sub-automata -----------------------------------------------------------------------
    async def sub_svg(self, path: str) -> str | None:
        """The drawing of the composite state ``path``'s sub-automaton alone (as
        ``hfsmc diagram --state PATH``), drawn once per picture; None when there is no
        such composite state or no model to draw it from."""
        picture = self.picture
        if picture.source is None:
            return None
        if picture is not self._subs_of:
            self._subs_of, self._subs = picture, {}
            self._drawable = _drawable(picture.source)
        if path not in self._drawable:  # nothing drawn, nothing kept: the cache stays the model's size
            return None
        if path not in self._subs:
            source = picture.source
            try:
                svg: str | None = await asyncio.to_thread(lambda: svg_of(source, path))
            except UsageError:
                svg = None
            if picture is self._subs_of:
                self._subs[path] = svg
            return svg
        return self._subs[path]

    # -- pages ------------------------------------------------------------------------------
    def attach(self) -> Page:
        """A new page, with the model and the current state already queued."""
        page = Page(self._queue_limit)
        self._flush()  # so that the state below and the deltas after it add up
        if self.structure is not None:
            page.offer(_dump(self.model_message()))
        page.offer(_dump(self.state_message()))
        for msg in (*self.vehicles.values(), *self.frames.values(), *self.worlds.values(),
                    *({"type": "trail", "name": n, "points": t.points}
                      for n, t in self.trails.items()),
                    *self.ros2.values(), *self.scans.values(), *self.drivers.values()):
            page.offer(_dump(msg))
        self.pages.add(page)
        self._subscribe()
        return page

    def detach(self, page: Page) -> None:
        self.pages.discard(page)
        self._subscribe()

    def _subscribe(self) -> None:
        """Ask the component for camera frames and laser scans while a page is open, and
        no longer after."""
        want = (bool(self.pages) and bool(self.feeds["camera"]),
                bool(self.pages) and bool(self.feeds["ros2"]))
        if self._writer is None or want == self._subscribed:
            return
        self._subscribed = want
        with contextlib.suppress(OSError, RuntimeError):
            self._writer.write(json.dumps({"type": "subscribe", "frames": want[0],
                                           "scans": want[1]}).encode() + b"\n")

    def command(self, text: str) -> None:
        """A page's command (a replay's controls, hfsmc/web/replay.py): a live view takes none."""

    def _broadcast(self, msg: dict[str, Any]) -> None:
        if not self.pages:
            self._subscribe()
            return
        text = _dump(msg)
        for page in list(self.pages):
            if not page.offer(text):
                self.pages.discard(page)

    def model_message(self) -> dict[str, Any]:
        return {"type": "model", "target": self.label, "structure": self.structure,
                "svg": self.picture.svg, "drawn_from": self.picture.drawn_from,
                "problem": self.picture.problem, "autofocus": self.autofocus,
                "feeds": self.feeds}

    def state_message(self) -> dict[str, Any]:
        v = self.view
        self._told_active = dict(v.active)
        self._told_values = _readable(v.values)
        self._told = {"overruns": v.overruns, "interrupt": v.interrupt, "stop": self._stop(),
                      "sim_rate": v.sim_rate}
        self._told_t = v.t_ms
        return {"type": "state", "status": self.status, "note": self.note, "t": v.t_ms,
                "started": v.started,
                "active": [{"state": p, "since": s} for p, s in v.active.items()],
                "variables": dict(self._told_values), "overruns": v.overruns,
                "transitions": list(v.transitions), "logs": list(v.logs),
                "interrupt": v.interrupt, "stop": self._stop(), "sim_rate": v.sim_rate}

    def _stop(self) -> dict[str, Any] | None:
        v = self.view
        if v.stop_reason is None:
            return None
        return {"reason": v.stop_reason,
                "states": [{"state": p, "since": s} for p, s in v.stopped_in.items()]}

    def _set_status(self, status: str, note: str) -> None:
        if (status, note) == (self.status, self.note):
            return
        self._flush()
        self.status, self.note = status, note
        self._broadcast({"type": "status", "status": status, "note": note, "t": self.view.t_ms})
        line = f"hfsmc view: {note}"
        if line != self._said:
            self._said = line
            print(line, file=self._log, flush=True)

    # -- deltas -----------------------------------------------------------------------------
    def _changed(self) -> None:
        """Tell the pages once the messages already read are applied."""
        if not self._pending.scheduled:
            self._pending.scheduled = True
            asyncio.get_running_loop().call_later(COALESCE_S, self._flush)

    def _flush(self) -> None:
        pending, self._pending = self._pending, _Pending()
        v = self.view
        delta: dict[str, Any] = {"type": "delta", "t": v.t_ms}
        entered = [{"state": p, "since": s} for p, s in v.active.items()
                   if self._told_active.get(p) != s]
        left = [p for p in self._told_active if p not in v.active]
        if entered:
            delta["enter"] = entered
        if left:
            delta["exit"] = left
        self._told_active = dict(v.active)
        if pending.fired:
            delta["fired"] = pending.fired
        if pending.logs:
            delta["logs"] = pending.logs
        values = _readable(v.values)
        if values != self._told_values:
            delta["variables"] = values
            self._told_values = values
        for key, now in (("overruns", v.overruns), ("interrupt", v.interrupt), ("stop", self._stop()),
                         ("sim_rate", v.sim_rate)):
            if self._told.get(key) != now:
                delta[key] = now
                self._told[key] = now
        if len(delta) > 2 or v.t_ms != self._told_t:
            self._told_t = v.t_ms
            self._broadcast(delta)

    def _apply(self, kind: str, payload: Any) -> None:
        v = self.view
        v.apply(kind, payload)
        if kind == "record":
            ev = payload.get("ev")
            if ev == "fire":
                self._pending.fired.append(v.transitions[-1])
            elif ev in ("log", "error"):
                self._pending.logs.append(v.logs[-1])
        self._changed()

    # -- the monitor ------------------------------------------------------------------------
    async def run(self) -> None:
        """Watch the component until cancelled, connecting again whenever it goes."""
        delay = RETRY_FIRST_S
        while True:
            try:
                reader, writer = await asyncio.wait_for(
                    asyncio.open_connection(self.host, self.port, limit=monitor.LINE_LIMIT),
                    CONNECT_TIMEOUT_S)
            except OSError as e:  # TimeoutError too
                why = os.strerror(e.errno) if e.errno else str(e) or "timed out"
                if self.status in ("connecting", "connected"):
                    self._set_status("connecting", f"cannot connect to {self.label}: {why}; "
                                     "trying again")
                await asyncio.sleep(delay)
                delay = min(delay * 2, RETRY_MAX_S)
                continue
            self._writer, self._subscribed = writer, (False, False)
            try:
                if await self._read(reader):
                    delay = RETRY_FIRST_S
                elif self.status == "error":  # another protocol: it will not change soon
                    delay = RETRY_MAX_S
            finally:
                self._writer = None
                writer.close()
                with contextlib.suppress(Exception):
                    await writer.wait_closed()
            await asyncio.sleep(delay)
            delay = min(delay * 2, RETRY_MAX_S)

    async def _read(self, reader: asyncio.StreamReader) -> bool:
        """Apply one connection's messages; whether the component said hello."""
        greeted = False
        ended: str | None = None
        while True:
            try:
                line = await reader.readline()
            except (OSError, ValueError, asyncio.LimitOverrunError):
                line = b""
            if not line or not line.endswith(b"\n"):
                break
            try:
                msg = json.loads(line)
                if self._feed(msg):
                    continue
                it = monitor.item(msg)
            except ValueError:
                continue
            if it is None:
                continue
            kind, payload = it
            if kind == "error":  # another protocol: nothing here can be read
                self._set_status("error", f"{self.label}: {payload}; trying again")
                return False
            if kind == "end":
                ended = str(payload)
                continue
            try:
                if kind == "structure":
                    greeted = True
                    await self._greet(payload)
                elif kind == "snapshot":
                    self.view.apply_snapshot(payload)
                    self._pending = _Pending()
                    self.status, self.note = "connected", f"connected to {self.label}"
                    self._broadcast(self.state_message())
                    self._log_status()
                else:
                    self._apply(kind, payload)
            except (KeyError, TypeError, ValueError):  # a malformed message is skipped
                continue
        self._flush()
        if ended is not None:
            self._set_status("stopped", f"{ended}; waiting for it to come back")
        elif greeted or self.status == "connected":
            self._set_status("disconnected", f"disconnected from {self.label}; trying again")
        return greeted

    def _feed(self, msg: object) -> bool:
        """A hello's feeds, a vehicle or a frame message (monitor minor version 1): whether
        ``msg`` was one of the latter two, taken here."""
        if not isinstance(msg, dict):
            return False
        kind = msg.get("type")
        if kind == "hello":
            given = msg.get("feeds")
            feeds: dict[str, Any] = given if isinstance(given, dict) else {}
            self.feeds = {k: [str(n) for n in feeds.get(k, ()) if isinstance(n, str)][:8]
                          if isinstance(feeds.get(k), list) else []
                          for k in ("vehicle", "camera", "ros2", "driver")}
            self.vehicles, self.frames, self.drivers = {}, {}, {}
            self.ros2, self.scans, self.trails, self.worlds = {}, {}, {}, {}
            self._subscribe()
            return False
        name = msg.get("name")
        if kind == "vehicle" and isinstance(name, str):
            rec = vehicle_record(msg)
            self.vehicles[name] = rec
            self._broadcast(rec)
            return True
        if kind == "ros2" and isinstance(name, str) and name in self.feeds["ros2"]:
            self._ros2(ros2_record(msg))
            return True
        if kind == "driver" and isinstance(name, str) and name in self.feeds["driver"]:
            rec = driverview.cleaned(msg)  # minor 4: a user driver's snapshot
            if rec is not None:
                self.drivers[name] = rec
                self._broadcast(rec)
            return True
        if kind == "scan" and isinstance(name, str) and name in self.feeds["ros2"]:
            scan = scan_record(msg)
            if scan is not None:
                self.scans[name] = scan
                self._broadcast(scan)
            return True
        if kind == "frame" and isinstance(name, str):
            jpeg, w, h = msg.get("jpeg"), msg.get("width"), msg.get("height")
            if isinstance(jpeg, str) and len(jpeg) <= FRAME_LIMIT and isinstance(w, int) \
                    and isinstance(h, int):
                frame = {"type": "frame", "name": name, "t": _int(msg.get("t")), "width": w,
                         "height": h, "jpeg": jpeg}
                self.frames[name] = frame
                self._broadcast(frame)
            return True
        return False

    def _ros2(self, rec: dict[str, Any]) -> None:
        """A ros2 interface's topics: its trail grows, and the first one (or one of a new
        namespace) draws the world in its odom frame."""
        name = rec["name"]
        if self.world is not None and (name not in self.worlds or
                                       self.ros2.get(name, {}).get("namespace") != rec["namespace"]):
            self.worlds[name] = world_message(self.world, name, rec["namespace"])
            self._broadcast(self.worlds[name])
        pose = odometry(rec)
        if pose is not None:
            self.trails.setdefault(name, Trail()).add(pose["x"], pose["y"])
        self.ros2[name] = rec
        self._broadcast(rec)

    def _log_status(self) -> None:
        line = f"hfsmc view: {self.note}"
        if line != self._said:
            self._said = line
            print(line, file=self._log, flush=True)

    async def _greet(self, structure: dict[str, Any]) -> None:
        """A new connection's structure: a fresh view, and the picture if it is new."""
        self.view = viewstate.ViewState(structure)
        self._told_active, self._told_values, self._told = {}, {}, {}
        if structure != self.structure:
            picture = await self._paint(structure)
            # Both at once: a page that attached while dot was drawing got the old pair.
            self.structure, self.picture = structure, picture
            self._broadcast(self.model_message())


def _drawable(model: Model) -> frozenset[str]:
    """The paths ``/sub`` draws: the composite states and the regions of ``model``."""
    return frozenset([s.path for s in model.states() if s.automata]
                     + [a.path for a in model.automata() if a.region is not None])


def _int(x: object) -> int:
    return x if isinstance(x, int) and not isinstance(x, bool) else 0


def _float(x: object) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else None


def vehicle_record(msg: dict[str, Any]) -> dict[str, Any]:
    """A monitor ``vehicle`` message as the pages get it: the known members, checked."""
    def triple(v: object) -> list[float | None] | None:
        return [_float(x) for x in v] if isinstance(v, list) and len(v) == 3 else None
    battery = msg.get("battery")
    return {"type": "vehicle", "name": str(msg.get("name")), "t": _int(msg.get("t")),
            "connected": msg.get("connected") is True, "mode": str(msg.get("mode") or "")[:40],
            "armed": msg.get("armed") is True, "altitude": _float(msg.get("altitude")),
            "position": triple(msg.get("position")), "velocity": triple(msg.get("velocity")),
            "battery": battery if isinstance(battery, int) and not isinstance(battery, bool) else None,
            "link_age": _float(msg.get("link_age"))}


def _readable(values: dict[str, str]) -> dict[str, str]:
    return {k: viewstate.readable(v) for k, v in values.items()}


def _dump(msg: dict[str, Any]) -> str:
    return json.dumps(msg, separators=(",", ":"))
