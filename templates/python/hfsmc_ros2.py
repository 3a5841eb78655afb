"""The ``ros2`` interface of Python components (docs/ros2.md): the component is a ROS 2
node, with no ROS 2 installed, over Eclipse Cyclone DDS (cyclonedds-python).

Copied beside a component with a ``ros2`` interface, with ``hfsmc_ros2_wire.py``,
``hfsmc_ros2_cdr.py`` and the generated message packages; imports nothing else of hfsmc.
The runtime calls ``connect(name, settings)`` with the interface's settings (node,
namespace, domain, distro, subscribe, publish: as in the model and NAME.yaml).

A reader thread takes every sample as it comes, decodes it (a malformed one is dropped
and counted, said once on stderr) and keeps the latest per subscription; ``snapshot()``
freezes that once per instant, and snippets read the frozen state
(:class:`Ros2Queries`): ``robot.scan``, ``robot.age("scan")``, ``robot.count("scan")``,
``robot.publishers("scan")``, ``robot.subscribers("cmd_vel")``. ``robot.publish(name,
msg)`` is a command: written at once.

On the wire as ROS 2 (rmw_cyclonedds_cpp): participant USER_DATA ``enclave=/;``; topics
``rt/<resolved name>`` of type ``pkg::msg::dds_::Name_``; plain CDR (XCDR1); with jazzy
``typehash=RIHS01_...;`` in each endpoint's USER_DATA; the node and its endpoints
announced on ``ros_discovery_info`` (rmw_dds_common/msg/ParticipantEntitiesInfo, whose
Gid is 24 bytes in humble and 16 in jazzy, as generated).
"""

from __future__ import annotations

import atexit
import base64
import contextlib
import math
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from cyclonedds.core import (
    DDSException,
    GuardCondition,
    InstanceState,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

if __package__:
    from . import hfsmc_ros2_cdr as cdr
    from . import hfsmc_ros2_rpc as rpc
    from . import hfsmc_ros2_wire as wire
    from .hfsmc_ros2_lockstep import Ros2Lockstep
else:  # copied beside the generated component, where the modules are top level
    import hfsmc_ros2_cdr as cdr  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_rpc as rpc  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_wire as wire  # type: ignore[import-not-found, no-redef]
    from hfsmc_ros2_lockstep import Ros2Lockstep  # type: ignore[import-not-found, no-redef]

DISTROS = ("humble", "jazzy")
DISCOVERY_TOPIC = "ros_discovery_info"
DISCOVERY_TYPE = "rmw_dds_common/msg/ParticipantEntitiesInfo"
TAKE_MAX = 64  # samples taken per reader and wake-up
WAKE_S = 0.05  # the reader thread looks at matched endpoints at least this often

Ros2Error = wire.Ros2Error


def connect(name: str, settings: dict[str, Any]) -> Ros2Node:
    """Join the ROS 2 graph as a node; returns once the node's endpoints exist. A bad
    setting or no usable network: one line on stderr and exit status 2."""
    try:
        return Ros2Node(name, settings)
    except (Ros2Error, DDSException) as exc:
        with contextlib.suppress(ValueError, OSError):
            sys.stderr.write(f"{name}: ros2: {_one_line(exc)}\n")
        raise SystemExit(2) from None


def _one_line(exc: Exception) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


class _Sub:
    """What the reader thread keeps of one subscription (replaced whole)."""

    __slots__ = ("arrived", "cdr", "count", "dropped", "msg", "publishers")

    def __init__(self) -> None:
        self.msg: Any = None
        self.cdr: bytes | None = None
        self.arrived = 0.0
        self.count = 0
        self.dropped = 0
        self.publishers = 0


class Ros2Queries:
    """What snippets call. Reads return the snapshot taken when the instant began."""

    name: str
    url: str | None = None  # every interface has one (docs/drivers.md); a ros2 one has none
    _subs: dict[str, Any]  # subscription name -> its settings
    _pubs: dict[str, Any]  # publication name -> its settings
    _snap: dict[str, tuple[Any, float, int, int]]  # name -> (msg, age, count, publishers)
    _snap_subscribers: dict[str, int]
    _acts: dict[str, Any]  # action name -> its settings (name, class, timeout)
    _srvs: dict[str, Any]  # service name -> its settings
    _goal_snap: dict[str, tuple[str, Any, Any]]  # action -> (status, feedback, result)
    _call_snap: dict[str, tuple[str, Any]]  # service -> (status, response)

    def __getattr__(self, attr: str) -> Any:
        """``robot.scan``: the latest message of subscription ``scan`` when the instant
        began; None before the first."""
        subs = self.__dict__.get("_subs") or {}
        if attr in subs:
            return self.__dict__["_snap"][attr][0]
        name = self.__dict__.get("name", "?")
        raise AttributeError(f"the ros2 interface `{name}` has no subscription or method "
                             f"`{attr}` (subscriptions: {', '.join(subs) or 'none'})",
                             name=attr, obj=self)

    def age(self, name: str) -> float:
        """Seconds since the latest message of ``name`` arrived; inf before the first."""
        return self._snap[self._sub(name)][1]

    def count(self, name: str) -> int:
        """How many messages of ``name`` have arrived since start."""
        return self._snap[self._sub(name)][2]

    def publishers(self, name: str) -> int:
        """How many remote publishers the subscription ``name`` is matched with."""
        return self._snap[self._sub(name)][3]

    def subscribers(self, name: str) -> int:
        """How many remote subscribers the publication ``name`` is matched with."""
        return self._snap_subscribers[self._pub(name)]

    def publish(self, name: str, msg: Any) -> None:
        """Send ``msg`` on the publication ``name`` now (a command)."""
        setting = self._pubs[self._pub(name)]
        cls = setting["class"]
        if type(msg) is not cls:
            raise TypeError(f"{self.name}.publish({name!r}, ...): a {cls._TYPE} is expected, "
                            f"not {_kind(msg)}")
        self._send(name, cdr.serialize(msg))

    # -- actions and services (SPEC 5.3) --------------------------------------------
    def send_goal(self, name: str, goal: Any) -> None:
        """Send ``goal`` (``Action.Goal``) to the action ``name`` now (a command). A goal
        still running is cancelled first. The status reads ``pending`` from now on in this
        instant; what the server says is seen from the next instants."""
        cls = self._acts[self._act(name)]["class"]
        if type(goal) is not cls.Goal:
            raise TypeError(f"{self.name}.send_goal({name!r}, ...): a {cls._TYPE} goal "
                            f"({cls.Goal._TYPE}) is expected, not {_kind(goal)}")
        running = self._goal_snap[name][0] in rpc.RUNNING  # as this instant sees it
        self._goal_snap[name] = ("pending", None, None)
        self._send_goal(name, goal, running)

    def cancel(self, name: str) -> bool:
        """Ask the server to cancel the running goal of ``name`` (a command); False, and
        nothing sent, when no goal runs."""
        if self._goal_snap[self._act(name)][0] not in rpc.RUNNING:
            return False
        self._cancel(name)
        return True

    def goal_status(self, name: str) -> str:
        """The status of the latest goal of ``name``: none, pending, accepted, executing,
        canceling, succeeded, aborted, canceled, rejected, no_server or timeout."""
        return str(self._goal_snap[self._act(name)][0])

    def feedback(self, name: str) -> Any:
        """The latest feedback of the running goal of ``name``; None before any."""
        return self._goal_snap[self._act(name)][1]

    def result(self, name: str) -> Any:
        """The result of the latest goal of ``name`` once it ended; None before."""
        return self._goal_snap[self._act(name)][2]

    def call(self, name: str, request: Any) -> None:
        """Call the service ``name`` with ``request`` (``Service.Request``) now (a
        command); a call still pending is forgotten. ``pending`` from now on."""
        cls = self._srvs[self._srv(name)]["class"]
        if type(request) is not cls.Request:
            raise TypeError(f"{self.name}.call({name!r}, ...): a {cls._TYPE} request "
                            f"({cls.Request._TYPE}) is expected, not {_kind(request)}")
        self._call_snap[name] = ("pending", None)
        self._call(name, request)

    def call_status(self, name: str) -> str:
        """The status of the latest call of ``name``: none, pending, done, no_server or
        timeout."""
        return str(self._call_snap[self._srv(name)][0])

    def response(self, name: str) -> Any:
        """The response of the latest call of ``name``; None until it is done."""
        return self._call_snap[self._srv(name)][1]

    def _send(self, name: str, data: bytes) -> None:
        raise NotImplementedError  # the live class and the replay define it

    def _send_goal(self, name: str, goal: Any, running: bool) -> None:
        raise NotImplementedError  # the live class and the replay define it

    def _cancel(self, name: str) -> None:
        raise NotImplementedError

    def _call(self, name: str, request: Any) -> None:
        raise NotImplementedError

    def _act(self, name: str) -> str:
        if name not in self._acts:
            raise KeyError(f"the ros2 interface `{self.name}` has no action `{name}` "
                           f"(actions: {', '.join(self._acts) or 'none'})")
        return name

    def _srv(self, name: str) -> str:
        if name not in self._srvs:
            raise KeyError(f"the ros2 interface `{self.name}` has no service `{name}` "
                           f"(services: {', '.join(self._srvs) or 'none'})")
        return name

    # -- the recording's own channels (docs/drivers.md) -------------------------------
    def own_channels(self) -> dict[str, dict[str, Any]]:
        """The MCAP channels of this interface's topics, one per subscription and per
        publication (key ``subscription/NAME``, ``publication/NAME``): named after the
        resolved topic, the message's ``ros2msg`` definition as schema, ``cdr`` bytes."""
        out: dict[str, dict[str, Any]] = {}
        for role, table in (("subscription", self._subs), ("publication", self._pubs)):
            for n, s in table.items():
                cls = s["class"]
                out[f"{role}/{n}"] = {
                    "topic": s["topic"], "schema": cls._TYPE, "schema_encoding": "ros2msg",
                    "schema_data": cls._ROS2MSG.encode(), "encoding": "cdr",
                    "metadata": {"hfsmc.interface": self.name, f"hfsmc.{role}": n}}
        return out

    def recorded(self, values: dict[str, Any]
                 ) -> tuple[dict[str, Any], dict[str, tuple[int, bytes]]]:
        """A snapshot as recorded: its JSON part (per subscription count, age, publishers,
        dropped; per publication its subscribers; each action's goal and each service's
        call: ``rpc.as_recorded``), and per subscription the latest sample's CDR with its
        count (the recording writes it when the count is new)."""
        subs: dict[str, Any] = {}
        raw: dict[str, tuple[int, bytes]] = {}
        for n, v in values["subscriptions"].items():
            subs[n] = {k: v[k] for k in ("count", "age", "publishers", "dropped")}
            if v.get("cdr") is not None:
                raw[f"subscription/{n}"] = (int(v["count"]), v["cdr"])
        out = {"subscriptions": subs, "subscribers": dict(values["subscribers"])}
        out.update(rpc.as_recorded(values, self.__dict__.setdefault("_recorded", {})))
        return out, raw

    def _sub(self, name: str) -> str:
        if name not in self._subs:
            raise KeyError(f"the ros2 interface `{self.name}` has no subscription `{name}` "
                           f"(subscriptions: {', '.join(self._subs) or 'none'})")
        return name

    def _pub(self, name: str) -> str:
        if name not in self._pubs:
            raise KeyError(f"the ros2 interface `{self.name}` does not publish `{name}` "
                           f"(publications: {', '.join(self._pubs) or 'none'})")
        return name


def _intro() -> Any:
    """hfsmc_ros2intro, imported only by a node that publishes its automaton (the module
    and the viewer's state it needs are copied beside every component, not beside the
    simulator's nodes)."""
    if __package__:
        from . import hfsmc_ros2intro
    else:
        import hfsmc_ros2intro  # type: ignore[import-not-found, no-redef]
    return hfsmc_ros2intro


def _kind(msg: Any) -> str:
    t = getattr(type(msg), "_TYPE", None)
    return t if isinstance(t, str) else type(msg).__name__


class Ros2Node(Ros2Lockstep, Ros2Queries):
    """A ROS 2 node on DDS: its subscriptions and publications, and the reader thread."""

    def __init__(self, name: str, settings: dict[str, Any]) -> None:
        self.name = name
        self.distro = str(settings.get("distro") or "jazzy")
        if self.distro not in DISTROS:
            raise Ros2Error(f"distro `{self.distro}`: one of {', '.join(DISTROS)}")
        self.node = wire.validate_node_name(str(settings.get("node") or name))
        self.namespace = wire.validate_namespace(str(settings.get("namespace") or "/"))
        self.domain = wire.domain_id(settings.get("domain"))
        self._subs = self._endpoints(settings.get("subscribe") or {})
        self._pubs = self._endpoints(settings.get("publish") or {})
        self._acts = self._rpc_settings(settings.get("actions") or {})
        self._srvs = self._rpc_settings(settings.get("services") or {})
        self._goal_snap = {n: ("none", None, None) for n in self._acts}
        self._call_snap = {n: ("none", None) for n in self._srvs}
        self._check_topics()
        self._introspect = settings.get("introspection") is True
        self.on_publish: Callable[[str, bytes], None] | None = None  # a recording's hook
        self.on_command: Callable[[str, list[Any]], None] | None = None  # the recording's
        self._lockstep_init()
        self._lock = threading.Lock()
        self._pending = {n: _Sub() for n in self._subs}
        self._snap = {n: (None, math.inf, 0, 0) for n in self._subs}
        self._snap_subscribers = dict.fromkeys(self._pubs, 0)
        self._subscribers = dict.fromkeys(self._pubs, 0)
        self._sent = dict.fromkeys(self._pubs, 0)  # per publication, for the live views (views())
        self._said: set[str] = set()
        self._closed = False
        self._open_dds()
        self._stop = GuardCondition(self._dp)
        self._thread = threading.Thread(target=self._run, name=f"ros2 {name}", daemon=True)
        self._thread.start()
        atexit.register(self.close)

    def __repr__(self) -> str:
        return f"<ros2 {self.name} node {self.namespace.rstrip('/')}/{self.node} " \
               f"domain {self.domain}>"

    def _endpoints(self, table: Any) -> dict[str, Any]:
        if not isinstance(table, dict):
            raise Ros2Error("subscribe and publish map names to topics")
        out: dict[str, Any] = {}
        for key, spec in table.items():
            if not isinstance(spec, dict) or "type" not in spec:
                raise Ros2Error(f"`{key}`: {{topic, type, qos}}")
            cls = wire.message_class(str(spec["type"]))
            topic = wire.resolve_name(str(spec.get("topic") or key), self.namespace, self.node)
            out[str(key)] = {"topic": topic, "class": cls, "qos": wire.qos_of(spec.get("qos"))}
        return out

    def _rpc_settings(self, table: Any) -> dict[str, Any]:
        """``actions`` / ``services``: name -> {name (the ROS name), type, timeout (s)}."""
        if not isinstance(table, dict):
            raise Ros2Error("actions and services map names to {name, type, timeout}")
        out: dict[str, Any] = {}
        for key, spec in table.items():
            if not isinstance(spec, dict) or "type" not in spec:
                raise Ros2Error(f"`{key}`: {{name, type, timeout}}")
            timeout = spec.get("timeout")
            if timeout is not None and (isinstance(timeout, bool)
                                        or not isinstance(timeout, (int, float))
                                        or not timeout > 0):
                raise Ros2Error(f"`{key}`: timeout `{timeout}`: seconds > 0, or null")
            out[str(key)] = {
                "name": wire.resolve_name(str(spec.get("name") or key), self.namespace,
                                          self.node),
                "class": wire.message_class(str(spec["type"])),
                "timeout": None if timeout is None else float(timeout)}
        return out

    def _check_topics(self) -> None:
        seen: dict[str, Any] = {}
        for key, s in [*self._subs.items(), *self._pubs.items()]:
            other = seen.setdefault(s["topic"], s["class"])
            if other is not s["class"]:
                raise Ros2Error(f"topic {s['topic']} (`{key}`) is used with two types: "
                                f"{other._TYPE} and {s['class']._TYPE}")

    # -- DDS ---------------------------------------------------------------------------
    def _open_dds(self) -> None:
        try:
            self._dp = DomainParticipant(self.domain, qos=wire.dds_qos(
                ("reliable", "volatile", 1), b"enclave=/;"))
        except DDSException:
            uri = " (CYCLONEDDS_URI is set: look at its network settings)" \
                if os.environ.get("CYCLONEDDS_URI") else ""
            raise Ros2Error(f"cannot join ROS 2 domain {self.domain}: Cyclone DDS found no "
                            f"usable network interface{uri}") from None
        topics: dict[str, Topic[Any]] = {}

        def topic(s: dict[str, Any]) -> Topic[Any]:
            if s["topic"] not in topics:
                topics[s["topic"]] = Topic(self._dp, "rt" + s["topic"], wire.dds_type(s["class"]))
            return topics[s["topic"]]

        self._readers = {n: DataReader(self._dp, topic(s), qos=self._qos(s))
                         for n, s in self._subs.items()}
        self._writers = {n: DataWriter(self._dp, topic(s), qos=self._qos(s))
                         for n, s in self._pubs.items()}
        self._topics = topics
        self._actions = {n: rpc.ActionClient(self._dp, n, s) for n, s in self._acts.items()}
        self._services = {n: rpc.ServiceClient(self._dp, n, s) for n, s in self._srvs.items()}
        self._views = _intro().writers(self, topic) if self._introspect else {}
        self._announce()

    def _qos(self, s: dict[str, Any]) -> Any:
        user = f"typehash={s['class']._HASH};".encode() if self.distro == "jazzy" else None
        return wire.dds_qos(s["qos"], user)

    def _announce(self) -> None:
        """The node and its endpoints on ros_discovery_info, as rmw_dds_common does."""
        info_cls = wire.message_class(DISCOVERY_TYPE)
        gid_cls = wire.message_class("rmw_dds_common/msg/Gid")
        size = int(gid_cls._FIELDS["data"].rsplit("[", 1)[1].rstrip("]"))

        def gid(entity: Any) -> Any:
            return gid_cls(data=list(entity.guid.bytes.ljust(size, b"\x00")))

        node_cls = wire.message_class("rmw_dds_common/msg/NodeEntitiesInfo")
        rpcs: list[Any] = [e for c in self._clients()
                           for e in c.entities()]
        node = node_cls(node_namespace=self.namespace, node_name=self.node,
                        reader_gid_seq=[gid(r) for r in (*self._readers.values(),
                                                         *[e for e in rpcs
                                                           if isinstance(e, DataReader)])],
                        writer_gid_seq=[gid(w) for w in (*self._writers.values(),
                                                         *[v[1] for v in self._views.values()],
                                                         *[e for e in rpcs
                                                           if isinstance(e, DataWriter)])])
        info = info_cls(gid=gid(self._dp), node_entities_info_seq=[node])
        kind = wire.dds_type(info_cls)
        qos = ("reliable", "transient_local", 1)
        user = f"typehash={info_cls._HASH};".encode() if self.distro == "jazzy" else None
        self._info_topic = Topic(self._dp, DISCOVERY_TOPIC, kind)
        self._info_writer = DataWriter(self._dp, self._info_topic, qos=wire.dds_qos(qos, user))
        self._info_writer.write(wire.raw_sample(kind, cdr.serialize(info)))

    def _send(self, name: str, data: bytes) -> None:
        writer = self._writers[name]
        writer.write(wire.raw_sample(writer.data_type, data))
        self._count_published(name)
        with self._lock:
            self._sent[name] += 1
        if self.on_publish is not None:
            self.on_publish(name, data)

    # -- the instant's snapshot ------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """Freeze the latest state for the instant that begins; queries return it. The
        result (for a recording): per subscription its count, age, matched publishers,
        dropped samples and the latest CDR bytes; per publication its subscribers."""
        now = time.monotonic()
        with self._lock:
            pending = [(n, s.msg, s.cdr, s.arrived, s.count, s.dropped, s.publishers)
                       for n, s in self._pending.items()]
            self._snap_subscribers = dict(self._subscribers)
        snap: dict[str, tuple[Any, float, int, int]] = {}
        topics: dict[str, Any] = {}
        for n, msg, data, arrived, count, dropped, pubs in pending:
            age = self._age(n, count, arrived, now)
            snap[n] = (msg, age, count, pubs)
            topics[n] = {"count": count, "age": age, "publishers": pubs, "dropped": dropped,
                         "cdr": data}
        self._snap = snap
        with self._lock:
            self._goal_snap = {n: (c.status, c.feedback, c.result)
                               for n, c in self._actions.items()}
            self._call_snap = {n: (c.status, c.response) for n, c in self._services.items()}
        return {"subscriptions": topics, "subscribers": dict(self._snap_subscribers),
                **rpc.snapshot_values(self._goal_snap, self._call_snap)}

    def views(self) -> dict[str, Any]:
        """What the live views show (the monitor's thread calls it; the instant's snapshot
        is left alone): the node, and per subscription its topic, type, count, age, matched
        publishers, dropped samples and latest message; per publication its topic, type,
        published count and matched subscribers (docs/web.md, "ROS 2")."""
        now = time.monotonic()
        with self._lock:
            subs = {n: {"topic": self._subs[n]["topic"], "type": self._subs[n]["class"]._TYPE,
                        "count": s.count, "age": now - s.arrived if s.count else None,
                        "publishers": s.publishers, "dropped": s.dropped, "msg": s.msg}
                    for n, s in self._pending.items()}
            pubs = {n: {"topic": p["topic"], "type": p["class"]._TYPE,
                        "count": self._sent[n], "subscribers": self._subscribers[n]}
                    for n, p in self._pubs.items()}
        return {"node": self.node, "namespace": self.namespace, "domain": self.domain,
                "distro": self.distro, "subscriptions": subs, "publications": pubs}

    # -- actions and services, live ---------------------------------------------------
    def _send_goal(self, name: str, goal: Any, running: bool) -> None:
        data = cdr.serialize(goal)
        with self._lock:
            client = self._actions[name]
            client.send_goal(goal, time.monotonic())  # cancels the goal it has running
            client.poll(time.monotonic())
        if running:  # recorded as the instant saw it, so that a replay tells the same
            self._told("cancel", [name, "replaced"])
        self._told("send_goal", [name, base64.b64encode(data).decode("ascii")])

    def _cancel(self, name: str) -> None:
        with self._lock:
            self._actions[name].cancel()
        self._told("cancel", [name])

    def _call(self, name: str, request: Any) -> None:
        data = cdr.serialize(request)
        with self._lock:
            client = self._services[name]
            client.call(data, time.monotonic())
            client.poll(time.monotonic())
        self._told("call", [name, base64.b64encode(data).decode("ascii")])

    def _clients(self) -> list[Any]:
        """The action and service clients."""
        return [*self._actions.values(), *self._services.values()]

    def _told(self, call: str, args: list[Any]) -> None:
        if self.on_command is not None:
            with contextlib.suppress(Exception):  # a recording that has closed
                self.on_command(call, args)

    def _rpc_poll(self) -> None:
        now = time.monotonic()
        with self._lock:
            for c in self._clients():
                try:
                    c.poll(now)
                except cdr.CdrError as exc:
                    self._say(f"a malformed answer of `{c.key}` dropped ({exc})")

    def _cancel_at_stop(self) -> None:
        """A goal still running when the component stops is cancelled (recorded); the
        cancel request is given a second to reach the server."""
        with self._lock:
            sent = [n for n, c in self._actions.items() if c.running() and c.cancel_current()]
        for n in sent:
            self._told("cancel", [n, "stop"])
            with contextlib.suppress(DDSException):
                self._actions[n].cancel_ep.writer.wait_for_acks(duration(seconds=1))

    def introspection(self) -> Any:
        """With ``introspection: true``: the observer that publishes the automaton on
        /fsm_viewer and ~/hfsm/status (SPEC 5.4); else None."""
        return _intro().Introspection(self, self._views) if self._views else None

    def dropped(self, name: str) -> int:
        """Malformed samples of ``name`` dropped so far (not a snapshot: for the views)."""
        with self._lock:
            return int(self._pending[self._sub(name)].dropped)

    def close(self) -> None:
        """Leave the graph (also run at exit): the reader thread stops, DDS entities go."""
        if self._closed:
            return
        with contextlib.suppress(DDSException):
            self._cancel_at_stop()
        self._closed = True
        self._stop.set(True)
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        with contextlib.suppress(DDSException):
            self._dp.__del__()

    # -- the reader thread -------------------------------------------------------------
    def _run(self) -> None:
        ws = WaitSet(self._dp)
        mask = SampleState.NotRead | ViewState.Any | InstanceState.Any
        conds = [ReadCondition(r, mask) for r in self._readers.values()]
        for client in self._clients():
            conds += [ReadCondition(r, mask) for r in client.readers()]
        for c in conds:
            ws.attach(c)
        ws.attach(self._stop)
        while not self._closed:
            try:
                ws.wait(duration(seconds=WAKE_S))
                for n, reader in self._readers.items():
                    self._take(n, reader)
                self._rpc_poll()
                self._matched()
            except DDSException as exc:
                if self._closed:
                    return
                self._say(f"DDS: {_one_line(exc)}")
                time.sleep(WAKE_S)

    def _take(self, name: str, reader: DataReader[Any]) -> None:
        samples = reader.take(TAKE_MAX)
        if not samples:
            return
        cls = self._subs[name]["class"]
        for sample in samples:
            data = sample.__dict__.get("raw")
            if data is None:  # an instance disposed, no data
                continue
            now = time.monotonic()
            try:
                msg = cdr.deserialize(cls, data)
            except cdr.CdrError as exc:
                with self._lock:
                    self._pending[name].dropped += 1
                if name not in self._said:
                    self._said.add(name)
                    self._say(f"a malformed sample on {self._subs[name]['topic']} dropped "
                              f"({exc}); further ones are counted")
                continue
            with self._lock:
                s = self._pending[name]
                s.msg, s.cdr, s.arrived, s.count = msg, bytes(data), now, s.count + 1

    def _matched(self) -> None:
        readers: dict[str, Any] = self._readers  # the binding's status calls are untyped
        writers: dict[str, Any] = self._writers
        pubs = {n: int(r.get_subscription_matched_status().current_count)
                for n, r in readers.items()}
        subs = {n: int(w.get_publication_matched_status().current_count)
                for n, w in writers.items()}
        with self._lock:
            for n, c in pubs.items():
                self._pending[n].publishers = c
            self._subscribers = subs

    def _say(self, text: str) -> None:
        with contextlib.suppress(ValueError, OSError):
            sys.stderr.write(f"{self.name}: ros2: {text}\n")
            sys.stderr.flush()
