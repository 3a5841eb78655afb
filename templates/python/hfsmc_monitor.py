"""The monitor: a running component serves its live state to ``hfsmc view``.

Copied beside every generated Python component (standard library only) and
imported by ``hfsmc view`` for the client side. The protocol (JSON lines over
TCP, read-only) is described in schemas/monitor.md and monitor.schema.json.

``MonitorServer`` is an observer of the runtime: its calls only put items on
a queue; one daemon thread owns the sockets and a ``ViewState``, from which a
client that connects late gets the current state at once. A slow client never
holds up the automaton or the other clients: each has a bounded buffer and is
dropped when it overflows. What clients send is read and thrown away, but
for one request: ``{"type":"subscribe","frames":true}`` asks for camera frames.
A connection beyond the client slots, or beyond one address's share of them, is
told ``busy`` (and why) and closed.

Minor version 1 adds two messages, for components with those interfaces: the
``vehicle`` of a ``mavlink`` interface (what the driver already holds, a few
times a second) and the ``frame`` of a ``camera`` interface (the latest frame a
snippet obtained, downscaled JPEG), the frames only to clients that subscribed
to them, so a component without such a viewer pays nothing for them. Minor
version 3 adds the ``ros2`` message of a ``ros2`` interface (its topics' rates,
ages, counts and matched endpoints, an odometry's pose) to every client, and its
LaserScans (``scan``) to the clients that asked for scans. Minor version 4 adds the
``driver`` message of a user's driver (docs/drivers.md): the fields of the snapshot it
gave the latest instant, to every client.
"""

from __future__ import annotations

import base64
import contextlib
import importlib
import json
import math
import queue
import re
import selectors
import socket
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any, TextIO

if __package__:
    from . import hfsmc_driverview as _driverview
    from . import hfsmc_ros2view as _ros2view
    from . import hfsmc_view as _view
else:  # copied beside the generated component, where the modules are top level
    import hfsmc_driverview as _driverview  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2view as _ros2view  # type: ignore[import-not-found, no-redef]
    import hfsmc_view as _view  # type: ignore[import-not-found, no-redef]

PROTOCOL = 1
# Additions old viewers ignore: 1 feeds in hello, vehicle and frame messages; 2 sim_rate;
# 3 ros2 feeds, ros2 and scan messages; 4 driver feeds and messages.
MINOR = 4
MAX_CLIENTS = 16  # more connections at once are told "busy" and closed
# One address (127.0.0.1 too) may hold at most this share of the slots: a viewer elsewhere
# always finds one.
MAX_PER_ADDRESS = MAX_CLIENTS // 2
BUFFER_LIMIT = 1 << 20  # bytes waiting for one client; beyond, the client is dropped
INPUT_LIMIT = 1 << 20  # bytes one client may send (all ignored); beyond, it is dropped
LINE_LIMIT = 1 << 24  # longest message a viewer reads
SLICE = 1 << 16  # bytes of messages made before the sockets are served again
FAREWELL_S = 0.5  # how long a stopping component tries to deliver the last messages
FEED_EVERY_S = 0.25  # vehicle records, camera frames, ros2 topics, drivers: at most 4 a second
FRAME_WIDTH = 320  # frames sent are downscaled to at most that many pixels wide
FRAME_QUALITY = 70  # JPEG quality of the frames sent
FRAME_BACKLOG = 1 << 18  # a client with that many bytes still unsent gets no new frame
REQUEST_LIMIT = 1024  # a client's request line longer than that is ignored
VEHICLE_QUERIES = ("connected", "mode", "armed", "altitude", "position", "velocity", "battery",
                   "heartbeat_age")


def parse_address(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``PORT``, ``HOST:PORT`` or ``[IPV6]:PORT`` as (host, port); ValueError if neither."""
    text = text.strip()
    host, port_text = default_host, text
    if text.startswith("["):
        end = text.find("]")
        if end < 0 or text[end + 1:end + 2] != ":":
            raise ValueError(f"bad address {text!r}: expected [HOST]:PORT")
        host, port_text = text[1:end], text[end + 2:]
    elif ":" in text:
        if text.count(":") > 1:
            raise ValueError(f"bad address {text!r}: write an IPv6 address in brackets, [::1]:PORT")
        host, port_text = text.rsplit(":", 1)
        host = host or default_host
    if not re.fullmatch(r"[0-9]{1,5}", port_text) or int(port_text) > 65535:
        raise ValueError(f"bad address {text!r}: expected [HOST:]PORT with a port from 0 to 65535")
    return host, int(port_text)


def format_address(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def encode(msg: dict[str, Any]) -> bytes:
    """One protocol message: compact JSON, ASCII only, one line."""
    return json.dumps(msg, separators=(",", ":"), default=str).encode("ascii") + b"\n"


def message(kind: str, payload: Any) -> dict[str, Any] | None:
    """The protocol message of one observer item (None for items that are not sent)."""
    if kind == "record":
        return {"type": "record", "record": payload}
    if kind == "sample":
        t_ms, values, overruns, *more = payload  # more: the rate, on the simulator's clock
        rate = more[0] if more else None
        msg = {"type": "sample", "t": t_ms, "variables": values, "overruns": overruns}
        return msg if rate is None else {**msg, "sim_rate": rate}
    return None


def _num(x: object, digits: int = 3) -> float | None:
    """A finite float rounded for the wire; None for NaN, inf or what is not a number."""
    try:
        f = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return round(f, digits) if math.isfinite(f) else None


def _triple(v: object) -> list[float | None] | None:
    try:
        xs = [_num(x) for x in v]  # type: ignore[attr-defined]
    except TypeError:
        return None
    return xs if len(xs) == 3 and any(x is not None for x in xs) else None


def vehicle_message(name: str, t_ms: int, vehicle: Any) -> dict[str, Any]:
    """A ``vehicle`` message from what a mavlink driver holds (its queries never wait)."""
    battery = vehicle.battery()
    age = _num(vehicle.heartbeat_age(), 2)
    return {"type": "vehicle", "t": t_ms, "name": name, "connected": bool(vehicle.connected()),
            "mode": str(vehicle.mode()), "armed": bool(vehicle.armed()),
            "altitude": _num(vehicle.altitude()), "position": _triple(vehicle.position()),
            "velocity": _triple(vehicle.velocity()),
            "battery": int(battery) if isinstance(battery, int) and battery >= 0 else None,
            "link_age": age}


def frame_message(name: str, t_ms: int, image: Any, cv2: Any) -> dict[str, Any] | None:
    """A ``frame`` message: ``image`` (BGR) downscaled to FRAME_WIDTH at most, as JPEG."""
    h, w = int(image.shape[0]), int(image.shape[1])
    if w > FRAME_WIDTH:
        h, w = max(1, round(h * FRAME_WIDTH / w)), FRAME_WIDTH
        image = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
    ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, FRAME_QUALITY])
    if not ok:
        return None
    return {"type": "frame", "t": t_ms, "name": name, "width": w, "height": h,
            "jpeg": base64.b64encode(jpeg.tobytes()).decode("ascii")}


def busy_message(reason: str) -> bytes:
    """What a connection the monitor cannot serve is told before it is closed."""
    return encode({"type": "busy", "reason": reason})


class _Client:
    __slots__ = ("addr", "events", "frames", "inbuf", "out", "reading", "received", "scans",
                 "sent", "sock")

    def __init__(self, sock: socket.socket, addr: str) -> None:
        self.sock = sock
        self.addr = addr  # the peer's address, whose share of the slots it takes
        self.out = bytearray()
        self.reading = True  # until the client shuts its side down
        self.received = 0
        self.events = 0  # what the selector watches for it
        self.inbuf = b""  # the start of a request line
        self.frames = False  # it asked for camera frames
        self.sent: dict[str, Any] = {}  # per camera, the image whose frame it was given last
        self.scans = False  # it asked for the ros2 interfaces' laser scans


class MonitorServer:
    """The ``--monitor`` observer: a TCP server of JSON lines on a daemon thread.

    The socket is bound at construction (so an address in use fails at once)
    and ``monitor: listening on HOST:PORT`` goes to ``announce`` (stderr);
    port 0 picks a free port, read back from ``port``.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, announce: TextIO | None = None,
                 max_clients: int = MAX_CLIENTS, buffer_limit: int = BUFFER_LIMIT,
                 input_limit: int = INPUT_LIMIT, max_per_address: int | None = None) -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._listener = socket.create_server((host, port), family=family, backlog=max_clients)
        self._listener.setblocking(False)
        self.host: str = self._listener.getsockname()[0]
        self.port: int = self._listener.getsockname()[1]
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._q: queue.SimpleQueue[_view.Item] = queue.SimpleQueue()
        self._signalled = False
        self._thread: threading.Thread | None = None
        self._max_clients, self._buffer_limit, self._input_limit = max_clients, buffer_limit, input_limit
        self._max_per_address = max_per_address if max_per_address is not None \
            else max(1, max_clients // 2)
        self._structure: dict[str, Any] = {}
        self._clients: dict[int, _Client] = {}
        self._sel = selectors.DefaultSelector()
        self._vehicles: dict[str, Any] = {}
        self._cameras: dict[str, Any] = {}
        self._ros2: dict[str, Any] = {}
        self._drivers: dict[str, Any] = {}  # user drivers (minor 4)
        self._rates = _ros2view.Rates()
        self._scans: dict[str, tuple[int, bytes]] = {}  # per interface/subscription: count, message
        self._encoded: dict[str, tuple[Any, bytes]] = {}  # per camera, the last image and its frame
        self._next_feed = 0.0
        self._cv2: Any = None
        print(f"monitor: listening on {format_address(self.host, self.port)}",
              file=announce if announce is not None else sys.stderr, flush=True)

    def watch(self, interfaces: dict[str, Any]) -> None:
        """The component's interface objects (before ``start``): a mavlink vehicle's state
        and a camera's latest frame are then sent to viewers (monitor.md, minor version 1)."""
        for name, obj in interfaces.items():
            try:  # an interface the component cannot drive raises on any use
                if _driverview.is_driver(obj):
                    self._drivers[name] = obj  # a user's driver, live or a playback's fake
                elif all(callable(getattr(obj, a, None)) for a in VEHICLE_QUERIES):
                    self._vehicles[name] = obj
                elif callable(getattr(obj, "views", None)) and callable(getattr(obj, "publish", None)):
                    self._ros2[name] = obj  # a live ros2 node (a replay's fake has no views)
                elif callable(getattr(obj, "_last_seen", None)):
                    self._cv2 = importlib.import_module("cv2")  # the camera driver has it
                    self._cameras[name] = obj
            except Exception:
                continue

    # -- observer calls (automaton thread): queue and wake, never block ---------------------
    def start(self, structure: dict[str, Any]) -> None:
        self._q.put(("structure", structure))
        self._thread = threading.Thread(target=self._serve, name="hfsmc-monitor", daemon=True)
        self._thread.start()

    def record(self, rec: dict[str, Any]) -> None:
        self._q.put(("record", rec))
        self._wake()

    def sample(self, t_ms: int, values: dict[str, str], overruns: int,
               rate: float | None = None) -> None:
        self._q.put(("sample", (t_ms, values, overruns, rate)))
        self._wake()

    def close(self) -> None:
        if self._thread is None:
            self._close_sockets()
            return
        self._q.put(("end", None))
        self._signalled = False
        self._wake()
        self._thread.join(FAREWELL_S + 0.4)

    def _wake(self) -> None:
        # One byte per batch: the server clears the flag before it drains the queue.
        if not self._signalled:
            self._signalled = True
            with contextlib.suppress(OSError):
                self._wake_w.send(b"\0")

    # -- the server thread -----------------------------------------------------------------
    def _serve(self) -> None:
        view = _view.ViewState()
        try:
            self._sel.register(self._listener, selectors.EVENT_READ, "listen")
            self._sel.register(self._wake_r, selectors.EVENT_READ, "wake")
            ended, more = self._pump(view)
            while not ended:
                # A burst is sent a slice at a time, the sockets served in between.
                wait = 0.0 if more else 0.5
                if self._clients and (self._vehicles or self._cameras or self._ros2
                                      or self._drivers):
                    wait = min(wait, max(self._next_feed - time.monotonic(), 0.0))
                for key, mask in self._sel.select(wait):
                    if key.data == "listen":
                        self._accept(view)
                    elif key.data == "wake":
                        self._drain_wake()
                    elif isinstance(key.data, _Client):
                        if mask & selectors.EVENT_READ and self._alive(key.data):
                            self._read(key.data)
                        if mask & selectors.EVENT_WRITE and self._alive(key.data):
                            self._flush(key.data)
                ended, more = self._pump(view)
                if not ended and self._clients and time.monotonic() >= self._next_feed:
                    self._feeds(view)
            self._farewell()
        finally:
            for c in list(self._clients.values()):
                self._drop(c)
            self._close_sockets()

    def _close_sockets(self) -> None:
        for s in (self._listener, self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                s.close()
        self._sel.close()

    def _drain_wake(self) -> None:
        try:
            while self._wake_r.recv(4096):
                pass
        except OSError:
            pass

    def _pump(self, view: _view.ViewState) -> tuple[bool, bool]:
        """Apply queued items and send them on, a slice at a time.

        Returns (the component closed, more items are waiting).
        """
        self._signalled = False
        chunks: list[bytes] = []
        size, ended = 0, False
        while not ended and size < SLICE:
            try:
                kind, payload = self._q.get_nowait()
            except queue.Empty:
                break
            if kind == "end":
                ended = True
                chunks.append(encode({"type": "bye", "reason": view.stop_reason}))
                continue
            if kind == "structure":
                self._structure = payload
            try:
                view.apply(kind, payload)
                msg = message(kind, payload) if self._clients else None
                if msg is not None:
                    chunks.append(encode(msg))
                    size += len(chunks[-1])
            except Exception:  # a malformed item must not stop the monitor
                continue
        if chunks and self._clients:
            self._send_all(b"".join(chunks))
        return ended, not ended and size >= SLICE

    def _feeds(self, view: _view.ViewState) -> None:
        """The vehicles' state to every client, a camera's new frame to those that asked."""
        self._next_feed = time.monotonic() + FEED_EVERY_S
        chunks = []
        for name, vehicle in self._vehicles.items():
            try:
                chunks.append(encode(vehicle_message(name, view.t_ms, vehicle)))
            except Exception:  # a driver's trouble must not stop the monitor
                continue
        now = time.monotonic()
        for name, node in self._ros2.items():
            try:
                views = node.views()
                chunks.append(encode(_ros2view.ros2_message(name, view.t_ms, views, self._rates,
                                                            now)))
            except Exception:  # a driver's trouble must not stop the monitor
                continue
            self._new_scans(name, views, view.t_ms)
        for name, driver in self._drivers.items():
            try:
                chunks.append(encode(_driverview.driver_message(name, view.t_ms, driver)))
            except Exception:  # a driver's trouble must not stop the monitor
                continue
        if chunks:
            self._send_all(b"".join(chunks))
        self._send_scans()
        takers = [c for c in self._clients.values() if c.frames]
        if not takers:
            return
        for name, camera in self._cameras.items():
            # Each new image is encoded once, here, at most every FEED_EVERY_S: however often
            # clients subscribe, a subscriber is only given the frame already made.
            try:
                image = camera._last_seen()
                if image is None:
                    continue
                if name not in self._encoded or self._encoded[name][0] is not image:
                    msg = frame_message(name, view.t_ms, image, self._cv2)
                    if msg is None:
                        continue
                    self._encoded[name] = (image, encode(msg))
            except Exception:
                continue
            image, data = self._encoded[name]
            for c in takers:
                # Frames are skipped, never queued without bound: the client is not dropped,
                # and gets the latest frame once it has caught up.
                if self._alive(c) and c.sent.get(name) is not image and \
                        len(c.out) + len(data) <= min(FRAME_BACKLOG, self._buffer_limit):
                    c.sent[name] = image
                    c.out += data
                    self._flush(c)

    def _new_scans(self, name: str, views: dict[str, Any], t_ms: int) -> None:
        """Encode each new scan once, and only while some client asked for scans."""
        if not any(c.scans for c in self._clients.values()):
            return
        odom = _ros2view.odometry_of(views)
        for sub, (count, msg) in _ros2view.scans_of(views).items():
            key = f"{name}/{sub}"
            if key in self._scans and self._scans[key][0] == count:
                continue
            with contextlib.suppress(Exception):
                made = _ros2view.scan_message(name, sub, t_ms, msg, odom)
                if made is not None:
                    self._scans[key] = (count, encode(made))

    def _send_scans(self) -> None:
        """The latest scans to the clients that asked, each scan once, skipped (never
        queued without bound) for a client that is behind."""
        for c in [c for c in self._clients.values() if c.scans]:
            for key, (count, data) in self._scans.items():
                if self._alive(c) and c.sent.get(key) != count and \
                        len(c.out) + len(data) <= min(FRAME_BACKLOG, self._buffer_limit):
                    c.sent[key] = count
                    c.out += data
                    self._flush(c)

    def _send_all(self, data: bytes) -> None:
        for c in list(self._clients.values()):
            if len(c.out) + len(data) > self._buffer_limit:
                self._drop(c)  # too slow: it would hold memory without bound
            else:
                c.out += data
                self._flush(c)

    def _accept(self, view: _view.ViewState) -> None:
        while True:
            try:
                sock, peer = self._listener.accept()
            except OSError:  # nothing more to accept (or out of descriptors: try later)
                return
            addr = str(peer[0]) if isinstance(peer, tuple) else str(peer)
            reason = self._no_room_for(addr)
            if reason is not None:
                self._turn_away(sock, reason)
                continue
            sock.setblocking(False)
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            c = _Client(sock, addr)
            self._clients[sock.fileno()] = c
            hello = {"type": "hello", "protocol": PROTOCOL, "minor": MINOR,
                     "structure": self._structure,
                     "feeds": {"vehicle": list(self._vehicles), "camera": list(self._cameras),
                               "ros2": list(self._ros2), "driver": list(self._drivers)}}
            c.out += encode(hello) + encode(view.snapshot())
            self._flush(c)

    def _no_room_for(self, addr: str) -> str | None:
        """Why a new client from ``addr`` cannot be served (None: it can)."""
        if len(self._clients) >= self._max_clients:
            return f"all {self._max_clients} viewer slots are taken; try again later"
        mine = sum(1 for c in self._clients.values() if c.addr == addr)
        if mine >= self._max_per_address:
            return (f"the viewers from {addr} hold {mine} of the {self._max_clients} slots, "
                    "the most one address may; close one")
        return None

    @staticmethod
    def _turn_away(sock: socket.socket, reason: str) -> None:
        """Tell a connection why it is not served, without waiting for it, and close it."""
        with contextlib.suppress(OSError):
            sock.setblocking(False)
            sock.send(busy_message(reason))
            sock.shutdown(socket.SHUT_WR)
        sock.close()

    def _read(self, c: _Client) -> None:
        try:
            data = c.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            self._drop(c)
            return
        if not data:  # the client shut its side: it may still read
            c.reading = False
            self._watch(c)
            return
        c.received += len(data)
        if c.received > self._input_limit:
            self._drop(c)
            return
        if self._cameras or self._ros2:  # the one request a client may make: frames, scans
            lines = (c.inbuf + data).split(b"\n")
            c.inbuf = lines.pop()
            if len(c.inbuf) > REQUEST_LIMIT:
                c.inbuf = b""
            for line in lines:
                self._request(c, line)

    def _request(self, c: _Client, line: bytes) -> None:
        if len(line) > REQUEST_LIMIT:
            return
        try:
            msg = json.loads(line)
        except ValueError:
            return
        if not isinstance(msg, dict) or msg.get("type") != "subscribe":
            return
        if isinstance(msg.get("frames"), bool):
            # The latest frame goes to a new subscriber at the next feed (within FEED_EVERY_S),
            # already encoded: asking again and again costs the component no encoding.
            if msg["frames"] and not c.frames:
                c.sent = {k: v for k, v in c.sent.items() if k not in self._cameras}
            c.frames = msg["frames"]
        if isinstance(msg.get("scans"), bool):  # minor 3: the same for the laser scans
            if msg["scans"] and not c.scans:
                c.sent = {k: v for k, v in c.sent.items() if k in self._cameras}
            c.scans = msg["scans"]

    def _flush(self, c: _Client) -> None:
        try:
            while c.out:
                sent = c.sock.send(c.out)
                del c.out[:sent]
        except BlockingIOError:
            pass
        except OSError:
            self._drop(c)
            return
        self._watch(c)

    def _watch(self, c: _Client) -> None:
        events = (selectors.EVENT_READ if c.reading else 0) | (selectors.EVENT_WRITE if c.out else 0)
        if events == c.events:
            return
        if c.events and events:
            self._sel.modify(c.sock, events, c)
        elif events:
            self._sel.register(c.sock, events, c)
        else:
            self._sel.unregister(c.sock)
        c.events = events

    def _alive(self, c: _Client) -> bool:
        return self._clients.get(c.sock.fileno()) is c

    def _drop(self, c: _Client) -> None:
        fd = c.sock.fileno()
        if self._clients.get(fd) is not c:
            return
        del self._clients[fd]
        if c.events:
            self._sel.unregister(c.sock)
            c.events = 0
        with contextlib.suppress(OSError):
            c.sock.close()

    def _farewell(self) -> None:
        """Give the clients a short while to take the last messages (the ``bye``)."""
        deadline = time.monotonic() + FAREWELL_S
        while any(c.out for c in self._clients.values()) and time.monotonic() < deadline:
            for key, _ in self._sel.select(max(deadline - time.monotonic(), 0.0)):
                if isinstance(key.data, _Client) and self._alive(key.data):
                    self._flush(key.data)


# -- the viewer's side --------------------------------------------------------------------
def connect(host: str, port: int, timeout: float = 5.0) -> socket.socket:
    """A connection to a component's monitor (OSError when there is none)."""
    sock = socket.create_connection((host, port), timeout=timeout)
    sock.settimeout(None)
    return sock


def item(msg: object) -> _view.Item | None:
    """What a viewer applies for one protocol message; None for what it ignores."""
    if not isinstance(msg, dict):
        return None
    kind = msg.get("type")
    if kind == "hello":
        if msg.get("protocol") != PROTOCOL:
            return "error", (f"the component speaks monitor protocol {msg.get('protocol')!r}; "
                             f"this viewer speaks {PROTOCOL}")
        return ("structure", msg["structure"]) if isinstance(msg.get("structure"), dict) else None
    if kind == "snapshot":
        ok = isinstance(msg.get("t"), int) and isinstance(msg.get("active", []), list)
        return ("snapshot", msg) if ok else None
    if kind == "record":
        rec = msg.get("record")
        return ("record", rec) if _view.check_record(rec) is None else None
    if kind == "sample":
        t, values, overruns = msg.get("t"), msg.get("variables"), msg.get("overruns")
        rate = msg.get("sim_rate")
        if not isinstance(rate, int | float) or isinstance(rate, bool) or not math.isfinite(rate) \
                or rate < 0:
            rate = None  # absent (not on the simulator's clock) or not a rate: not shown
        if isinstance(t, int) and isinstance(values, dict) and isinstance(overruns, int):
            return "sample", (t, values, overruns, rate)
        return None
    if kind == "ros2":  # minor 3: shown as sent (the view cleans what it prints)
        ok = isinstance(msg.get("name"), str) and isinstance(msg.get("subscriptions"), list) \
            and isinstance(msg.get("publications"), list)
        return ("ros2", msg) if ok else None
    if kind == "driver":  # minor 4: a user driver's snapshot
        return ("driver", msg) if _driverview.valid(msg) else None
    if kind == "busy":
        return "error", f"the component's monitor is busy: {msg.get('reason')}"
    if kind == "bye":
        reason = msg.get("reason")
        return "end", (f"component stopped ({reason})" if reason else "component closed the monitor")
    return None


def client_items(sock: socket.socket, label: str) -> Iterator[_view.Item]:
    """The items a viewer applies, read from a monitor connection until it ends."""
    stream = sock.makefile("rb")
    try:
        while True:
            try:
                line = stream.readline(LINE_LIMIT)
                while line and not line.endswith(b"\n"):  # overlong: skip it whole
                    line = stream.readline(LINE_LIMIT)
                    if line.endswith(b"\n"):
                        line = b"\n"
            except (OSError, ValueError):  # reset, or closed on the way out
                line = b""
            if not line:
                yield "end", f"disconnected from {label}"
                return
            try:
                it = item(json.loads(line))
            except ValueError:
                continue
            if it is not None:
                yield it
                if it[0] in ("end", "error"):
                    return
    finally:
        stream.close()
