"""The monitor: a running component serves its live state to ``hfsmc view``.

Copied beside every generated Python component (standard library only) and
imported by ``hfsmc view`` for the client side. The protocol (JSON lines over
TCP, read-only) is described in schemas/monitor.md and monitor.schema.json.

``MonitorServer`` is an observer of the runtime: its calls only put items on
a queue; one daemon thread owns the sockets and a ``ViewState``, from which a
client that connects late gets the current state at once. A slow client never
holds up the automaton or the other clients: each has a bounded buffer and is
dropped when it overflows. What clients send is read and thrown away.
"""

from __future__ import annotations

import contextlib
import json
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
    from . import hfsmc_view as _view
else:  # copied beside the generated component, where the modules are top level
    import hfsmc_view as _view  # type: ignore[import-not-found, no-redef]

PROTOCOL = 1
MAX_CLIENTS = 16  # more connections at once are closed as soon as they are accepted
BUFFER_LIMIT = 1 << 20  # bytes waiting for one client; beyond, the client is dropped
INPUT_LIMIT = 1 << 20  # bytes one client may send (all ignored); beyond, it is dropped
LINE_LIMIT = 1 << 24  # longest message a viewer reads
SLICE = 1 << 16  # bytes of messages made before the sockets are served again
FAREWELL_S = 0.5  # how long a stopping component tries to deliver the last messages


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
        t_ms, values, overruns = payload
        return {"type": "sample", "t": t_ms, "variables": values, "overruns": overruns}
    return None


class _Client:
    __slots__ = ("events", "out", "reading", "received", "sock")

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.out = bytearray()
        self.reading = True  # until the client shuts its side down
        self.received = 0
        self.events = 0  # what the selector watches for it


class MonitorServer:
    """The ``--monitor`` observer: a TCP server of JSON lines on a daemon thread.

    The socket is bound at construction (so an address in use fails at once)
    and ``monitor: listening on HOST:PORT`` goes to ``announce`` (stderr);
    port 0 picks a free port, read back from ``port``.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, announce: TextIO | None = None,
                 max_clients: int = MAX_CLIENTS, buffer_limit: int = BUFFER_LIMIT,
                 input_limit: int = INPUT_LIMIT) -> None:
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
        self._structure: dict[str, Any] = {}
        self._clients: dict[int, _Client] = {}
        self._sel = selectors.DefaultSelector()
        print(f"monitor: listening on {format_address(self.host, self.port)}",
              file=announce if announce is not None else sys.stderr, flush=True)

    # -- observer calls (automaton thread): queue and wake, never block ---------------------
    def start(self, structure: dict[str, Any]) -> None:
        self._q.put(("structure", structure))
        self._thread = threading.Thread(target=self._serve, name="hfsmc-monitor", daemon=True)
        self._thread.start()

    def record(self, rec: dict[str, Any]) -> None:
        self._q.put(("record", rec))
        self._wake()

    def sample(self, t_ms: int, values: dict[str, str], overruns: int) -> None:
        self._q.put(("sample", (t_ms, values, overruns)))
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
                for key, mask in self._sel.select(0 if more else 0.5):
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
                sock, _ = self._listener.accept()
            except OSError:  # nothing more to accept (or out of descriptors: try later)
                return
            if len(self._clients) >= self._max_clients:
                sock.close()
                continue
            sock.setblocking(False)
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            c = _Client(sock)
            self._clients[sock.fileno()] = c
            hello = {"type": "hello", "protocol": PROTOCOL, "structure": self._structure}
            c.out += encode(hello) + encode(view.snapshot())
            self._flush(c)

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
        if isinstance(t, int) and isinstance(values, dict) and isinstance(overruns, int):
            return "sample", (t, values, overruns)
        return None
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
