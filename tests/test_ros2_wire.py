"""The Python ROS 2 runtime on the wire (templates/python/hfsmc_ros2*.py): real processes on
loopback exchanging messages; what ROS 2's own DDS (Debian's Cyclone DDS 0.10, in C) sees
of them on the built-in topics; their ros_discovery_info decoded with rosbags; bad settings
and malformed samples. Each test uses a domain id of its own, made from the process id."""

from __future__ import annotations

import importlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hfsmc.emit.python import INTERFACE_FILES
from hfsmc.ros2.definitions import DISTROS, typestore
from tests.ros2_support import build, build_ddsinspect, ros2_domain
from tests.support import ROOT

RUNTIME = ROOT / "templates" / "python"
HERE = Path(__file__).resolve().parent / "ros2"
SECONDS = 4.0  # how long each peer runs
TYPES = ["sensor_msgs/msg/LaserScan", "geometry_msgs/msg/Twist",
         "rmw_dds_common/msg/ParticipantEntitiesInfo"]


@pytest.fixture(scope="module", params=DISTROS)
def folder(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
           ) -> tuple[str, Path]:
    """A component-like folder: the generated messages, the runtime files, tests/ros2/peer.py."""
    distro = str(request.param)
    out = tmp_path_factory.mktemp(f"ros2_{distro}")
    build(distro, TYPES, out)
    for name in INTERFACE_FILES["ros2"]:  # what a component gets beside it
        shutil.copy(RUNTIME / name, out / name)
    shutil.copy(HERE / "peer.py", out / "peer.py")
    return distro, out


@pytest.fixture(scope="module")
def inspector(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/ros2/ddsinspect.cpp built against Debian's Cyclone DDS (ROS 2's DDS)."""
    return build_ddsinspect(tmp_path_factory.mktemp("ddsinspect"))


class Peers:
    """Peer processes (tests/ros2/peer.py), stopped and reaped at the end."""

    def __init__(self, distro: str, where: Path, dom: int) -> None:
        self.distro, self.where, self.dom = distro, where, dom
        self.procs: list[tuple[subprocess.Popen[bytes], Path, Path]] = []

    def start(self, role: str, seconds: float = SECONDS, dom: int | None = None) -> int:
        out = self.where / f"{role}{len(self.procs)}.out"
        err = self.where / f"{role}{len(self.procs)}.err"
        with out.open("wb") as o, err.open("wb") as e:
            proc = subprocess.Popen(
                [sys.executable, "peer.py", role, self.distro, str(self.dom if dom is None
                                                                    else dom), str(seconds)],
                cwd=self.where, stdout=o, stderr=e, stdin=subprocess.DEVNULL)
        self.procs.append((proc, out, err))
        return len(self.procs) - 1

    def finish(self, i: int) -> tuple[int, list[dict[str, Any]], str]:
        proc, out, err = self.procs[i]
        try:
            rc = proc.wait(timeout=SECONDS + 30)
        except subprocess.TimeoutExpired:
            proc.kill()
            rc = proc.wait(timeout=10)
        lines = [json.loads(x) for x in out.read_text().splitlines() if x.startswith("{")]
        return rc, lines, err.read_text()

    def close(self) -> None:
        for proc, _, _ in self.procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)


@pytest.fixture
def peers(folder: tuple[str, Path]) -> Any:
    with ros2_domain() as dom:
        made = Peers(folder[0], folder[1], dom)
        yield made
        made.close()


def test_two_processes_exchange_messages(peers: Peers) -> None:
    robot = peers.start("robot")
    sim = peers.start("sim")
    rc_r, got_r, err_r = peers.finish(robot)
    rc_s, got_s, err_s = peers.finish(sim)
    assert (rc_r, rc_s) == (0, 0), err_r + err_s
    scans = [x for x in got_r if "count" in x]
    assert len(scans) >= 5, got_r
    for x in scans:  # the sim's scans as sent: [i, i, i]
        assert len(x["ranges"]) == 3 and len(set(x["ranges"])) == 1 and x["dropped"] == 0
    assert [x["count"] for x in scans] == sorted({x["count"] for x in scans})
    assert scans[-1]["publishers"] == 1
    cmds = [x for x in got_s if "count" in x]
    assert len(cmds) >= 5, got_s
    xs = [x["x"] for x in cmds]
    assert xs == sorted(xs) and xs[-1] >= 5.0  # linear.x = the scans the robot had seen
    assert cmds[-1]["subscribers"] == 1
    assert err_r == err_s == ""


def test_malformed_samples_dropped_and_counted(peers: Peers) -> None:
    robot = peers.start("robot")
    bad = peers.start("garbage")
    rc, got, err = peers.finish(robot)
    peers.finish(bad)
    assert rc == 0, err
    scans = [x for x in got if "count" in x]
    assert len(scans) >= 3, got  # the good ones still come
    assert scans[-1]["dropped"] >= 3
    said = [x for x in err.splitlines() if "malformed sample on /tb2/scan dropped" in x]
    assert len(said) == 1, err  # said once, then counted
    assert "Traceback" not in err


def test_discovery_as_ros2_sees_it(peers: Peers, inspector: Path) -> None:
    robot = peers.start("robot")
    sim = peers.start("sim")
    found = subprocess.run([str(inspector), str(peers.dom), "20", "rt/tb2/scan",
                            "rt/tb2/cmd_vel", "ros_discovery_info"],
                           capture_output=True, text=True, timeout=60)
    assert found.returncode == 0, found.stdout + found.stderr
    seen = [json.loads(x) for x in found.stdout.splitlines()]
    self = seen[0]["key"]  # the inspector's own participant
    ours = [p for p in seen if p["kind"] == "participant" and p["key"] != self]
    assert len(ours) == 2
    assert {bytes.fromhex(p["user_data"]) for p in ours} == {b"enclave=/;"}
    ends = {(e["kind"], e["topic"], e["participant"]): e for e in seen
            if "topic" in e and e["participant"] != self}
    store = typestore(peers.distro)
    want = {
        "rt/tb2/scan": ("sensor_msgs::msg::dds_::LaserScan_", "sensor_msgs/msg/LaserScan",
                        False, False, 5),
        "rt/tb2/cmd_vel": ("geometry_msgs::msg::dds_::Twist_", "geometry_msgs/msg/Twist",
                           True, False, 10),
        "ros_discovery_info": ("rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_",
                               "rmw_dds_common/msg/ParticipantEntitiesInfo", True, True, 1),
    }
    for (kind, topic, _), e in ends.items():
        if topic not in want:
            continue
        dds_type, ros_type, reliable, transient, depth = want[topic]
        assert (e["type"], e["reliable"], e["transient_local"], e["depth"]) == (
            dds_type, reliable, transient, depth), e
        assert e["representation"] == [0]  # XCDR1
        user = bytes.fromhex(e["user_data"])
        if peers.distro == "jazzy":
            assert user == f"typehash={store.hash_rihs01(ros_type)};".encode(), (kind, topic)
        else:
            assert user == b"", (kind, topic)
    kinds = {(k, t) for k, t, _ in ends}
    assert {("publication", "rt/tb2/scan"), ("subscription", "rt/tb2/scan"),
            ("publication", "rt/tb2/cmd_vel"), ("subscription", "rt/tb2/cmd_vel")} <= kinds
    peers.finish(robot)
    peers.finish(sim)


def test_ros_discovery_info_decoded_with_rosbags(peers: Peers, inspector: Path) -> None:
    robot = peers.start("robot", seconds=8)
    listen = peers.start("discovery", seconds=3)
    found = subprocess.run([str(inspector), str(peers.dom), "20", "rt/tb2/scan"],
                           capture_output=True, text=True, timeout=60)
    rc, got, err = peers.finish(listen)
    peers.finish(robot)
    assert rc == 0, err
    assert got, "no ros_discovery_info sample"
    store = typestore(peers.distro)
    info: Any = store.deserialize_cdr(bytes.fromhex(got[-1]["info"]),
                                      "rmw_dds_common/msg/ParticipantEntitiesInfo")
    size = 24 if peers.distro == "humble" else 16
    assert len(info.gid.data) == size
    [node] = info.node_entities_info_seq
    assert (node.node_namespace, node.node_name) == ("/tb2", "bump_and_go")
    assert len(node.reader_gid_seq) == 1 and len(node.writer_gid_seq) == 1
    seen = [json.loads(x) for x in found.stdout.splitlines()]
    reader = next(e for e in seen if e["kind"] == "subscription" and e["topic"] == "rt/tb2/scan")
    writer = next(e for e in seen if e["kind"] == "publication" and e["topic"] == "rt/tb2/cmd_vel")
    gid = bytes(info.gid.data)
    assert gid[:16].hex() == reader["participant"] and gid[16:] == bytes(size - 16)
    assert bytes(node.reader_gid_seq[0].data)[:16].hex() == reader["key"]
    assert bytes(node.writer_gid_seq[0].data)[:16].hex() == writer["key"]


@pytest.mark.parametrize(("dom", "said"), [(233, "domain 233 is out of range"),
                                           (-1, "domain -1 is out of range")])
def test_domain_out_of_range_exits_2(peers: Peers, dom: int, said: str) -> None:
    i = peers.start("robot", seconds=1, dom=dom)
    rc, _, err = peers.finish(i)
    assert rc == 2
    assert err.splitlines() == [f"robot: ros2: {said} (ROS_DOMAIN_ID: 0..232)"]


def test_names_resolved_as_ros2(folder: tuple[str, Path]) -> None:
    wire: Any = importlib.import_module("hfsmc.templates.python.hfsmc_ros2_wire")
    assert wire.resolve_name("scan", "/tb2", "bump") == "/tb2/scan"
    assert wire.resolve_name("/scan", "/tb2", "bump") == "/scan"
    assert wire.resolve_name("~/status", "/tb2", "bump") == "/tb2/bump/status"
    assert wire.resolve_name("scan", "/", "bump") == "/scan"
    assert wire.resolve_name("a/b", "tb2", "n") == "/tb2/a/b"
    for bad, why in [("9scan", "not letters"), ("sc an", "not letters"), ("a//b", "empty part"),
                     ("scan/", "ends with"), ("a__b", "has `__`"), ("~x", "followed by `/`"),
                     ("", "empty")]:
        with pytest.raises(wire.Ros2Error, match=why):
            wire.resolve_name(bad, "/tb2", "bump")
    with pytest.raises(wire.Ros2Error, match="namespace"):
        wire.resolve_name("scan", "/tb 2", "bump")
    assert wire.qos_of("latched") == ("reliable", "transient_local", 1)
    assert wire.qos_of({"reliability": "best_effort", "depth": 3}) == ("best_effort",
                                                                       "volatile", 3)
    for bad_qos in ("fast", {"depth": 0}, {"durability": "persistent"}):
        with pytest.raises(wire.Ros2Error):
            wire.qos_of(bad_qos)
    os.environ["ROS_DOMAIN_ID"] = "42"
    try:
        assert wire.domain_id(None) == 42 and wire.domain_id(7) == 7
        os.environ["ROS_DOMAIN_ID"] = "x"
        with pytest.raises(wire.Ros2Error, match="not a number"):
            wire.domain_id(None)
    finally:
        del os.environ["ROS_DOMAIN_ID"]
    assert wire.domain_id(None) == 0
