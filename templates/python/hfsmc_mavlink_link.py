"""The link plumbing of the ``mavlink`` interface (hfsmc_mavlink.py), copied beside a
component with it: duplicate frames dropped, datagrams counted for the lockstep, options
read, a half-open socket closed. Nothing here knows an autopilot."""

from __future__ import annotations

import collections
import math
import socket
import sys
from typing import Any

DUPLICATE_WINDOW = 255  # frames remembered per source: a copy of one of them is dropped
SILENCE_S = 0.5  # a source silent that long (a reboot) is remembered afresh


class Duplicates:
    """Per source (system, component): its last frames (bytes), how many of each, when."""

    def __init__(self) -> None:
        self.recent: dict[tuple[int, int], tuple[collections.deque[bytes],
                                                 collections.Counter[bytes]]] = {}
        self.at: dict[tuple[int, int], float] = {}

    def seen(self, now: float, source: tuple[int, int], frame: bytes) -> bool:
        """A copy of one of the last DUPLICATE_WINDOW frames of that source (same seq, same
        bytes): a network duplicate, however late. A new frame can only be byte for byte
        an old one 256 frames later (seq is 8 bits)."""
        if now - self.at.get(source, -math.inf) > SILENCE_S:
            self.recent[source] = (collections.deque(), collections.Counter())
        self.at[source] = now
        order, count = self.recent[source]
        if count[frame]:
            return True
        order.append(frame)
        count[frame] += 1
        if len(order) > DUPLICATE_WINDOW:
            old = order.popleft()
            count[old] -= 1
            if not count[old]:
                del count[old]
        return False


class Counted:
    """Lockstep: the datagrams that go through pymavlink's UDP socket, both ways."""

    def __init__(self, conn: Any) -> None:
        self.sent = 0
        self.received = 0
        recv, write = conn.recv, conn.write

        def counted_recv(n: Any = None) -> Any:
            data = recv(n)
            if data:
                self.received += 1
            return data

        def counted_write(buf: Any) -> None:
            write(buf)
            self.sent += len(conn.clients) if conn.udp_server else 1

        conn.recv, conn.write = counted_recv, counted_write


def option(name: str, options: dict[str, str], key: str, default: float) -> float:
    """A positive number from the interface's options; a bad one is said and replaced."""
    raw = options.get(key)
    if raw is None:
        return default
    try:
        value = float(raw)
    except (TypeError, ValueError):
        value = -1.0
    if not value > 0 or math.isinf(value):
        sys.stderr.write(f"{name}: option {key}: `{raw}` is not a positive number, "
                         f"{default:g} used\n")
        return default
    return value


def close_half_open(error: BaseException) -> None:
    """pymavlink keeps the socket it failed to bind (or connect) open: close it."""
    tb = error.__traceback__
    while tb is not None:
        port = getattr(tb.tb_frame.f_locals.get("self"), "port", None)
        if isinstance(port, socket.socket):
            port.close()
        tb = tb.tb_next
