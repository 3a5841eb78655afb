"""The names a local server answers to: the Host header's name, and loopback names.

A browser sends in ``Host`` the name it looked up, so a page served under a
name that a DNS server made point at 127.0.0.1 (DNS rebinding) says so there.
The web view (hfsmc/web/server.py) and the simulator's camera (hfsmc/sim/mjpeg.py)
answer only under loopback names and the names their user gave (docs/web.md).
"""

from __future__ import annotations

import ipaddress
import re

_NAME = re.compile(r"[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?(\.[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?)*")


def host_name(header: str | None) -> str | None:
    """The name of a ``Host`` header (``[::1]:8080`` -> ``::1``, ``Robot.local.:80`` ->
    ``robot.local``), lower case; None when there is none or it is not a host name."""
    if not header or len(header) > 300:
        return None
    text = header.strip().lower()
    if text.startswith("["):
        end = text.find("]")
        rest = text[end + 1:]
        if end < 0 or (rest and not re.fullmatch(r":[0-9]{1,5}", rest)):
            return None
        try:
            return str(ipaddress.IPv6Address(text[1:end]))
        except ValueError:
            return None
    name, colon, port = text.rpartition(":")
    if not colon:
        name = text
    elif not re.fullmatch(r"[0-9]{1,5}", port):
        return None
    return normal_name(name)


def normal_name(text: str) -> str | None:
    """A host name or IP address as compared (lower case, no final dot, IPv6 without
    brackets and in its short form); None when ``text`` is neither."""
    text = text.strip().lower()
    if text.startswith("[") and text.endswith("]"):
        text = text[1:-1]
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        pass
    text = text.removesuffix(".")
    return text if len(text) <= 253 and _NAME.fullmatch(text) else None


def is_loopback(name: str) -> bool:
    """Whether ``name`` (as ``normal_name`` gives it) is this machine's loopback: an
    address of 127.0.0.0/8 or ::1, ``localhost`` or a name under it (which browsers
    resolve to loopback themselves, never through DNS)."""
    if name == "localhost" or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def is_unspecified(name: str) -> bool:
    """Whether ``name`` is 0.0.0.0 or ::, which a server listens on but no one connects to."""
    try:
        return ipaddress.ip_address(name).is_unspecified
    except ValueError:
        return False


def allowed_name(text: str) -> str:
    """An ``--allow-host`` value as compared; ValueError with the reason when it is none."""
    name = normal_name(text)
    if name is None or is_unspecified(name):
        raise ValueError(f"bad --allow-host {text!r}: expected a host name or an IP address, "
                         "without a port")
    return name
