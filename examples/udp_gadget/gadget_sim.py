#!/usr/bin/env python3
"""A stand-in for the UDP gadget of examples/udp_gadget: a distance sensor that sees an
obstacle come and go (2 m down to 0.2 m and back, every `--period` seconds), a LED and
a buzzer. It answers whoever said HELLO last with `D <metres> <led>` at 20 Hz and prints
every command it obeys on stdout (`LED 1`, `BEEP 100`), one line each."""

from __future__ import annotations

import argparse
import socket
import sys
import time


def distance(t: float, period: float) -> float:
    phase = (t % period) / period  # a triangle: far, near, far
    return round(2.0 - 1.8 * (1 - abs(2 * phase - 1)), 3)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--port", type=int, default=9870)
    p.add_argument("--period", type=float, default=4.0, help="seconds of one come-and-go")
    p.add_argument("--for", dest="duration", type=float, default=0.0,
                   help="stop after that many seconds (0: never)")
    a = p.parse_args()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(("127.0.0.1", a.port))
    except OSError as e:
        sys.stderr.write(f"gadget_sim: cannot listen on udp:127.0.0.1:{a.port}: {e.strerror}\n")
        return 1
    sock.settimeout(0.05)
    print(f"gadget on udp:127.0.0.1:{sock.getsockname()[1]}", flush=True)
    start, client, led, nxt = time.monotonic(), None, False, 0.0
    while not a.duration or time.monotonic() - start < a.duration:
        now = time.monotonic() - start
        if client is not None and now >= nxt:
            nxt = now + 0.05
            sock.sendto(b"D %.3f %d" % (distance(now, a.period), led), client)
        try:
            data, sender = sock.recvfrom(128)
        except OSError:
            continue
        words = data.split()
        if words == [b"HELLO"]:
            client = sender
        elif len(words) == 2 and words[0] == b"LED" and words[1] in (b"0", b"1"):
            led = words[1] == b"1"
            print(f"LED {int(led)}", flush=True)
        elif len(words) == 2 and words[0] == b"BEEP" and words[1].isdigit():
            print(f"BEEP {int(words[1])}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
