"""The C++ ``ros2`` runtime on a real DDS network (loopback only, a test domain id):
a component-side program (tests/ros2_cpp/component.cpp over templates/cpp/hfsmc_ros2*.cpp,
built with CMake against Debian's Cyclone DDS 0.10) exchanges ROS 2 messages with a program
on eProsima Fast DDS 2.9, is seen from the DDS built-in topics as a ROS 2 node would be
(topic and type names, QoS, enclave, type hashes), and announces its node on
``ros_discovery_info`` in the distro's layout, decoded here by rosbags."""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rosbags.typesys import Stores, get_typestore

from hfsmc.ros2.cpp_messages import RUNTIME_TYPES, cpp_message_files
from hfsmc.ros2.definitions import message_set
from tests.ros2_support import AT, LOOPBACK, build_ddsinspect
from tests.support import ROOT

HERE = Path(__file__).resolve().parent / "ros2_cpp"
STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY}
TYPES = ["sensor_msgs/msg/LaserScan", "geometry_msgs/msg/Twist"]


def _build(out: Path, distro: str, fastdds: bool) -> Path:
    ms = message_set(distro, [(t, AT) for t in [*TYPES, *RUNTIME_TYPES]])
    for rel, text in cpp_message_files(ms, model="test").items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for name in ("component.cpp", "fastdds_peer.cpp", "CMakeLists.txt"):
        shutil.copy(HERE / name, out / name)
    build = out / "build"
    subprocess.run(["cmake", "-S", str(out), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                    f"-DHFSMC={ROOT / 'templates' / 'cpp'}",
                    f"-DWITH_FASTDDS={'ON' if fastdds else 'OFF'}"],
                   check=True, capture_output=True, timeout=300)
    subprocess.run(["cmake", "--build", str(build), "-j2"], check=True, capture_output=True,
                   timeout=900)
    return build


@pytest.fixture(scope="module")
def builds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("ros2cpp")
    return {d: _build(root / d, d, fastdds=d == "jazzy") for d in STORES}


@pytest.fixture(scope="module")
def inspector(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/ros2/ddsinspect.cpp: what a ROS 2 tool on Cyclone DDS sees of the domain."""
    return build_ddsinspect(tmp_path_factory.mktemp("ddsinspect"))


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A domain id of this test alone, on loopback (for this process's DDS and its children)."""
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    return random.Random(os.getpid() ^ time.monotonic_ns()).randint(100, 200)


@pytest.fixture
def started() -> Iterator[list[subprocess.Popen[str]]]:
    procs: list[subprocess.Popen[str]] = []
    yield procs
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.communicate(timeout=10)


def _start(procs: list[subprocess.Popen[str]], *args: object) -> subprocess.Popen[str]:
    p = subprocess.Popen([str(a) for a in args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    procs.append(p)
    return p


def test_fast_dds_scan_in_twist_out(builds: dict[str, Path], domain: int,
                                    started: list[subprocess.Popen[str]]) -> None:
    """Fast DDS publishes LaserScans (one malformed first): the component reads each in its
    snapshot, drops and counts the malformed one, and answers with Twists Fast DDS reads."""
    build = builds["jazzy"]
    # Each ends after three: the component after three scans (each answered), the peer after
    # three twists (without, the component waited its whole 60 s for scans nobody sent).
    comp = _start(started, build / "component", "bump", "/", "jazzy", domain, 60, 3)
    peer = _start(started, build / "fastdds_peer", domain, 60, 3)
    # The peer sends once both sides have matched: the component's reader its writer (else
    # a scan is lost to the volatile reader), and the component's writer its reader (else
    # the component's twists go to nobody, and the peer waits its whole 60 s for them).
    seen = []
    for line in comp.stdout or ():  # the component ends itself after 60 s at most
        seen.append(line)
        if {"publishers 1\n", "subscribers 1\n"} <= set(seen):
            break
    assert {"publishers 1\n", "subscribers 1\n"} <= set(seen), seen
    peer_out, peer_err = peer.communicate("go\n", timeout=90)
    comp_out, comp_err = comp.communicate(timeout=90)
    comp_out = "".join(seen) + comp_out
    assert peer.returncode == 0, (peer_out, peer_err, comp_out, comp_err)
    assert comp.returncode == 0, comp_err
    assert "started /scan /cmd_vel" in comp_out
    scans = re.findall(r"scan count=(\d+) malformed=(\d+) publishers=(\d+) frame=(\S+) "
                       r"sec=(\d+) n=(\d+) r0=(\S+) age_ok=1 bytes=(\d+)", comp_out)
    assert scans, comp_out
    for _, malformed, publishers, frame, sec, n, r0, _ in scans:
        assert (frame, n, float(r0), publishers) == ("fastdds", "3", 0.5 + int(sec), "1")
        assert malformed == "1"  # the first sample Fast DDS sent, dropped and counted
    assert "dropped a malformed sensor_msgs/msg/LaserScan on /scan" in comp_err
    secs = {int(s[4]) for s in scans}
    twists = re.findall(r"twist x=(\S+) z=(\S+)", peer_out)
    assert len(twists) >= 3
    for x, z in twists:  # each answers a scan the component read
        assert int(float(z)) in secs and float(x) == 0.5 + float(z)


def test_start_errors_are_one_line(builds: dict[str, Path], domain: int) -> None:
    """A domain id out of range or a topic name ROS 2 forbids: one line, exit 2."""
    exe = builds["jazzy"] / "component"
    bad = subprocess.run([str(exe), "bump", "/", "jazzy", "233", "1", "1"],
                         capture_output=True, text=True, timeout=30)
    assert (bad.returncode, bad.stderr) == (2, "error: domain id 233 out of range (0 to 232)\n")
    bad = subprocess.run([str(exe), "bump", "/tb2//x", "jazzy", str(domain), "1", "1"],
                         capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1
    assert "namespace '/tb2//x'" in bad.stderr
    bad = subprocess.run([str(exe), "2bump", "/", "jazzy", str(domain), "1", "1"],
                         capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and "node name '2bump'" in bad.stderr


@pytest.mark.parametrize("distro", sorted(STORES))
def test_discovery_as_a_ros2_node(builds: dict[str, Path], inspector: Path, domain: int,
                                  distro: str, started: list[subprocess.Popen[str]]) -> None:
    """From the built-in topics (a plain Cyclone participant, tests/ros2/ddsinspect.cpp): the
    participant's `enclave=/;`, `rt/` topics with ROS 2 type names and QoS, jazzy's type
    hashes (rosbags' RIHS01) and none on humble; from ros_discovery_info, decoded by rosbags:
    the node /tb2/bump with its reader and writer, its Gid 24 bytes on humble, 16 on jazzy."""
    store = get_typestore(STORES[distro])
    _start(started, builds[distro] / "component", "bump", "/tb2", distro, domain, 30, 1000)
    probe = _start(started, inspector, domain, 20, "rt/tb2/scan", "rt/tb2/cmd_vel")
    out, err = probe.communicate(timeout=60)
    assert probe.returncode == 0, out + err
    seen = [json.loads(line) for line in out.splitlines()]
    self = seen[0]["key"]  # the inspector's own participant
    ours = [p["key"] for p in seen if p["kind"] == "participant" and p["key"] != self]
    assert len(ours) == 1, out
    assert [bytes.fromhex(p["user_data"]) for p in seen if p.get("key") == ours[0]] == [b"enclave=/;"]
    endpoints = {e["topic"]: e for e in seen if e.get("participant") == ours[0]}
    cmd, scan = endpoints["rt/tb2/cmd_vel"], endpoints["rt/tb2/scan"]
    info = endpoints["ros_discovery_info"]
    def kind(e: dict[str, Any]) -> tuple[str, str, bool, bool, int, list[int]]:
        return (e["kind"], e["type"], e["reliable"], e["transient_local"], e["depth"],
                e["representation"])
    assert kind(cmd) == ("publication", "geometry_msgs::msg::dds_::Twist_", True, False, 10, [0])
    assert kind(scan) == ("subscription", "sensor_msgs::msg::dds_::LaserScan_", False, False, 5, [0])
    assert kind(info) == ("publication", "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_",
                          True, True, 1, [0])
    for endpoint, ros_type in ((cmd, TYPES[1]), (scan, TYPES[0]),
                               (info, "rmw_dds_common/msg/ParticipantEntitiesInfo")):
        hashed = f"typehash={store.hash_rihs01(ros_type)};".encode()
        assert bytes.fromhex(endpoint["user_data"]) == (hashed if distro == "jazzy" else b"")

    announced: list[Any] = [store.deserialize_cdr(bytes.fromhex(d["cdr"]),
                                                  "rmw_dds_common/msg/ParticipantEntitiesInfo")
                            for d in seen if d["kind"] == "discovery"]
    msg = next(m for m in announced if bytes(m.gid.data[:16]).hex() == ours[0])
    assert len(msg.gid.data) == (24 if distro == "humble" else 16)
    node = msg.node_entities_info_seq[0]
    assert (node.node_namespace, node.node_name) == ("/tb2", "bump")
    assert [bytes(g.data[:16]).hex() for g in node.writer_gid_seq] == [cmd["key"]]
    assert [bytes(g.data[:16]).hex() for g in node.reader_gid_seq] == [scan["key"]]
    if distro == "humble":
        assert all(bytes(g.data[16:]) == bytes(8) for g in [msg.gid, *node.writer_gid_seq])
