"""What the ROS 2 tests share: a domain of their own, generated message packages loaded in
this process, hypothesis strategies that draw a message as ours and as rosbags', and a
built Python component run against the simulated ground robot (tests/test_ros2_*.py)."""

from __future__ import annotations

import contextlib
import fcntl
import importlib
import json
import os
import subprocess
import sys
import tempfile
from array import array
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

from hfsmc.errors import Span
from hfsmc.ros2.definitions import FieldType, MessageSet, MsgFile, message_set
from hfsmc.ros2.python_messages import python_message_files
from tests.conftest import LOOPBACK_DDS
from tests.support import ROOT, hfsmc, interrupt

AT = Span("test.yaml", 1, 1)
STOP_AT_WALL = ROOT / "examples" / "stop_at_wall" / "stop_at_wall.yaml"
# DDS in the tests stays on the loopback interface (multicast discovery on `lo`): other
# machines and interfaces never see them. tests/conftest.py sets it for the whole run.
LOOPBACK = LOOPBACK_DDS
DOMAINS = range(10, 102)  # ROS_DOMAIN_ID values the tests use: not 0 (ROS 2's default), and
# none above 101, whose ports (7400 + 250 * id and up) fall in the kernel's ephemeral range


@contextlib.contextmanager
def ros2_domain() -> Iterator[int]:
    """A ROS 2 domain id that no other test holds meanwhile, on this machine, whatever
    process runs it (pytest-xdist workers, another checkout's run): a lock file per id."""
    folder = os.path.join(tempfile.gettempdir(), "hfsmc-ros2-domains")
    os.makedirs(folder, exist_ok=True)
    start = os.getpid() % len(DOMAINS)
    for i in range(len(DOMAINS)):
        dom = DOMAINS[(start + i) % len(DOMAINS)]
        fd = os.open(os.path.join(folder, f"{dom}.lock"), os.O_CREAT | os.O_RDWR, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        try:
            yield dom
        finally:
            os.close(fd)  # releases the lock
        return
    raise RuntimeError("every ROS 2 test domain is taken")
# One .msg with every field kind (tests/test_ros2_cdr.py), nested in a second one.
ALL_KINDS = """\
uint8 MODE_A=1
string NAME="all # kinds"
bool b
byte y
char c
int8 i8
uint8 u8
int16 i16
uint16 u16
int32 i32
uint32 u32
int64 i64
uint64 u64
float32 f32
float64 f64
string s
string<=5 sb
float64 d 1.5
int32[] di [1, -2]
string ds "dflt"
int16[3] ai
float64[2] af
bool[2] ab
byte[2] ay
string[2] astr
string<=3[2] asb
uint32[<=3] bi
float32[<=2] bf
bool[<=2] bb
string[<=2] bs
int64[] ui
float64[] uf
uint8[] uy
bool[] ub
byte[] ubytes
char[] uc
string[] us
Inner n
Inner[2] an
Inner[<=2] bn
Inner[] un
std_msgs/Header h
geometry_msgs/Point[] pts
"""
INNER = "int8 a\nfloat64 v\nstring t\nuint16[] w\n"
TEST_PACKAGE = "hfsmc_test_msgs"


def write_msgs(tmp: Path) -> list[MsgFile]:
    out = []
    for name, text in (("AllKinds", ALL_KINDS), ("Inner", INNER)):
        path = tmp / TEST_PACKAGE / "msg" / f"{name}.msg"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        out.append(MsgFile(path, f"{TEST_PACKAGE}/msg/{name}.msg"))
    return out


def generate(ms: MessageSet, out: Path) -> None:
    for rel, text in python_message_files(ms).items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def load(ms: MessageSet, out: Path) -> dict[str, Any]:
    """Import the generated packages of ``out`` in this process (first forgetting those of
    another folder: both distros make `std_msgs.msg`); the classes by full type name."""
    for mod in list(sys.modules):
        if mod.split(".")[0] in (*ms.packages(), "hfsmc_ros2_cdr"):
            del sys.modules[mod]
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        classes = {}
        for m in ms:
            module = importlib.import_module(f"{m.package}.msg")
            classes[m.name] = getattr(module, m.short)
        classes["_cdr"] = importlib.import_module("hfsmc_ros2_cdr")
    finally:
        sys.path.remove(str(out))
    return classes


def build(distro: str, types: list[str], tmp: Path, msg_files: list[MsgFile] | None = None
          ) -> tuple[MessageSet, dict[str, Any]]:
    ms = message_set(distro, [(t, AT) for t in types], msg_files or [])
    generate(ms, tmp)
    return ms, load(ms, tmp)


_INT = {"byte": (0, 255), "char": (0, 255), "uint8": (0, 255), "int8": (-128, 127),
        "int16": (-(2**15), 2**15 - 1), "uint16": (0, 2**16 - 1), "int32": (-(2**31), 2**31 - 1),
        "uint32": (0, 2**32 - 1), "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1)}
_NP = {"bool": "bool", "byte": "uint8", "char": "uint8", "int8": "int8", "uint8": "uint8",
       "int16": "int16", "uint16": "uint16", "int32": "int32", "uint32": "uint32",
       "int64": "int64", "uint64": "uint64", "float32": "float32", "float64": "float64"}
_CODE = {"char": "B", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H", "int32": "i",
         "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f", "float64": "d"}


def _scalar(t: FieldType) -> st.SearchStrategy[Any]:
    if t.kind == "string":
        text = st.text(st.characters(exclude_categories=["Cs"], exclude_characters="\x00"),
                       max_size=t.string_bound or 12)
        return text
    if t.name == "bool":
        return st.booleans()
    if t.name == "float32":
        return st.floats(width=32, allow_nan=False)
    if t.name == "float64":
        return st.floats(allow_nan=False)
    lo, hi = _INT[t.name]
    return st.integers(lo, hi)


def plain(ms: MessageSet, name: str, depth: int = 0) -> st.SearchStrategy[dict[str, Any]]:
    """A message as plain data: a dict of field values (nested ones dicts, arrays lists)."""
    fields = {}
    for f in ms.get(name).fields:
        t = f.type
        one = plain(ms, t.name, depth + 1) if t.kind == "nested" else _scalar(t)
        if t.array == "none":
            fields[f.name] = one
        elif t.array == "fixed":
            fields[f.name] = st.lists(one, min_size=t.size, max_size=t.size)
        else:
            most = t.size if t.array == "bounded" else (4 if depth < 2 else 1)
            fields[f.name] = st.lists(one, max_size=most)
    return st.fixed_dictionaries(fields)


def ours(ms: MessageSet, classes: dict[str, Any], name: str, data: dict[str, Any]) -> Any:
    """The plain message as an instance of a generated class (rclpy's field types)."""
    kwargs = {}
    for f in ms.get(name).fields:
        t, v = f.type, data[f.name]
        if t.kind == "nested":
            v = [ours(ms, classes, t.name, x) for x in v] if t.array != "none" else \
                ours(ms, classes, t.name, v)
        elif t.name == "byte":
            v = [bytes((x,)) for x in v] if t.array != "none" else bytes((v,))
        elif t.array == "fixed" and t.name in _CODE:
            v = np.array(v, dtype=_NP[t.name])
        elif t.array != "none" and t.name in _CODE:
            v = array(_CODE[t.name], v)
        kwargs[f.name] = v
    return classes[name](**kwargs)


def theirs(ms: MessageSet, store: Any, name: str, data: dict[str, Any]) -> Any:
    """The plain message as a rosbags object (numpy arrays for primitive arrays)."""
    from rosbags.typesys.base import normalize_fieldname

    kwargs = {}
    for f in ms.get(name).fields:
        t, v = f.type, data[f.name]
        if t.kind == "nested":
            v = [theirs(ms, store, t.name, x) for x in v] if t.array != "none" else \
                theirs(ms, store, t.name, v)
        elif t.array != "none" and t.kind == "primitive":
            v = np.array(v, dtype=_NP[t.name])
        elif t.name == "byte":  # rosbags keeps a byte as an int8 (the same bits)
            v = v - 256 if v > 127 else v
        kwargs[normalize_fieldname(f.name)] = v
    return store.types[name](**kwargs)


# -- a built component against the simulated ground robot --------------------------------
def build_component(tmp: Path, model: Path = STOP_AT_WALL) -> Path:
    """`hfsmc build MODEL` (Python) into TMP/component: its executable."""
    out = tmp / "component"
    result = hfsmc("build", str(model), "-o", str(out))
    assert result.returncode == 0, result.stderr
    return out / f"{model.stem}.py"


# A model that resets odometry (a service) and sends a NavigateToPose goal (an action),
# and the room it drives in (tests/test_ros2_actions.py, tests/test_ros2_rpc_replay.py).
NAV = """\
hfsm: 1
name: nav
imports:
  - from nav2_msgs.action import NavigateToPose
  - from std_srvs.srv import Trigger
interfaces:
  robot:
    type: ros2
    actions:
      navigate: {name: navigate_to_pose, type: nav2_msgs/action/NavigateToPose, timeout: 60s}
    services:
      reset: {name: reset_odometry, type: std_srvs/srv/Trigger}
initial: Reset
states:
  Reset:
    entry: robot.call("reset", Trigger.Request())
    transitions:
      - {to: Go, when: robot.call_status("reset") == "done"}
  Go:
    entry: |
      goal = NavigateToPose.Goal()
      goal.pose.header.frame_id = "odom"
      goal.pose.pose.position.x = 2.0
      goal.pose.pose.position.y = 1.0
      robot.send_goal("navigate", goal)
    transitions:
      - {to: Done, when: robot.goal_status("navigate") == "succeeded"}
  Done:
    final: true
"""
ROOM = "name: room\nseed: 1\nwalls:\n  - [[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]]\n"


def run_against_sim(tmp: Path, world: str, domain: int, component: Path, *args: str,
                    env: dict[str, str] | None = None) -> tuple[subprocess.CompletedProcess[str],
                                                                dict[str, object]]:
    """Start the simulator on ``domain``, run the component (a Python script, or a C++
    executable) until it stops by itself (bounded), stop the simulator: the component's run
    and the truth of the robots."""
    (tmp / "world.yaml").write_text(world)
    sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                            "--world", str(tmp / "world.yaml"), "--domain", str(domain),
                            "--truth", str(tmp / "truth.json")],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        command = [sys.executable, str(component)] if component.suffix == ".py" else [str(component)]
        run = subprocess.run([*command, "--until", "40s", *args],
                             capture_output=True, text=True, timeout=90,
                             env={**os.environ, **(env or {})})
    finally:
        status = interrupt(sim, timeout=30)
        assert sim.stderr is not None
        err = sim.stderr.read().decode()
        sim.stderr.close()
    assert status == 0, err
    truth = json.loads((tmp / "truth.json").read_text())["robots"]
    assert isinstance(truth, dict)
    return run, truth


def build_ddsinspect(out: Path) -> Path:
    """tests/ros2/ddsinspect.cpp, what a ROS 2 tool on Cyclone DDS sees of a domain, built
    against Debian's Cyclone DDS 0.10 (ROS 2's DDS) into ``out``: its executable."""
    exe = out / "ddsinspect"
    flags = subprocess.run(["pkg-config", "--cflags", "--libs", "CycloneDDS"], check=True,
                           capture_output=True, text=True).stdout.split()
    cpp = ROOT / "templates" / "cpp"
    made = subprocess.run(["g++", "-std=c++17", "-Wall", "-Wextra", "-Werror", "-O1", "-I", str(cpp),
                           str(ROOT / "tests" / "ros2" / "ddsinspect.cpp"),
                           str(cpp / "hfsmc_ros2_wire.cpp"), "-o", str(exe), *flags],
                          capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stderr
    return exe
