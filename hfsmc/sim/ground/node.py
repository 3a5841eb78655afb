"""The ground robots on ROS 2: each robot a node in its namespace, and ``/clock``.

Each robot subscribes ``cmd_vel`` (geometry_msgs/Twist) and publishes ``odom``
(nav_msgs/Odometry, frames ``odom`` -> ``base_footprint``), ``scan`` (sensor_msgs/LaserScan,
sensor-data QoS, frame ``base_scan``) and ``events/bumper``
(kobuki_ros_interfaces/BumperEvent), as a TurtleBot 2 on ROS 2 does; several robots'
frames carry their namespace (``tb2/odom``). A node ``hfsmc_sim`` publishes the simulated
time on ``/clock`` (rosgraph_msgs/Clock) at every step, as Gazebo does for nodes that use
``use_sim_time``.

The nodes are the components' own runtime (``hfsmc_ros2``), copied with message classes
generated for this run into a temporary folder as into a component's, so that the
simulator speaks exactly what components speak.
"""

from __future__ import annotations

import importlib
import math
import shutil
import sys
import tempfile
from importlib.resources import files
from pathlib import Path
from typing import Any

from hfsmc.errors import Span
from hfsmc.ros2.definitions import MsgFile, message_set
from hfsmc.ros2.python_messages import python_message_files
from hfsmc.sim.ground.base import DiffDrive
from hfsmc.sim.ground.navigate import Navigator, reset_odometry
from hfsmc.sim.ground.sim import Bumper, GroundSim, Odometry, Reading, Scan

SHIPPED = Path(__file__).resolve().parent.parent.parent / "ros2" / "msg"
BUMPER_MSG = SHIPPED / "kobuki_ros_interfaces" / "msg" / "BumperEvent.msg"
# A component's runtime files, written beside the messages as in a component folder.
RUNTIME = ("hfsmc_ros2.py", "hfsmc_ros2_wire.py", "hfsmc_ros2_names.py",
           "hfsmc_ros2_lockstep.py", "hfsmc_ros2_rpc.py")
DISCOVERY = "rmw_dds_common/msg/ParticipantEntitiesInfo"  # every node announces itself
TYPES = {
    "cmd_vel": "geometry_msgs/msg/Twist",
    "odom": "nav_msgs/msg/Odometry",
    "scan": "sensor_msgs/msg/LaserScan",
    "bumper": "kobuki_ros_interfaces/msg/BumperEvent",
    "clock": "rosgraph_msgs/msg/Clock",
}
NAVIGATE = ("navigate_to_pose", "nav2_msgs/action/NavigateToPose")  # each robot serves
RESET = ("reset_odometry", "std_srvs/srv/Trigger")


class NodeError(Exception):
    """The robots cannot join ROS 2 (a bad domain id, no usable network): one line."""


class Messages:
    """The message classes of this run, generated into a folder removed at close()."""

    def __init__(self, distro: str) -> None:
        uses = [*TYPES.values(), DISCOVERY]
        ms = message_set(distro, [(t, Span("<sim>", 1, 1)) for t in uses],
                         [MsgFile(BUMPER_MSG, str(BUMPER_MSG.name))],
                         [(t, Span("<sim>", 1, 1)) for _, t in (NAVIGATE, RESET)])
        self.folder = Path(tempfile.mkdtemp(prefix="hfsmc-sim-msgs-"))
        runtime = files("hfsmc.templates").joinpath("python")
        made = {**python_message_files(ms),
                **{f: runtime.joinpath(f).read_text("utf-8") for f in RUNTIME}}
        for rel, text in made.items():
            path = self.folder / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        sys.path.insert(0, str(self.folder))
        importlib.invalidate_caches()
        self.ros2 = importlib.import_module("hfsmc_ros2")
        wire = importlib.import_module("hfsmc_ros2_wire")
        self.cls = {k: wire.message_class(t) for k, t in TYPES.items()}
        self.rpc = importlib.import_module("hfsmc_ros2_rpc")
        self.navigate, self.trigger = (wire.message_class(t) for _, t in (NAVIGATE, RESET))

    def close(self) -> None:
        if str(self.folder) in sys.path:
            sys.path.remove(str(self.folder))
        shutil.rmtree(self.folder, ignore_errors=True)


class GroundNodes:
    """One node per robot and the clock's node, publishing what the simulation reads."""

    def __init__(self, sim: GroundSim, domain: str | int | None, distro: str) -> None:
        self.sim = sim
        self.msgs = Messages(distro)
        wire = importlib.import_module("hfsmc_ros2_wire")
        try:
            self.domain = wire.domain_id(domain)
        except wire.Ros2Error as e:
            self.msgs.close()
            raise NodeError(f"--domain: {e}") from None
        self.nodes: dict[str, Any] = {}
        self.servers: dict[str, tuple[Navigator, Any]] = {}
        self._seen: dict[str, int] = {}
        self._published: dict[str, int] = {}  # resolved topic -> samples written
        self._base_in: dict[str, int] = {}  # lockstep counts from the component's hello
        self._base_out: dict[str, int] = {}
        try:
            for r in sim.robots:
                self.nodes[r.name] = self.msgs.ros2.Ros2Node(f"sim {r.name}", {
                    "node": "diffdrive", "namespace": r.namespace, "domain": self.domain,
                    "distro": distro,
                    "subscribe": {"cmd_vel": {"topic": "cmd_vel", "type": TYPES["cmd_vel"]}},
                    "publish": {
                        "odom": {"topic": "odom", "type": TYPES["odom"]},
                        "scan": {"topic": "scan", "type": TYPES["scan"], "qos": "sensor_data"},
                        "bumper": {"topic": "events/bumper", "type": TYPES["bumper"]},
                    }})
                self._seen[r.name] = 0
                self._serve(r)
            self.clock = self.msgs.ros2.Ros2Node("sim clock", {
                "node": "hfsmc_sim", "namespace": "/", "domain": self.domain, "distro": distro,
                "publish": {"clock": {"topic": "/clock", "type": TYPES["clock"]}}})
        except BaseException:
            self.close()
            raise

    def _serve(self, r: DiffDrive) -> None:
        """The robot's navigate_to_pose and reset_odometry, on its node's participant."""
        node, wire = self.nodes[r.name], importlib.import_module("hfsmc_ros2_wire")
        nav = Navigator(r, None, self.msgs.navigate)
        name = wire.resolve_name(NAVIGATE[0], r.namespace, "diffdrive")
        nav.server = self.msgs.rpc.ActionServer(node._dp, name, self.msgs.navigate,
                                                nav.on_goal, nav.on_cancel)
        reset = self.msgs.rpc.ServiceServer(
            node._dp, wire.resolve_name(RESET[0], r.namespace, "diffdrive"), self.msgs.trigger,
            reset_odometry(r, self.msgs.trigger))
        self.servers[r.name] = (nav, reset)

    def topics(self) -> dict[str, str]:
        """Resolved topic name -> type, of every robot (for the start line and the docs)."""
        out = {}
        for node in self.nodes.values():
            for table in (node._subs, node._pubs):
                for s in table.values():
                    out[s["topic"]] = s["class"]._TYPE
        return out

    def commands(self) -> None:
        """Apply every robot's latest cmd_vel, if one came since the last call."""
        for r in self.sim.robots:
            node = self.nodes[r.name]
            nav, reset = self.servers[r.name]
            nav.server.poll()
            reset.poll()
            nav.step(self.sim.t)
            node.snapshot()
            n = node.count("cmd_vel")
            if n != self._seen[r.name]:
                self._seen[r.name] = n
                msg = node.cmd_vel
                r.command(float(msg.linear.x), float(msg.angular.z), self.sim.t)

    def publish(self, readings: list[Reading]) -> None:
        for reading in readings:
            node = self.nodes[reading.robot]
            if isinstance(reading, Odometry):
                self._send(node, "odom", self._odometry(reading))
            elif isinstance(reading, Scan):
                self._send(node, "scan", self._scan(reading))
            elif isinstance(reading, Bumper):
                c = self.msgs.cls["bumper"]
                self._send(node, "bumper", c(bumper=reading.bumper,
                                             state=c.PRESSED if reading.pressed else c.RELEASED))
        self._send(self.clock, "clock", self.msgs.cls["clock"](clock=self._stamp(self.sim.t)))

    def _send(self, node: Any, name: str, msg: Any) -> None:
        node.publish(name, msg)
        topic = node._pubs[name]["topic"]
        self._published[topic] = self._published.get(topic, 0) + 1

    # -- lockstep (hfsmc/sim/ground/lockstep.py) ----------------------------------------
    def _endpoints(self, table: str) -> dict[str, list[tuple[Any, str]]]:
        """Resolved topic -> (node, endpoint name) of the publications or subscriptions."""
        out: dict[str, list[tuple[Any, str]]] = {}
        for node in [*self.nodes.values(), self.clock]:
            for name, s in getattr(node, table).items():
                out.setdefault(s["topic"], []).append((node, name))
        return out

    def published_topics(self) -> list[str]:
        return list(self._endpoints("_pubs"))

    def subscribed_topics(self) -> list[str]:
        return list(self._endpoints("_subs"))

    def matched(self, their_subs: set[str], their_pubs: set[str]) -> bool:
        """Whether each of our publications they subscribe has a subscriber, and each of
        our subscriptions they publish has a publisher."""
        for node in [*self.nodes.values(), self.clock]:
            node.snapshot()
        pubs, subs = self._endpoints("_pubs"), self._endpoints("_subs")
        return all(node.subscribers(n) > 0 for t in their_subs & set(pubs)
                   for node, n in pubs[t]) and \
            all(node.publishers(n) > 0 for t in their_pubs & set(subs) for node, n in subs[t])

    def _received(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for topic, ends in self._endpoints("_subs").items():
            for node, name in ends:
                node.snapshot()
                out[topic] = out.get(topic, 0) + node.count(name)
        return out

    def count_from_now(self) -> None:
        """Lockstep counts samples from now on (the component has just connected)."""
        self._base_in = self._received()
        self._base_out = dict(self._published)

    def received_all(self, counts: dict[str, int]) -> bool:
        """Whether the samples the component says it sent (since it connected) have come."""
        got = self._received()
        return all(got.get(t, 0) - self._base_in.get(t, 0) >= n for t, n in counts.items()
                   if t in got)

    def published_counts(self) -> dict[str, int]:
        return {t: n - self._base_out.get(t, 0) for t, n in sorted(self._published.items())}

    def _stamp(self, t: float) -> Any:
        clock = self.msgs.cls["clock"]()
        ns = round(t * 1e9)
        stamp = type(clock.clock)(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return stamp

    def _frame(self, robot: str, frame: str) -> str:
        ns = self.sim.robot(robot).namespace.strip("/")
        return f"{ns}/{frame}" if ns else frame

    def _header(self, robot: str, t: float, frame: str) -> Any:
        header_cls = type(self.msgs.cls["scan"]().header)
        return header_cls(stamp=self._stamp(t), frame_id=self._frame(robot, frame))

    def _odometry(self, o: Odometry) -> Any:
        msg = self.msgs.cls["odom"](header=self._header(o.robot, o.t, "odom"),
                                    child_frame_id=self._frame(o.robot, "base_footprint"))
        pose = msg.pose.pose
        pose.position.x, pose.position.y = o.pose.x, o.pose.y
        pose.orientation.z, pose.orientation.w = math.sin(o.pose.yaw / 2), math.cos(o.pose.yaw / 2)
        msg.twist.twist.linear.x, msg.twist.twist.angular.z = o.v, o.w
        return msg

    def _scan(self, s: Scan) -> Any:
        n = len(s.ranges)
        return self.msgs.cls["scan"](
            header=self._header(s.robot, s.t, "base_scan"), angle_min=s.angle_min,
            angle_max=s.angle_min + (n - 1) * s.angle_increment,
            angle_increment=s.angle_increment, time_increment=0.0, scan_time=s.scan_time,
            range_min=s.range_min, range_max=s.range_max, ranges=list(s.ranges),
            intensities=[])

    def close(self) -> None:
        for node in [*self.nodes.values(), getattr(self, "clock", None)]:
            if node is not None:
                node.close()
        self.msgs.close()
