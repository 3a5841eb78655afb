"""CDR for the generated ROS 2 message classes (docs/ros2.md, "On the wire").

Copied beside a component that has a ``ros2`` interface, with the message packages
hfsmc generates (``geometry_msgs/msg/__init__.py``...), which import it. It needs nothing
but Python (numpy only for a message with a fixed-size numeric array, as rclpy).

The encoding is ROS 2's: plain CDR (XCDR1), little endian, behind the 4-byte
encapsulation header ``00 01 00 00``; each primitive aligned to its size (8 at most),
counted from the byte after the header; a string is its UTF-8 length + 1 (uint32), the
bytes and a NUL; a sequence its count (uint32), then its items, aligned only when there
is one. :func:`serialize` gives the bytes rosbags' ``serialize_cdr`` gives for the same
message; :func:`deserialize` raises :class:`CdrError` on any malformed buffer, never
allocating more than the buffer could hold.
"""

from __future__ import annotations

import struct
import sys
from array import array
from typing import Any

HEADER_LE = b"\x00\x01\x00\x00"
_LITTLE = sys.byteorder == "little"
_U32 = struct.Struct("<I")


class CdrError(ValueError):
    """A sample that is not a valid CDR encoding of its message type."""


class MessageError(TypeError):
    """A message that cannot be sent: a field of the wrong type, out of range, too long.
    ``path`` names the field (``linear.x``)."""

    def __init__(self, path: str, why: str, owner: str = "") -> None:
        super().__init__(f"{owner}: field `{path}`: {why}" if owner else f"field `{path}`: {why}")
        self.path = path
        self.why = why


def serialize(msg: Any) -> bytes:
    """The CDR bytes of ``msg`` (an instance of a generated message class), header first.
    Raises MessageError (a TypeError) naming the field that does not fit."""
    ser = getattr(type(msg), "_ser", None)
    if ser is None:
        raise TypeError(f"not a ROS 2 message: {type(msg).__name__}")
    out = bytearray(HEADER_LE)
    try:
        ser(msg, out)
    except MessageError as exc:
        raise MessageError(exc.path, exc.why, msg._TYPE) from None
    return bytes(out)


def deserialize(cls: Any, data: bytes | bytearray | memoryview) -> Any:
    """The message of class ``cls`` that ``data`` (header first) encodes. Raises CdrError."""
    if len(data) < 4:
        raise CdrError(f"{len(data)} bytes: shorter than the CDR header")
    head = bytes(data[:2])
    if head != b"\x00\x01":
        kind = "big-endian CDR" if head == b"\x00\x00" else f"encapsulation {head.hex()}"
        raise CdrError(f"{kind} is not supported (ROS 2 sends little-endian plain CDR)")
    buf = memoryview(data)[4:]
    try:
        msg, pos = cls._de(buf, 0)
    except CdrError:
        raise
    except (struct.error, IndexError, ValueError, UnicodeDecodeError, OverflowError) as exc:
        raise CdrError(f"malformed {cls._TYPE}: {exc}") from None
    if pos > len(buf):
        raise CdrError(f"malformed {cls._TYPE}: {pos} bytes needed, {len(buf)} sent")
    return msg


# -- writing (offsets count from the byte after the header: len(out) - 4) ------------------


def align(out: bytearray, n: int) -> None:
    pad = -(len(out) - 4) % n
    if pad:
        out += b"\x00" * pad


def put_bool(out: bytearray, v: Any) -> None:
    if v is not True and v is not False and type(v).__name__ != "bool_":
        raise MessageError("", f"must be a bool, not {type(v).__name__}")
    out.append(1 if v else 0)


def put_byte(out: bytearray, v: Any) -> None:
    """A ``byte`` (IDL octet): bytes of length 1, as rclpy, or an int 0..255."""
    if isinstance(v, bytes | bytearray) and len(v) == 1:
        out += v
    elif isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255:
        out.append(v)
    else:
        raise MessageError("", f"must be a byte (b'\\x00' or 0..255), not {v!r:.40}")


def put_str(out: bytearray, v: Any, bound: int) -> None:
    if not isinstance(v, str):
        raise MessageError("", f"must be a str, not {type(v).__name__}")
    if bound and len(v) > bound:
        raise MessageError("", f"{len(v)} characters, more than its bound {bound}")
    data = v.encode()
    align(out, 4)
    out += _U32.pack(len(data) + 1)
    out += data
    out.append(0)


def put_count(out: bytearray, v: Any, bound: int) -> int:
    """A sequence's count (a bounded one checked); returns it."""
    try:
        n = len(v)
    except TypeError:
        raise MessageError("", f"must be a sequence, not {type(v).__name__}") from None
    if bound and n > bound:
        raise MessageError("", f"{n} items, more than its bound {bound}")
    align(out, 4)
    out += _U32.pack(n)
    return n


def check_fixed(v: Any, n: int) -> None:
    try:
        have = len(v)
    except TypeError:
        raise MessageError("", f"must be a sequence of {n}, not {type(v).__name__}") from None
    if have != n:
        raise MessageError("", f"{have} items for an array of exactly {n}")


def put_prims(out: bytearray, v: Any, code: str, size: int) -> None:
    """The items of a numeric array (already counted), aligned when there is one."""
    n = len(v)
    if not n:
        return
    align(out, size)
    if _LITTLE and type(v) is array and v.typecode == code:
        out += v.tobytes()
        return
    dtype = getattr(v, "dtype", None)
    if dtype is not None:  # numpy: rclpy's type for fixed-size arrays
        out += v.astype(_NP[code], copy=False).tobytes()
        return
    try:
        out += struct.pack(f"<{n}{_FMT[code]}", *v)
    except struct.error as exc:
        raise MessageError("", f"an item does not fit ({exc})") from None


def put_each(out: bytearray, v: Any, put: Any, *extra: Any) -> None:
    """Items one by one (bool, byte, string)."""
    for i, item in enumerate(v):
        try:
            put(out, item, *extra)
        except MessageError as exc:
            raise MessageError(f"[{i}]", exc.why) from None


def put_msgs(out: bytearray, v: Any, cls: Any) -> None:
    for i, item in enumerate(v):
        if type(item) is not cls:
            raise MessageError(f"[{i}]", f"must be a {cls._TYPE}, not {type(item).__name__}")
        try:
            item._ser(out)
        except MessageError as exc:
            raise MessageError(f"[{i}].{exc.path}".rstrip("."), exc.why) from None


def wrong(field: str, exc: Exception) -> MessageError:
    """The error to raise for ``field`` of a message being written."""
    if isinstance(exc, MessageError):
        path = f"{field}.{exc.path}" if exc.path and not exc.path.startswith("[") else \
            field + exc.path
        return MessageError(path, exc.why)
    if isinstance(exc, struct.error | OverflowError):
        return MessageError(field, f"does not fit its type ({exc})")
    return MessageError(field, f"{type(exc).__name__}: {exc}")


def not_a(field: str, v: Any, cls: Any) -> MessageError:
    return MessageError(field, f"must be a {cls._TYPE}, not {type(v).__name__}")


# -- reading (pos counts from the byte after the header) -----------------------------------


def get_str(buf: memoryview, pos: int, bound: int) -> tuple[str, int]:
    pos = (pos + 3) & -4
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    if n > len(buf) - pos:
        raise CdrError(f"a string of {n} bytes at {pos}, past the end ({len(buf)})")
    text = bytes(buf[pos:pos + n]).rstrip(b"\x00").decode()
    if bound and len(text) > bound:
        raise CdrError(f"a string of {len(text)} characters, more than its bound {bound}")
    return text, pos + n


def get_count(buf: memoryview, pos: int, least: int, bound: int) -> tuple[int, int]:
    """A sequence's count; each item takes at least ``least`` bytes, so a count the rest of
    the buffer cannot hold is an error before anything is allocated."""
    pos = (pos + 3) & -4
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    if bound and n > bound:
        raise CdrError(f"a sequence of {n} items, more than its bound {bound}")
    if n * least > len(buf) - pos:
        raise CdrError(f"a sequence of {n} items at {pos}, past the end ({len(buf)})")
    return n, pos


def get_prims(buf: memoryview, pos: int, n: int, code: str, size: int) -> tuple[array[Any], int]:
    """``n`` numeric items as an array.array (rclpy's type for sequences)."""
    out = array(code)
    if n:
        pos = (pos + size - 1) & -size
        end = pos + n * size
        if end > len(buf):
            raise CdrError(f"{n} items at {pos}, past the end ({len(buf)})")
        out.frombytes(buf[pos:end])
        if not _LITTLE:
            out.byteswap()
        pos = end
    return out, pos


def get_fixed(buf: memoryview, pos: int, n: int, code: str, size: int) -> tuple[Any, int]:
    """``n`` numeric items as a numpy array (rclpy's type for fixed-size arrays)."""
    import numpy as np

    pos = (pos + size - 1) & -size
    end = pos + n * size
    if end > len(buf):
        raise CdrError(f"{n} items at {pos}, past the end ({len(buf)})")
    return np.frombuffer(buf, dtype=_NP[code], count=n, offset=pos).copy(), end


def get_bools(buf: memoryview, pos: int, n: int) -> tuple[list[bool], int]:
    if pos + n > len(buf):
        raise CdrError(f"{n} bools at {pos}, past the end ({len(buf)})")
    return [b != 0 for b in buf[pos:pos + n]], pos + n


def get_bytes(buf: memoryview, pos: int, n: int) -> tuple[list[bytes], int]:
    if pos + n > len(buf):
        raise CdrError(f"{n} bytes at {pos}, past the end ({len(buf)})")
    return [bytes((b,)) for b in buf[pos:pos + n]], pos + n


def get_strs(buf: memoryview, pos: int, n: int, bound: int) -> tuple[list[str], int]:
    out: list[str] = []
    for _ in range(n):
        text, pos = get_str(buf, pos, bound)
        out.append(text)
    return out, pos


def get_msgs(buf: memoryview, pos: int, n: int, cls: Any) -> tuple[list[Any], int]:
    out: list[Any] = []
    for _ in range(n):
        msg, pos = cls._de(buf, pos)
        out.append(msg)
    return out, pos


def same(a: Any, b: Any) -> bool:
    """Field equality that numpy arrays (fixed-size arrays) take part in."""
    if hasattr(a, "dtype") or hasattr(b, "dtype"):
        return bool(len(a) == len(b) and all(x == y for x, y in zip(a, b, strict=True)))
    return bool(a == b)


def zeros(code: str, n: int) -> Any:
    """A fixed-size numeric array of ``n`` zeros (numpy, as rclpy)."""
    import numpy as np

    return np.zeros(n, dtype=_NP[code])


def fixed_of(code: str, values: Any) -> Any:
    import numpy as np

    return np.array(values, dtype=_NP[code])


# array.array type code -> struct format and numpy dtype (little endian)
_FMT = {"b": "b", "B": "B", "h": "h", "H": "H", "i": "i", "I": "I", "q": "q", "Q": "Q",
        "f": "f", "d": "d"}
_NP = {"b": "<i1", "B": "<u1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4", "q": "<i8",
       "Q": "<u8", "f": "<f4", "d": "<f8"}
