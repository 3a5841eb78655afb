"""ROS 2 message definitions (hfsmc/ros2/definitions.py): a distro's messages from rosbags'
stores, a model's own .msg files, the closure of the types used, type hashes, name checks."""

from __future__ import annotations

from pathlib import Path

import pytest

from hfsmc.errors import CheckError, Span
from hfsmc.ros2.definitions import (
    DISTROS,
    FieldType,
    MsgFile,
    message_set,
    ros2_type_name,
    standard_types,
    typestore,
)

AT = Span("robot.yaml", 7, 13)


def _msg(tmp_path: Path, text: str, package: str = "my_msgs", name: str = "Detection") -> MsgFile:
    path = tmp_path / package / "msg" / f"{name}.msg"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return MsgFile(path, f"{package}/msg/{name}.msg")


@pytest.mark.parametrize("distro", DISTROS)
def test_closure_dependencies_first(distro: str) -> None:
    ms = message_set(distro, [("nav_msgs/msg/Odometry", AT)])
    names = [m.name for m in ms]
    assert names[-1] == "nav_msgs/msg/Odometry"
    assert set(names) == {
        "nav_msgs/msg/Odometry", "std_msgs/msg/Header", "builtin_interfaces/msg/Time",
        "geometry_msgs/msg/PoseWithCovariance", "geometry_msgs/msg/Pose",
        "geometry_msgs/msg/Point", "geometry_msgs/msg/Quaternion",
        "geometry_msgs/msg/TwistWithCovariance", "geometry_msgs/msg/Twist",
        "geometry_msgs/msg/Vector3"}
    for i, m in enumerate(ms.messages):  # every nested type comes before its user
        for f in m.fields:
            if f.type.kind == "nested":
                assert names.index(f.type.name) < i
    assert ms.packages() == ("builtin_interfaces", "geometry_msgs", "nav_msgs", "std_msgs")


@pytest.mark.parametrize("distro", DISTROS)
def test_fields_kinds_and_hash(distro: str) -> None:
    ms = message_set(distro, [("sensor_msgs/msg/LaserScan", AT), ("nav_msgs/Odometry", AT)])
    scan = ms.get("sensor_msgs/msg/LaserScan")
    assert scan.dds_type_name == "sensor_msgs::msg::dds_::LaserScan_"
    by = {f.name: f.type for f in scan.fields}
    assert by["header"] == FieldType("nested", "std_msgs/msg/Header")
    assert by["ranges"] == FieldType("primitive", "float32", 0, "unbounded", 0)
    cov = {f.name: f.type for f in ms.get("geometry_msgs/msg/PoseWithCovariance").fields}
    assert cov["covariance"] == FieldType("primitive", "float64", 0, "fixed", 36)
    assert scan.type_hash == typestore(distro).hash_rihs01("sensor_msgs/msg/LaserScan")
    assert scan.type_hash.startswith("RIHS01_") and len(scan.type_hash) == 7 + 64
    assert "MSG: std_msgs/Header" in scan.ros2msg
    quat = ms.get("geometry_msgs/msg/Quaternion")
    assert [(f.name, f.default) for f in quat.fields] == [
        ("x", None), ("y", None), ("z", None), ("w", 1.0)]


def test_known_twist_hash_and_distro_differences() -> None:
    # the hash ROS 2 Jazzy announces for geometry_msgs/msg/Twist (`ros2 topic info -v`)
    twist = message_set("jazzy", [("geometry_msgs/msg/Twist", AT)]).get("geometry_msgs/msg/Twist")
    assert twist.type_hash == (
        "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a")
    gid = {d: {f.name: f.type for f in message_set(d, [("rmw_dds_common/msg/Gid", AT)])
               .get("rmw_dds_common/msg/Gid").fields}["data"] for d in DISTROS}
    assert gid["humble"].size == 24 and gid["jazzy"].size == 16
    nav = {d: message_set(d, [("sensor_msgs/msg/NavSatStatus", AT)])
           .get("sensor_msgs/msg/NavSatStatus") for d in DISTROS}
    assert [f.default for f in nav["jazzy"].fields] == [-2, None]
    assert [f.default for f in nav["humble"].fields] == [None, None]
    assert ("STATUS_UNKNOWN", -2) in [(c.name, c.value) for c in nav["jazzy"].constants]


def test_ros1_names_map_to_ros2() -> None:
    assert ros2_type_name("geometry_msgs/Twist") == "geometry_msgs/msg/Twist"
    assert ros2_type_name("geometry_msgs/msg/Twist") == "geometry_msgs/msg/Twist"
    ms = message_set("humble", [("geometry_msgs/Twist", AT)])
    assert ms.messages[-1].name == "geometry_msgs/msg/Twist"
    assert "sensor_msgs/msg/LaserScan" in standard_types("jazzy")


def test_unknown_type_did_you_mean() -> None:
    with pytest.raises(CheckError) as err:
        message_set("jazzy", [("sensor_msgs/msg/LaserScn", AT), ("kobuki_msgs/BumperEvent", AT)])
    d = err.value.diagnostics
    assert [x.code for x in d] == ["E310", "E310"]
    assert d[0].span == AT
    assert "unknown ROS 2 message type `sensor_msgs/msg/LaserScn`" in d[0].message
    assert "did you mean `sensor_msgs/msg/LaserScan`?" in d[0].notes
    assert "kobuki_msgs/BumperEvent" in d[1].message


@pytest.mark.parametrize("distro", DISTROS)
def test_own_msg_files(tmp_path: Path, distro: str) -> None:
    det = _msg(tmp_path, "# a detection\nuint8 KIND_PERSON=1\nstring LABEL=\"a # b\"\n"
               "std_msgs/Header header\nuint8 kind 1\nfloat32[4] box [0.0, 0.0, 1.0, 1.0]\n"
               "string<=16 label \"none\"\nBox[<=3] parts\nbyte b\nchar c\nbool ok true\n")
    box = _msg(tmp_path, "int32 x -3\nint32[] ys\n", name="Box")
    ms = message_set(distro, [("my_msgs/msg/Detection", AT)], [det, box])
    d = ms.get("my_msgs/msg/Detection")
    assert d.origin == "my_msgs/msg/Detection.msg"
    assert [(c.name, c.value) for c in d.constants] == [("KIND_PERSON", 1), ("LABEL", "a # b")]
    f = {x.name: x for x in d.fields}
    assert f["kind"].default == 1 and f["box"].default == (0.0, 0.0, 1.0, 1.0)
    assert f["label"].type == FieldType("string", "string", 16) and f["label"].default == "none"
    assert f["parts"].type == FieldType("nested", "my_msgs/msg/Box", 0, "bounded", 3)
    assert f["b"].type.name == "byte" and f["c"].type.name == "char" and f["ok"].default is True
    assert [m.name for m in ms][:3] == ["builtin_interfaces/msg/Time", "std_msgs/msg/Header",
                                        "my_msgs/msg/Box"]
    assert ms.get("my_msgs/msg/Box").fields[0].default == -3
    assert d.type_hash.startswith("RIHS01_")


@pytest.mark.parametrize(("text", "line", "what"), [
    ("int32 a\n  %%\n", 2, "not a ROS 2 .msg line"),
    ("int32 a\nint32 b c d\n", 2, "`c d` is not a value of type int32"),
    ("float64 x\n\n  Strng name\n", 3, "unknown message type `my_msgs/msg/Strng`"),
    ("uint8 v 300\n", 1, "`300` is not a value of type uint8"),
    ("int32 Bad\n", 1, "field `Bad` is not lower_case"),
    ("int32 a\nint32 a\n", 2, "`a` is defined twice"),
    ("float64[2] a [1.0]\n", 1, "the default has 1 values for an array of 2"),
    ("wstring w\n", 1, "`wstring` is not supported yet"),
    ("uint8 one_=1\n", 1, "not a ROS 2 .msg line"),
    ("int32 ok\nint32 from\n", 2, "field `from` is a keyword of Python or C++"),
    ("int32 ok\nfloat64 delete\n", 2, "field `delete` is a keyword of Python or C++"),
])
def test_bad_msg_file_at_its_line(tmp_path: Path, text: str, line: int, what: str) -> None:
    f = _msg(tmp_path, text)
    with pytest.raises(CheckError) as err:
        message_set("jazzy", [("my_msgs/msg/Detection", AT)], [f])
    d = err.value.diagnostics[0]
    assert d.code == "E311" and what in d.message
    assert (d.span.file, d.span.line) == ("my_msgs/msg/Detection.msg", line)


def test_bad_msg_file_names(tmp_path: Path) -> None:
    std = _msg(tmp_path, "int32 a\n", package="std_msgs", name="Header")
    lower = _msg(tmp_path, "int32 a\n", name="detection")
    with pytest.raises(CheckError) as err:
        message_set("jazzy", [], [std, lower])
    text = [x.message for x in err.value.diagnostics]
    assert any("is a standard message of jazzy" in t for t in text)
    assert any("`detection` is not CamelCase" in t for t in text)


def test_recursive_messages_refused(tmp_path: Path) -> None:
    a = _msg(tmp_path, "B b\n", name="A")
    b = _msg(tmp_path, "int32 x\nA[] back\n", name="B")
    with pytest.raises(CheckError, match="message types contain each other: "
                       "my_msgs/msg/A -> my_msgs/msg/B -> my_msgs/msg/A"):
        message_set("jazzy", [("my_msgs/msg/A", AT)], [a, b])
    self_ref = _msg(tmp_path, "Node[] children\n", name="Node")
    with pytest.raises(CheckError, match="contain each other"):
        message_set("jazzy", [("my_msgs/msg/Node", AT)], [self_ref])
