"""`hfsmc sim --lockstep`: the simulator as the time master of one component.

The component connects over TCP (JSON lines, schemas/lockstep.md) beside the MAVLink
link and the camera's stream. Time only advances when both sides are done with it:

- the component says ``{"next": T, "sent": M}``: it has run every instant before T,
  has sent M MAVLink datagrams in all, and wants to be woken at T (µs);
- the simulator reads the component's datagrams up to M, applies them at its present
  step, steps the physics up to the last step at or before T (rendering the camera's
  frames due on the way) and answers ``{"t": T, "sent": N, "frame": K, ...}``: N
  datagrams sent in all, K the number of the camera's latest frame;
- the component's drivers wait until they hold datagram N and frame K, then the
  component runs its instant at T.

Neither side reads the wall clock, so a flight depends only on the world, the seed, the
model and its parameters. ``--speedup N`` holds the simulator back to N times real
time (a person watching); the order of events does not change.
"""

from __future__ import annotations

import json
import math
import select
import socket
import time
from typing import Any, Protocol

PROTOCOL = "hfsmc-lockstep"
VERSION = 1
DATAGRAM_WAIT_S = 5.0  # the component's datagrams, counted, are late: said and skipped
ANSWER_WAIT_S = 30.0  # a component silent that long is taken for gone (a stopped process)
POLL_S = 0.1  # how often waits look at the stop flag (signals)


class LockstepError(Exception):
    """The component broke the protocol, or cannot be served."""


def parse_address(text: str) -> tuple[str, int]:
    """``PORT`` (on 127.0.0.1) or ``HOST:PORT``."""
    host, _, port = text.rpartition(":")
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"--lockstep {text!r}: expected [HOST:]PORT")
    return host or "127.0.0.1", int(port)


class Sim(Protocol):
    """What the lockstep loop needs of hfsmc.sim.run.Simulator."""

    stopping: bool
    link: Any
    body: Any
    ap: Any
    camera: Any

    def log(self, text: str) -> None: ...
    def advance(self, duration: float | None = None) -> bool: ...
    def _faults(self) -> None: ...


class Channel:
    """One component's connection: JSON lines both ways, reads bounded in time."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.buf = b""
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def send(self, msg: dict[str, Any]) -> bool:
        try:
            self.sock.sendall(json.dumps(msg, separators=(",", ":")).encode() + b"\n")
        except OSError:
            return False
        return True

    def read(self, stopping: Any, timeout: float) -> dict[str, Any] | None:
        """The next message; None when the component has gone (closed, silent for
        ``timeout``) or ``stopping()`` became true. LockstepError on garbage."""
        end = time.monotonic() + timeout
        while b"\n" not in self.buf:
            if stopping() or time.monotonic() > end:
                return None
            try:
                ready, _, _ = select.select([self.sock], [], [], POLL_S)
            except InterruptedError:
                continue
            if not ready:
                continue
            try:
                data = self.sock.recv(65536)
            except OSError:
                return None
            if not data:
                return None
            self.buf += data
            if len(self.buf) > 1 << 16:
                raise LockstepError("a line longer than 64 KiB")
        line, _, self.buf = self.buf.partition(b"\n")
        try:
            msg = json.loads(line)
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise LockstepError(f"not a JSON line: {line[:60]!r}") from None
        if not isinstance(msg, dict):
            raise LockstepError(f"not a JSON object: {line[:60]!r}")
        return msg

    def close(self) -> None:
        self.sock.close()


class Server:
    """The listening socket (loopback unless a host is named) and the one component."""

    def __init__(self, address: str) -> None:
        host, port = parse_address(address)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, port))
            self.sock.listen(1)
        except OSError:
            self.sock.close()
            raise
        self.channel: Channel | None = None
        self.hello: dict[str, Any] = {}  # the component's hello (its topics, with ROS 2)

    def describe(self) -> str:
        host, port = self.sock.getsockname()
        return f"lockstep on tcp:{host}:{port}"

    def accept(self, stopping: Any) -> tuple[Channel, str] | None:
        """Wait for a component and its hello; None when stopping first."""
        while not stopping():
            try:
                ready, _, _ = select.select([self.sock], [], [], POLL_S)
            except InterruptedError:
                continue
            if not ready:
                continue
            conn, _ = self.sock.accept()
            channel = Channel(conn)
            try:
                hello = channel.read(stopping, ANSWER_WAIT_S)
            except LockstepError:
                hello = None
            if hello is None or hello.get("hello") != PROTOCOL or hello.get("version") != VERSION:
                channel.send({"error": f"expected {{\"hello\": \"{PROTOCOL}\", \"version\": "
                                       f"{VERSION}}}"})
                channel.close()
                continue  # a stray client: wait for the component
            self.channel = channel
            self.hello = hello
            return channel, str(hello.get("component", "?"))
        return None

    def close(self) -> None:
        if self.channel is not None:
            self.channel.send({"bye": "simulator stopped"})
            self.channel.close()
            self.channel = None
        self.sock.close()


def fly(sim: Sim, server: Server, duration: float | None, speedup: float,
        when_gone: str) -> bool:
    """Fly in lockstep until stopped, ``duration``, or the component's end. True when the
    simulator is to go on in real time (``when_gone`` == "realtime" and the component
    went)."""
    step_us = round(sim.body.dt * 1e6)
    sim.log(f"lockstep: waiting for a component on {server.describe().partition(' on ')[2]}")
    got = server.accept(lambda: sim.stopping)
    if got is None:
        return False
    channel, name = got
    rate = "as fast as it goes" if math.isinf(speedup) else f"{speedup:g}x real time"
    channel.send({"hello": PROTOCOL, "version": VERSION, "step_us": step_us})
    sim.log(f"lockstep: component {name} connected; simulated time runs {rate}")
    camera = sim.camera
    frame_every = 1e6 / max(camera.world.camera.fps, 0.1) if camera is not None else math.inf
    next_frame = 1  # frame 1 was rendered at 0 by the camera's start
    wall0 = time.monotonic() - sim.body.t / speedup
    while not sim.stopping:
        try:
            msg = channel.read(lambda: sim.stopping, ANSWER_WAIT_S)
        except LockstepError as e:
            sim.log(f"lockstep: the component broke the protocol ({e}); it is dropped")
            msg = None
        if msg is None or "bye" in msg:
            if sim.stopping:
                return False
            why = f" ({msg['bye']})" if msg is not None else ""
            then = "goes on in real time" if when_gone == "realtime" else "stops"
            sim.log(f"lockstep: the component has gone{why}; the simulator {then}")
            server.channel = None
            channel.close()
            return when_gone == "realtime"
        until, sent = msg.get("next"), msg.get("sent")
        if not isinstance(until, int) or not isinstance(sent, int) or until < 0 or sent < 0:
            sim.log(f"lockstep: not a request: {json.dumps(msg)[:80]}; the component is dropped")
            channel.close()
            server.channel = None
            return when_gone == "realtime"
        _take(sim, sent)
        while (sim.body.steps + 1) * step_us <= until and not sim.stopping:
            sim._faults()
            if sim.advance(duration):
                return False
            now_us = sim.body.steps * step_us
            if camera is not None and now_us >= round(next_frame * frame_every):
                while now_us >= round(next_frame * frame_every):
                    next_frame += 1
                camera.shoot_at(now_us)
        if not math.isinf(speedup):
            ahead = wall0 + sim.body.t / speedup - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
        live = camera is not None and not camera.paused
        if not channel.send({"t": until, "now": sim.body.steps * step_us, "sent": sim.link.sent,
                             "frame": camera.count if live else 0,
                             "frame_t": camera.frame_us if live else 0}):
            continue  # gone: the next read says so
    return False


def _take(sim: Sim, count: int) -> None:
    """Read and apply the component's datagrams until ``count`` have come in all."""
    link = sim.link
    end = time.monotonic() + DATAGRAM_WAIT_S
    while True:
        for data in link.receive():
            sim.ap.receive(data)
        if link.received >= count or sim.stopping:
            return
        left = end - time.monotonic()
        if left <= 0:
            sim.log(f"lockstep: {count - link.received} of the component's datagrams did not "
                    f"come in {DATAGRAM_WAIT_S:g} s; going on without them")
            link.received = count
            return
        try:
            select.select([link.sock], [], [], min(left, POLL_S))
        except InterruptedError:
            continue
