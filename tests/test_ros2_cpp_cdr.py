"""The C++ message types of the ``ros2`` interface put every message on the wire as rosbags
does (docs/ros2-cpp.md): one compiled program per distro holds every standard message type
hfsmc generates; messages filled with random values by rosbags go through it (read, then
written again) and come back byte for byte; messages built field by field in C++ are
rosbags' bytes of the same values; a malformed sample is refused, never read past its end."""

from __future__ import annotations

import random
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from hfsmc.ros2.cpp_messages import RUNTIME_TYPES, cpp_message_files, cpp_type_name, header_path
from hfsmc.ros2.definitions import message_set
from tests.ros2_support import AT
from tests.support import ROOT

STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY}
NUMPY = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8,
         "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
         "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64, "float32": np.float32,
         "float64": np.float64}

# Built in C++ field by field (the program's `built` mode); the same values through rosbags.
BUILT = r"""
  if (which == "twist") {
    geometry_msgs::msg::Twist t;
    t.linear.x = 0.5; t.angular.z = -1.25;
    return hfsmc::cdr::serialize(t);
  }
  if (which == "scan") {
    sensor_msgs::msg::LaserScan s;
    s.header.stamp.sec = 12; s.header.stamp.nanosec = 345u; s.header.frame_id = "base_scan";
    s.angle_min = -1.5f; s.angle_max = 1.5f; s.range_max = 8.0f;
    s.ranges = {1.0f, 2.5f, 3.0f};
    return hfsmc::cdr::serialize(s);
  }
  if (which == "shape") {
    shape_msgs::msg::SolidPrimitive p;
    p.type = shape_msgs::msg::SolidPrimitive::BOX;
    p.dimensions = {1.0, 2.0, 3.0};
    p.polygon.points.resize(2);
    p.polygon.points[1].y = 4.0f;
    return hfsmc::cdr::serialize(p);
  }
  if (which == "quat") {  // Quaternion.msg: `float64 w 1`
    return hfsmc::cdr::serialize(geometry_msgs::msg::Quaternion());
  }
"""


def _built(store: Any, which: str) -> bytes:
    t = store.types
    time = t["builtin_interfaces/msg/Time"]
    if which == "twist":
        v3 = t["geometry_msgs/msg/Vector3"]
        msg = t["geometry_msgs/msg/Twist"](v3(0.5, 0.0, 0.0), v3(0.0, 0.0, -1.25))
        return bytes(store.serialize_cdr(msg, "geometry_msgs/msg/Twist"))
    if which == "scan":
        header = t["std_msgs/msg/Header"](time(12, 345), "base_scan")
        msg = t["sensor_msgs/msg/LaserScan"](header, -1.5, 1.5, 0.0, 0.0, 0.0, 0.0, 8.0,
                                             np.array([1.0, 2.5, 3.0], np.float32),
                                             np.array([], np.float32))
        return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
    if which == "quat":
        msg = t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)
        return bytes(store.serialize_cdr(msg, "geometry_msgs/msg/Quaternion"))
    p32 = t["geometry_msgs/msg/Point32"]
    polygon = t["geometry_msgs/msg/Polygon"]([p32(0.0, 0.0, 0.0), p32(0.0, 4.0, 0.0)])
    msg = t["shape_msgs/msg/SolidPrimitive"](1, np.array([1.0, 2.0, 3.0]), polygon)
    return bytes(store.serialize_cdr(msg, "shape_msgs/msg/SolidPrimitive"))


def _types(store: Any) -> list[str]:
    """Every message type of the distro's store that has a C++ face (no wstring)."""
    out = []
    for name, (_, fields) in sorted(store.fielddefs.items()):
        text = repr(fields)
        if "wstring" not in text:
            out.append(name)
    return out


def _program(types: list[str]) -> str:
    includes = "\n".join(f'#include "{header_path(t)}"' for t in types)
    cases = "\n".join(
        f'  if (type == "{t}") {{ auto m = hfsmc::cdr::deserialize<{cpp_type_name(t)}>'
        f"(in.data(), in.size()); return hfsmc::cdr::serialize(m); }}" for t in types)
    return f"""#include <iostream>
#include <string>
#include <vector>
{includes}

static std::vector<std::uint8_t> roundtrip(const std::string& type,
                                           const std::vector<std::uint8_t>& in) {{
{cases}
  throw std::runtime_error("no such type " + type);
}}

static std::vector<std::uint8_t> built(const std::string& which) {{
{BUILT}
  throw std::runtime_error("no such message " + which);
}}

static std::string hex(const std::vector<std::uint8_t>& v) {{
  static const char* d = "0123456789abcdef";
  std::string s;
  for (auto b : v) {{ s += d[b >> 4]; s += d[b & 15]; }}
  return s;
}}

int main() {{
  std::string mode, type, h;
  while (std::cin >> mode >> type >> h) {{
    try {{
      if (mode == "built") {{ std::cout << hex(built(type)) << std::endl; continue; }}
      std::vector<std::uint8_t> in;
      for (std::size_t i = 0; i + 1 < h.size(); i += 2)
        in.push_back(static_cast<std::uint8_t>(std::stoi(h.substr(i, 2), nullptr, 16)));
      std::cout << hex(roundtrip(type, in)) << std::endl;
    }} catch (const hfsmc::cdr::Malformed& e) {{
      std::cout << "malformed " << e.what() << std::endl;
    }}
  }}
}}
"""


@pytest.fixture(scope="module", params=sorted(STORES))
def program(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
            ) -> tuple[str, Any, list[str], Path]:
    distro = request.param
    store = get_typestore(STORES[distro])
    types = _types(store)
    out = tmp_path_factory.mktemp(f"cdr-{distro}")
    ms = message_set(distro, [(t, AT) for t in [*types, *RUNTIME_TYPES]])
    for rel, text in cpp_message_files(ms, model="test").items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    (out / "main.cpp").write_text(_program(types))
    exe = out / "cdr"
    subprocess.run(["g++", "-std=c++17", "-O0", "-Wall", "-Wextra", "-Werror", "-I",
                    str(out / "include"), "-I", str(ROOT / "templates" / "cpp"),
                    str(out / "main.cpp"), "-o", str(exe)], check=True, timeout=600)
    return distro, store, types, exe


def _run(exe: Path, lines: list[str]) -> list[str]:
    done = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True,
                          text=True, timeout=120, check=True)
    return done.stdout.splitlines()


def _value(store: Any, kind: int, desc: Any, rng: random.Random) -> Any:
    if kind == 2:
        return _message(store, desc, rng)
    if kind == 1:
        base, bound = desc
        if base == "string":
            return "".join(rng.choice("abcxyz_/ 09") for _ in range(rng.randint(0, bound or 9)))
        return _scalar(base, rng)
    (ekind, edesc), size = desc
    n = size if kind == 3 else rng.randint(0, size or 4)
    if ekind == 1 and edesc[0] != "string":
        return np.array([_scalar(edesc[0], rng) for _ in range(n)], dtype=NUMPY[edesc[0]])
    return [_value(store, ekind, edesc, rng) for _ in range(n)]


def _scalar(base: str, rng: random.Random) -> Any:
    if base == "bool":
        return rng.random() < 0.5
    if base.startswith("float"):
        return float(np.dtype(NUMPY[base]).type(rng.uniform(-1e3, 1e3)))
    if base == "byte":  # an octet to rclcpp, a signed char to rosbags: both agree on 0..127
        return rng.randint(0, 127)
    info = np.iinfo(NUMPY[base])
    return rng.randint(int(info.min), int(info.max))


def _message(store: Any, name: str, rng: random.Random) -> Any:
    fields = store.fielddefs[name][1]
    return store.types[name](*[_value(store, k, d, rng) for _, (k, d) in fields])


def test_every_type_round_trips_byte_for_byte(program: tuple[str, Any, list[str], Path]) -> None:
    """Three random messages of every standard type: read and written again by the
    generated C++, the bytes are rosbags' (nested, fixed and bounded arrays, strings,
    sequences of messages, every primitive)."""
    distro, store, types, exe = program
    rng = random.Random(32)
    lines, expected = [], []
    for t in types:
        for _ in range(3):
            data = bytes(store.serialize_cdr(_message(store, t, rng), t))
            lines.append(f"rt {t} {data.hex() or '-'}")
            expected.append(data.hex())
    got = _run(exe, lines)
    bad = [(line.split()[1], g) for line, g, e in zip(lines, got, expected, strict=True)
           if g != e]
    assert not bad, f"{distro}: {len(bad)} differ, first {bad[0]}"
    assert len(types) > 100  # the whole store, not a few


def test_messages_built_in_cpp_are_rosbags_bytes(
        program: tuple[str, Any, list[str], Path]) -> None:
    """Defaults (zero, and the .msg's: Quaternion's w 1) and fields set by rclcpp's names give rosbags' bytes of the same values."""
    _, store, _, exe = program
    which = ("twist", "scan", "shape", "quat")
    got = _run(exe, [f"built {w} -" for w in which])
    assert got == [_built(store, w).hex() for w in which]


def test_a_malformed_sample_is_refused(program: tuple[str, Any, list[str], Path]) -> None:
    """Cut short, a string without its NUL, a sequence longer than the sample, a bound
    passed, another encapsulation: Malformed, never a crash or a read past the end."""
    _, store, _, exe = program
    scan = _built(store, "scan")
    shape = _built(store, "shape")
    cut = [scan[:n] for n in (0, 3, 4, 10, 20, len(scan) - 1)]
    no_nul = bytearray(scan)
    no_nul[4 + 8 + 4 + len("base_scan")] = 0x41  # the frame_id's NUL
    huge = bytearray(scan)
    at = scan.index(bytes([3, 0, 0, 0]), 40)  # the count of `ranges`
    huge[at:at + 4] = (0x7fffffff).to_bytes(4, "little")
    over = bytearray(shape)
    over[8:12] = (4).to_bytes(4, "little")  # dimensions: 4 > its bound 3
    xcdr2 = b"\x00\x07" + bytes(scan[2:])
    lines = [f"rt sensor_msgs/msg/LaserScan {bytes(b).hex() or '-'}"
             for b in [*cut, no_nul, huge, xcdr2]]
    lines.append(f"rt shape_msgs/msg/SolidPrimitive {bytes(over).hex()}")
    got = _run(exe, lines)
    assert len(got) == len(lines)
    assert all(g.startswith("malformed ") for g in got), got
