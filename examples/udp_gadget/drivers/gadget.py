"""A UDP distance sensor with a LED and a buzzer: the driver of examples/udp_gadget.

The device (gadget_sim.py stands for it) answers whoever said `HELLO` last with a
reading, `D <metres> <led 0|1>`, 20 times a second, and obeys `LED <0|1>` and
`BEEP <ms>`. This driver says `HELLO` every half second until readings come, keeps the
latest in its listening thread, and hands it to the automaton once per instant.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from typing import Any, ClassVar

from hfsmc_driver import Driver, command, query


class Gadget(Driver):
    """A UDP distance sensor with a LED and a buzzer."""

    KIND = "gadget"
    DEFAULT_URL = "udp:127.0.0.1:9870"
    SNAPSHOT: ClassVar[dict[str, Any]] = {"distance": float("inf"), "age": float("inf"),
                                          "count": 0, "led": False}
    OPTIONS: ClassVar[dict[str, Any]] = {"stale": 1.0}

    def open(self) -> None:
        scheme, _, rest = str(self.url).partition(":")
        host, _, port = rest.rpartition(":")
        if scheme != "udp" or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"write udp:HOST:PORT, not `{self.url}`")
        self._device = (host, int(port))
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(("127.0.0.1" if host.startswith("127.") else "0.0.0.0", 0))
        self._sock.settimeout(0.1)
        self._lock = threading.Lock()
        self._latest: tuple[float, bool, float] | None = None
        self._count = 0
        self.start_thread(self._listen)

    def _listen(self) -> None:
        hello, said, bad = 0.0, "", 0
        while not self.stopping():
            now = time.monotonic()
            with self._lock:
                last = self._latest[2] if self._latest else None
            stale = last is None or now - last > self.options["stale"]
            if stale and now - hello > 0.5:
                hello = now
                self._send(b"HELLO")
            if stale and said == "readings":
                said = "stale"
                self.say(f"no reading for {self.options['stale']} s")
            try:
                data, _ = self._sock.recvfrom(512)
            except OSError:
                continue
            parts = data.split()
            try:
                if len(parts) != 3 or parts[0] != b"D":
                    raise ValueError
                reading = (float(parts[1]), parts[2] == b"1", time.monotonic())
            except ValueError:
                bad += 1
                if bad == 1:
                    self.say(f"a datagram that is no reading (dropped): {data[:40]!r}")
                continue
            with self._lock:
                self._latest = reading
                self._count += 1
            if said != "readings":
                self.say(f"readings from {self.url}" + (" again" if said else ""))
                said = "readings"

    def _send(self, data: bytes) -> None:
        with contextlib.suppress(OSError):  # no device yet: the next HELLO tries again
            self._sock.sendto(data, self._device)

    def read(self) -> dict[str, Any]:
        with self._lock:
            latest, count = self._latest, self._count
        if latest is None:
            return {}
        return {"distance": latest[0], "age": time.monotonic() - latest[2], "count": count,
                "led": latest[1]}

    def close(self) -> None:
        super().close()
        self._sock.close()

    @query
    def distance(self) -> float:
        """Metres to the obstacle in front; inf before the first reading."""
        return float(self.value("distance"))

    @query
    def age(self) -> float:
        """Seconds since the latest reading; inf before the first."""
        return float(self.value("age"))

    @query
    def ok(self) -> bool:
        """Readings are coming: the latest is younger than the `stale` option."""
        return bool(self.value("age") < self.options["stale"])

    @query
    def count(self) -> int:
        """Readings received so far."""
        return int(self.value("count"))

    @query
    def led_on(self) -> bool:
        """The LED is on, as the device last said."""
        return bool(self.value("led"))

    @command
    def led(self, on: bool) -> None:
        """Switch the LED on or off."""
        self._send(b"LED 1" if on else b"LED 0")

    @command
    def beep(self, ms: int) -> None:
        """Sound the buzzer for `ms` milliseconds."""
        self._send(b"BEEP %d" % int(ms))
