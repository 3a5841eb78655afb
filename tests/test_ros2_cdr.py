"""The generated Python message classes (hfsmc/ros2/python_messages.py) against rosbags:
byte for byte the same CDR for every field kind and every standard message of both
distros, the same messages back, rclpy's defaults, and clear errors on bad input."""

from __future__ import annotations

import contextlib
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hfsmc.ros2.definitions import DISTROS, rosbags_store, standard_types
from tests.ros2_support import TEST_PACKAGE, build, ours, plain, theirs, write_msgs

ALL = f"{TEST_PACKAGE}/msg/AllKinds"
ROBOT = ["sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist",
         "sensor_msgs/msg/Image", "sensor_msgs/msg/Imu", "sensor_msgs/msg/PointCloud2",
         "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/NavSatFix",
         "visualization_msgs/msg/MarkerArray", "std_msgs/msg/Empty",
         "rmw_dds_common/msg/ParticipantEntitiesInfo", "rcl_interfaces/msg/ParameterDescriptor"]
SETTINGS = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@pytest.fixture(scope="module", params=DISTROS)
def gen(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
        ) -> tuple[str, Any, Any, dict[str, Any]]:
    distro = str(request.param)
    tmp = tmp_path_factory.mktemp(f"msgs_{distro}")
    files = write_msgs(tmp / "model")
    ms, classes = build(distro, [ALL, *standard_types(distro)], tmp / "out", files)
    return distro, ms, rosbags_store(distro, files), classes


def _same_as_rosbags(gen: tuple[str, Any, Any, dict[str, Any]], name: str, data: Any) -> None:
    _, ms, store, classes = gen
    cdr = classes["_cdr"]
    mine = ours(ms, classes, name, data)
    wire = cdr.serialize(mine)
    assert wire == bytes(store.serialize_cdr(theirs(ms, store, name, data), name))
    back = cdr.deserialize(classes[name], wire)
    assert back == mine
    assert cdr.serialize(back) == wire
    # what rosbags reads from our bytes, written again by rosbags, is our bytes
    assert bytes(store.serialize_cdr(store.deserialize_cdr(wire, name), name)) == wire


@SETTINGS
@given(data=st.data())
def test_every_field_kind_as_rosbags(gen: tuple[str, Any, Any, dict[str, Any]],
                                     data: st.DataObject) -> None:
    ms = gen[1]
    _same_as_rosbags(gen, ALL, data.draw(plain(ms, ALL)))


@pytest.mark.parametrize("name", ROBOT)
def test_robot_messages_as_rosbags(gen: tuple[str, Any, Any, dict[str, Any]], name: str) -> None:
    @settings(max_examples=25, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(data=st.data())
    def check(data: st.DataObject) -> None:
        _same_as_rosbags(gen, name, data.draw(plain(gen[1], name)))

    check()


def test_every_standard_message_as_rosbags(gen: tuple[str, Any, Any, dict[str, Any]]) -> None:
    """Each standard message of the distro, three drawn messages each (the robot's ones
    and every field kind are drawn more above)."""
    distro, ms, _, _ = gen
    names = standard_types(distro)
    assert len(names) > 140

    @settings(max_examples=3 * len(names), deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(data=st.data())
    def check(data: st.DataObject) -> None:
        name = data.draw(st.sampled_from(names))
        _same_as_rosbags(gen, name, data.draw(plain(ms, name)))

    check()


def test_defaults_and_names_as_rclpy(gen: tuple[str, Any, Any, dict[str, Any]]) -> None:
    distro, ms, _store, classes = gen
    odom = classes["nav_msgs/msg/Odometry"]()
    assert odom.pose.pose.orientation.w == 1.0 and odom.child_frame_id == ""
    assert odom.pose.covariance.shape == (36,) and odom.pose.covariance.dtype.name == "float64"
    scan = classes["sensor_msgs/msg/LaserScan"](range_max=8.0)
    assert scan.ranges.typecode == "f" and len(scan.ranges) == 0 and scan.range_max == 8.0
    twist_cls = classes["geometry_msgs/msg/Twist"]
    vec = classes["geometry_msgs/msg/Vector3"]
    twist = twist_cls(linear=vec(x=0.5))
    assert (twist.linear.x, twist.angular.z) == (0.5, 0.0)
    assert twist_cls.get_fields_and_field_types() == {
        "linear": "geometry_msgs/Vector3", "angular": "geometry_msgs/Vector3"}
    assert repr(vec(x=1.0)) == "geometry_msgs.msg.Vector3(x=1.0, y=0.0, z=0.0)"
    assert classes["sensor_msgs/msg/NavSatStatus"].STATUS_FIX == 0
    assert classes["sensor_msgs/msg/NavSatStatus"]().status == (-2 if distro == "jazzy" else 0)
    allk = classes[ALL]()
    assert (allk.d, list(allk.di), allk.ds, allk.y, allk.ay) == (1.5, [1, -2], "dflt", b"\x00",
                                                                 [b"\x00", b"\x00"])
    assert classes[ALL].MODE_A == 1 and classes[ALL].NAME == "all # kinds"
    assert classes[ALL]._TYPE == ALL and ms.get(ALL).type_hash == classes[ALL]._HASH
    assert classes[ALL]._DDS == "hfsmc_test_msgs::msg::dds_::AllKinds_"
    with pytest.raises(TypeError, match="unexpected keyword argument 'lineer'"):
        twist_cls(lineer=vec())
    with pytest.raises(AttributeError):
        twist.linear.w = 1.0  # a field Vector3 does not have


@pytest.mark.parametrize(("change", "error"), [
    (lambda m: setattr(m, "angle_min", "x"), r"sensor_msgs/msg/LaserScan: field `angle_min`"),
    (lambda m: setattr(m.header, "frame_id", b"x"), r"field `header.frame_id`: must be a str"),
    (lambda m: setattr(m, "ranges", [1.0, "a"]), r"field `ranges`: an item does not fit"),
    (lambda m: setattr(m, "header", 3), r"field `header`: must be a std_msgs/msg/Header"),
    (lambda m: setattr(m.header.stamp, "sec", 2**40), r"field `header.stamp.sec`: does not fit"),
    (lambda m: setattr(m, "range_min", 1e39), r"field `range_min`: does not fit"),
])
def test_bad_fields_are_named(gen: tuple[str, Any, Any, dict[str, Any]], change: Any,
                              error: str) -> None:
    classes = gen[3]
    scan = classes["sensor_msgs/msg/LaserScan"]()
    change(scan)
    with pytest.raises(TypeError, match=error):
        classes["_cdr"].serialize(scan)


def test_bounds_and_arrays_checked(gen: tuple[str, Any, Any, dict[str, Any]]) -> None:
    classes = gen[3]
    cdr = classes["_cdr"]
    for field, value, error in [("sb", "toolong", "more than its bound 5"),
                                ("bi", [1, 2, 3, 4], "4 items, more than its bound 3"),
                                ("ai", [1, 2], "2 items for an array of exactly 3"),
                                ("b", 1, "must be a bool"), ("y", 300, "must be a byte"),
                                ("an", [classes[ALL]()] * 2, r"an\[0\]`: must be a")]:
        msg = classes[ALL]()
        setattr(msg, field, value)
        with pytest.raises(TypeError, match=error):
            cdr.serialize(msg)


def test_malformed_buffers_raise_cdr_error(gen: tuple[str, Any, Any, dict[str, Any]]) -> None:
    classes = gen[3]
    cdr = classes["_cdr"]
    scan_cls = classes["sensor_msgs/msg/LaserScan"]
    good = cdr.serialize(scan_cls(ranges=[1.0] * 10))
    for cut in range(len(good)):  # every truncation
        with pytest.raises(cdr.CdrError):
            cdr.deserialize(scan_cls, good[:cut])
    huge = bytearray(good)
    count_at = 4 + 4 + 4 + 4 + 4 + 7 * 4  # the ranges' count, after an empty frame_id
    assert huge[count_at:count_at + 4] == (10).to_bytes(4, "little")
    huge[count_at:count_at + 4] = (2**32 - 1).to_bytes(4, "little")
    with pytest.raises(cdr.CdrError, match="past the end"):
        cdr.deserialize(scan_cls, bytes(huge))
    with pytest.raises(cdr.CdrError, match="big-endian"):
        cdr.deserialize(scan_cls, b"\x00\x00\x00\x00" + good[4:])
    bad_utf8 = cdr.serialize(scan_cls())[:12] + b"\x02\x00\x00\x00\xff\x00" + good[18:]
    with pytest.raises(cdr.CdrError):
        cdr.deserialize(scan_cls, bad_utf8)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(noise=st.binary(max_size=200))
def test_random_bytes_never_crash(gen: tuple[str, Any, Any, dict[str, Any]], noise: bytes) -> None:
    classes = gen[3]
    cdr = classes["_cdr"]
    for name in ("sensor_msgs/msg/LaserScan", ALL, "nav_msgs/msg/Odometry"):
        with contextlib.suppress(cdr.CdrError):
            cdr.deserialize(classes[name], b"\x00\x01\x00\x00" + noise)
