"""ROS 2 services and actions of the ``ros2`` interface (SPEC 5.3, docs/ros2.md "Services
and actions"): the clients a component uses, and the servers the simulator and the tests
use, on rmw_cyclonedds_cpp's request/reply mapping.

The mapping: a service ``/ns/reset`` is two DDS topics, ``rq/ns/resetRequest`` (type
``pkg::srv::dds_::Name_Request_``) and ``rr/ns/resetReply`` (``..._Response_``), reliable,
volatile, keep last 10. Each sample is the request header, the client's 8-byte id and a
64-bit sequence number (little endian, right after the CDR encapsulation), then the message
as on a topic; the server answers with the same header, and a client keeps the replies
that carry its own id. Client endpoints carry ``clientid=<id>;`` in their USER_DATA
(servers ``serviceid=...;``): a server on rmw_cyclonedds_cpp waits until it has matched
the reader of the client that asked before it answers.

An action ``/ns/navigate`` is three services, ``navigate/_action/send_goal``,
``.../cancel_goal`` (action_msgs/srv/CancelGoal) and ``.../get_result``, and two topics,
``navigate/_action/feedback`` (reliable, volatile) and ``navigate/_action/status``
(action_msgs/msg/GoalStatusArray, reliable, transient local, keep last 1). Goal ids are
random UUIDs (16 bytes, as rclpy's).

Copied beside a component with a ``ros2`` interface; imports only cyclonedds and the
runtime's wire module.
"""

from __future__ import annotations

import base64
import binascii
import os
import struct
import time
from typing import Any

from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

if __package__:
    from . import hfsmc_ros2_cdr as cdr
    from . import hfsmc_ros2_wire as wire
else:  # beside the generated component
    import hfsmc_ros2_cdr as cdr  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_wire as wire  # type: ignore[import-not-found, no-redef]

HEADER = struct.Struct("<Qq")  # the client's id, the sequence number
SERVICE_QOS = ("reliable", "volatile", 10)  # rmw_qos_profile_services_default
FEEDBACK_QOS = ("reliable", "volatile", 10)
STATUS_QOS = ("reliable", "transient_local", 1)  # rcl_action_qos_profile_status_default
TAKE_MAX = 64
# action_msgs/msg/GoalStatus's values, as the status a snippet reads
GOAL_STATUS = {1: "accepted", 2: "executing", 3: "canceling", 4: "succeeded", 5: "canceled",
               6: "aborted"}
TERMINAL = frozenset({"succeeded", "aborted", "canceled", "rejected", "timeout"})
RUNNING = frozenset({"pending", "accepted", "executing", "canceling", "no_server"})
GOAL_STATUSES = ("none", "pending", "accepted", "executing", "canceling", "succeeded",
                 "aborted", "canceled", "rejected", "no_server", "timeout")
CALL_STATUSES = ("none", "pending", "done", "no_server", "timeout")


def wrap(client: int, seq: int, data: bytes) -> bytes:
    """A message's CDR (header first) as a request or reply sample: the request header
    after the encapsulation, then the message."""
    return bytes(data[:4]) + HEADER.pack(client, seq) + bytes(data[4:])


def unwrap(data: bytes) -> tuple[int, int, bytes]:
    """A request or reply sample -> (client id, sequence number, the message's CDR)."""
    if len(data) < 4 + HEADER.size:
        raise cdr.CdrError("a request or reply shorter than its header")
    client, seq = HEADER.unpack_from(data, 4)
    return client, seq, bytes(data[:4]) + bytes(data[4 + HEADER.size:])


class Endpoint:
    """One side of a service on a participant: ``client`` writes requests and reads
    replies, a server the other way round."""

    def __init__(self, dp: Any, service: str, request: Any, response: Any, client: bool) -> None:
        self.service = service
        self.request, self.response = request, response
        rq = Topic(dp, f"rq{service}Request", wire.dds_type(request, header=True))
        rr = Topic(dp, f"rr{service}Reply", wire.dds_type(response, header=True))
        self.topics = (rq, rr)
        out, into = (rq, rr) if client else (rr, rq)
        self.client = client
        self.ident = int.from_bytes(os.urandom(8), "little")  # the id requests carry
        tag = f"{'clientid' if client else 'serviceid'}={self.ident:016x};".encode()
        self.writer: Any = DataWriter(dp, out, qos=wire.dds_qos(SERVICE_QOS, tag))
        self.reader: Any = DataReader(dp, into, qos=wire.dds_qos(SERVICE_QOS, tag))
        self.seq = 0

    def matched(self) -> bool:
        """Both of the other side's endpoints are matched."""
        return (int(self.writer.get_publication_matched_status().current_count) > 0
                and int(self.reader.get_subscription_matched_status().current_count) > 0)

    def send(self, msg_cdr: bytes) -> int:
        """A client's request; returns its sequence number."""
        self.seq += 1
        self.writer.write(wire.raw_sample(self.writer.data_type,
                                          wrap(self.ident, self.seq, msg_cdr)))
        return self.seq

    def reply(self, client: int, seq: int, msg_cdr: bytes) -> None:
        """A server's reply to the request (client, seq)."""
        self.writer.write(wire.raw_sample(self.writer.data_type, wrap(client, seq, msg_cdr)))

    def take(self) -> list[tuple[int, int, bytes]]:
        """Samples as (client id, seq, CDR); a client keeps only replies to itself. A sample
        too short for its header is dropped."""
        out = []
        for sample in self.reader.take(TAKE_MAX):
            data = sample.__dict__.get("raw")
            if data is None:
                continue
            try:
                client, seq, body = unwrap(data)
            except cdr.CdrError:
                continue
            if not self.client or client == self.ident:
                out.append((client, seq, body))
        return out

    def entities(self) -> list[Any]:
        return [self.writer, self.reader]


def action_names(name: str) -> dict[str, str]:
    """The services and topics of the action ``name`` (resolved)."""
    base = f"{name}/_action"
    return {"send_goal": f"{base}/send_goal", "cancel_goal": f"{base}/cancel_goal",
            "get_result": f"{base}/get_result", "feedback": f"{base}/feedback",
            "status": f"{base}/status"}


def stamp_now() -> Any:
    """builtin_interfaces/Time of the wall clock (a server's acceptance stamp)."""
    t = time.time()
    cls = wire.message_class("builtin_interfaces/msg/Time")
    return cls(sec=int(t), nanosec=int((t % 1) * 1e9))


def new_uuid() -> Any:
    cls = wire.message_class("unique_identifier_msgs/msg/UUID")
    return cls(uuid=list(os.urandom(16)))


# ---------------------------------------------------------------------------------------
# the client's side: one service or action of a component


class ServiceClient:
    """A service a component calls: the state of its latest call."""

    def __init__(self, dp: Any, key: str, setting: dict[str, Any]) -> None:
        self.key = key
        self.cls = setting["class"]
        self.timeout: float | None = setting["timeout"]
        self.ep = Endpoint(dp, setting["name"], self.cls.Request, self.cls.Response, True)
        self.status = "none"
        self.response: Any = None
        self.waiting: bytes | None = None  # a request held until the server is matched
        self.seq = 0
        self.deadline = 0.0

    def entities(self) -> list[Any]:
        return self.ep.entities()

    def readers(self) -> list[Any]:
        return [self.ep.reader]

    def call(self, data: bytes, now: float) -> None:
        self.status, self.response, self.waiting, self.seq = "pending", None, data, 0
        self.deadline = now + self.timeout if self.timeout is not None else 0.0

    def poll(self, now: float) -> None:
        """Send a held request once the server is there; take the reply; the time limit."""
        for _, seq, body in self.ep.take():
            if self.status in ("pending", "no_server") and seq == self.seq and not self.waiting:
                try:
                    self.response = cdr.deserialize(self.cls.Response, body)
                    self.status = "done"
                except cdr.CdrError:
                    continue
        if self.waiting is not None:
            if self.ep.matched():
                self.seq = self.ep.send(self.waiting)
                self.waiting = None
                self.status = "pending"
            else:
                self.status = "no_server"
        if self.deadline and self.status in ("pending", "no_server") and now >= self.deadline:
            self.status, self.waiting = "timeout", None


class ActionClient:
    """An action a component sends goals to: the state of its latest goal."""

    def __init__(self, dp: Any, key: str, setting: dict[str, Any]) -> None:
        self.key = key
        self.cls = setting["class"]
        self.timeout: float | None = setting["timeout"]
        names = action_names(setting["name"])
        impl = self.cls.Impl
        cancel = wire.message_class("action_msgs/srv/CancelGoal")
        self.cancel_cls = cancel
        self.send_ep = Endpoint(dp, names["send_goal"], impl.SendGoalService.Request,
                                impl.SendGoalService.Response, True)
        self.cancel_ep = Endpoint(dp, names["cancel_goal"], cancel.Request, cancel.Response,
                                  True)
        self.result_ep = Endpoint(dp, names["get_result"], impl.GetResultService.Request,
                                  impl.GetResultService.Response, True)
        fb = impl.FeedbackMessage
        status = wire.message_class("action_msgs/msg/GoalStatusArray")
        self.status_cls = status
        self.feedback_reader: Any = DataReader(
            dp, Topic(dp, "rt" + names["feedback"], wire.dds_type(fb)),
            qos=wire.dds_qos(FEEDBACK_QOS))
        self.status_reader: Any = DataReader(
            dp, Topic(dp, "rt" + names["status"], wire.dds_type(status)),
            qos=wire.dds_qos(STATUS_QOS))
        self.status = "none"
        self.feedback: Any = None
        self.result: Any = None
        self.goal_id: bytes = b""
        self.waiting: bytes | None = None  # a goal held until the server is matched
        self.accepted = False
        self.send_seq = 0
        self.result_seq = 0
        self.deadline = 0.0

    def entities(self) -> list[Any]:
        return [*self.send_ep.entities(), *self.cancel_ep.entities(),
                *self.result_ep.entities(), self.feedback_reader, self.status_reader]

    def readers(self) -> list[Any]:
        return [self.send_ep.reader, self.cancel_ep.reader, self.result_ep.reader,
                self.feedback_reader, self.status_reader]

    def running(self) -> bool:
        return self.status in RUNNING

    def send_goal(self, goal: Any, now: float) -> bool:
        """A new goal (the one before, if running, is cancelled: True then)."""
        replaced = self.cancel_current()
        uuid = new_uuid()
        self.goal_id = bytes(bytearray(uuid.uuid))
        req = self.cls.Impl.SendGoalService.Request(goal_id=uuid, goal=goal)
        self.waiting = cdr.serialize(req)
        self.status, self.feedback, self.result = "pending", None, None
        self.accepted, self.send_seq, self.result_seq = False, 0, 0
        self.deadline = now + self.timeout if self.timeout is not None else 0.0
        return replaced

    def cancel_current(self) -> bool:
        """Ask the server to cancel the running goal; False when none runs."""
        if not self.running():
            return False
        if self.accepted or self.send_seq:
            info = wire.message_class("action_msgs/msg/GoalInfo")
            uuid = wire.message_class("unique_identifier_msgs/msg/UUID")
            req = self.cancel_cls.Request(goal_info=info(goal_id=uuid(uuid=list(self.goal_id))))
            self.cancel_ep.send(cdr.serialize(req))
        self.waiting = None
        return True

    def cancel(self) -> bool:
        """The snippet's cancel: the goal goes to `canceling` when the server says so."""
        return self.cancel_current()

    def poll(self, now: float) -> None:
        """Everything the server said since the last poll, the held goal, the time limit."""
        impl = self.cls.Impl
        for _, seq, body in self.send_ep.take():
            if seq != self.send_seq or self.status not in ("pending", "no_server"):
                continue
            resp = cdr.deserialize(impl.SendGoalService.Response, body)
            if resp.accepted:
                self.accepted = True
                self.status = "accepted"
                req = impl.GetResultService.Request(goal_id=self._uuid())
                self.result_seq = self.result_ep.send(cdr.serialize(req))
            else:
                self.status = "rejected"
        for _, seq, body in self.result_ep.take():
            if seq == self.result_seq and self.running():
                resp = cdr.deserialize(impl.GetResultService.Response, body)
                self.result = resp.result
                self.status = GOAL_STATUS.get(int(resp.status), "aborted")
                if self.status not in TERMINAL:
                    self.status = "aborted"
        self.cancel_ep.take()  # the answer changes nothing: the status topic says it
        self._feedback()
        self._statuses()
        if self.waiting is not None:
            if self.send_ep.matched() and self.result_ep.matched():
                self.send_seq = self.send_ep.send(self.waiting)
                self.waiting = None
                self.status = "pending"
            else:
                self.status = "no_server"
        elif self.accepted and self.running() and not self.result_ep.matched():
            self.status = "no_server"  # the server went away while the goal ran
            self.accepted = False
        if self.deadline and self.running() and now >= self.deadline:
            self.cancel_current()
            self.status = "timeout"

    def _uuid(self) -> Any:
        return wire.message_class("unique_identifier_msgs/msg/UUID")(uuid=list(self.goal_id))

    def _feedback(self) -> None:
        fb = self.cls.Impl.FeedbackMessage
        for sample in self.feedback_reader.take(TAKE_MAX):
            data = sample.__dict__.get("raw")
            if data is None:
                continue
            try:
                msg = cdr.deserialize(fb, data)
            except cdr.CdrError:
                continue
            if bytes(bytearray(msg.goal_id.uuid)) == self.goal_id and self.running():
                self.feedback = msg.feedback

    def _statuses(self) -> None:
        for sample in self.status_reader.take(TAKE_MAX):
            data = sample.__dict__.get("raw")
            if data is None:
                continue
            try:
                arr = cdr.deserialize(self.status_cls, data)
            except cdr.CdrError:
                continue
            for st in arr.status_list:
                if bytes(bytearray(st.goal_info.goal_id.uuid)) != self.goal_id:
                    continue
                said = GOAL_STATUS.get(int(st.status))
                # a terminal status waits for the result, which comes with it
                if said in ("accepted", "executing", "canceling") and self.accepted \
                        and self.status in ("accepted", "executing", "canceling"):
                    self.status = said


# ---------------------------------------------------------------------------------------
# the server's side (the simulator's navigate_to_pose and reset_odometry, the tests')


class ServiceServer:
    """A service answered by ``handler(request) -> response`` at each ``poll()``."""

    def __init__(self, dp: Any, name: str, srv: Any, handler: Any) -> None:
        self.srv, self.handler = srv, handler
        self.ep = Endpoint(dp, name, srv.Request, srv.Response, False)
        self.calls = 0

    def poll(self) -> None:
        for client, seq, body in self.ep.take():
            try:
                req = cdr.deserialize(self.srv.Request, body)
            except cdr.CdrError:
                continue
            self.calls += 1
            self.ep.reply(client, seq, cdr.serialize(self.handler(req)))

    def entities(self) -> list[Any]:
        return self.ep.entities()


class ActionServer:
    """An action's server. ``on_goal(goal_id, goal) -> bool`` accepts or rejects a goal;
    ``on_cancel(goal_id) -> bool`` accepts a cancel. The owner then moves each goal on
    with :meth:`execute`, :meth:`publish_feedback` and :meth:`finish`; :meth:`poll`
    answers requests (a result request waits until its goal ends)."""

    def __init__(self, dp: Any, name: str, action: Any, on_goal: Any, on_cancel: Any) -> None:
        self.action, self.on_goal, self.on_cancel = action, on_goal, on_cancel
        names = action_names(name)
        impl = action.Impl
        cancel = wire.message_class("action_msgs/srv/CancelGoal")
        self.cancel_cls = cancel
        self.send_ep = Endpoint(dp, names["send_goal"], impl.SendGoalService.Request,
                                impl.SendGoalService.Response, False)
        self.cancel_ep = Endpoint(dp, names["cancel_goal"], cancel.Request, cancel.Response,
                                  False)
        self.result_ep = Endpoint(dp, names["get_result"], impl.GetResultService.Request,
                                  impl.GetResultService.Response, False)
        self.status_cls = wire.message_class("action_msgs/msg/GoalStatusArray")
        fb = impl.FeedbackMessage
        self.feedback_writer: Any = DataWriter(
            dp, Topic(dp, "rt" + names["feedback"], wire.dds_type(fb)),
            qos=wire.dds_qos(FEEDBACK_QOS))
        self.status_writer: Any = DataWriter(
            dp, Topic(dp, "rt" + names["status"], wire.dds_type(self.status_cls)),
            qos=wire.dds_qos(STATUS_QOS))
        # goal id -> [status (GoalStatus value), result or None, waiting (client, seq), stamp]
        self.goals: dict[bytes, list[Any]] = {}
        self.requests = {"send_goal": 0, "cancel_goal": 0, "get_result": 0}

    def entities(self) -> list[Any]:
        return [*self.send_ep.entities(), *self.cancel_ep.entities(),
                *self.result_ep.entities(), self.feedback_writer, self.status_writer]

    def poll(self) -> None:
        impl = self.action.Impl
        changed = False
        for client, seq, body in self.send_ep.take():
            self.requests["send_goal"] += 1
            req = cdr.deserialize(impl.SendGoalService.Request, body)
            gid = bytes(bytearray(req.goal_id.uuid))
            ok = bool(self.on_goal(gid, req.goal))
            stamp = stamp_now()
            if ok:
                self.goals[gid] = [1, None, [], stamp]
                changed = True
            resp = impl.SendGoalService.Response(accepted=ok, stamp=stamp)
            self.send_ep.reply(client, seq, cdr.serialize(resp))
        for client, seq, body in self.result_ep.take():
            self.requests["get_result"] += 1
            req = cdr.deserialize(impl.GetResultService.Request, body)
            goal = self.goals.get(bytes(bytearray(req.goal_id.uuid)))
            if goal is None:  # rclcpp answers STATUS_UNKNOWN for a goal it does not have
                self.result_ep.reply(client, seq, cdr.serialize(
                    impl.GetResultService.Response(status=0)))
            elif goal[0] >= 4:
                self._answer(goal, client, seq)
            else:
                goal[2].append((client, seq))
        for client, seq, body in self.cancel_ep.take():
            self.requests["cancel_goal"] += 1
            changed = self._cancel(client, seq, body) or changed
        if changed:
            self.publish_status()

    def _cancel(self, client: int, seq: int, body: bytes) -> bool:
        req = cdr.deserialize(self.cancel_cls.Request, body)
        gid = bytes(bytearray(req.goal_info.goal_id.uuid))
        goal = self.goals.get(gid)
        resp = self.cancel_cls.Response()
        if goal is None:
            resp.return_code = self.cancel_cls.Response.ERROR_UNKNOWN_GOAL_ID
        elif goal[0] >= 4:
            resp.return_code = self.cancel_cls.Response.ERROR_GOAL_TERMINATED
        elif goal[0] == 3 or self.on_cancel(gid):
            goal[0] = 3
            resp.goals_canceling = [req.goal_info]
        else:
            resp.return_code = self.cancel_cls.Response.ERROR_REJECTED
        self.cancel_ep.reply(client, seq, cdr.serialize(resp))
        return goal is not None and goal[0] == 3

    def status_of(self, gid: bytes) -> int:
        return int(self.goals[gid][0]) if gid in self.goals else 0

    def execute(self, gid: bytes) -> None:
        if self.goals[gid][0] == 1:
            self.goals[gid][0] = 2
            self.publish_status()

    def publish_feedback(self, gid: bytes, feedback: Any) -> None:
        uuid = wire.message_class("unique_identifier_msgs/msg/UUID")(uuid=list(gid))
        msg = self.action.Impl.FeedbackMessage(goal_id=uuid, feedback=feedback)
        self.feedback_writer.write(wire.raw_sample(self.feedback_writer.data_type,
                                                   cdr.serialize(msg)))

    def finish(self, gid: bytes, status: int, result: Any) -> None:
        """End the goal: 4 succeeded, 5 canceled, 6 aborted (action_msgs/GoalStatus)."""
        goal = self.goals[gid]
        goal[0], goal[1] = status, result
        for client, seq in goal[2]:
            self._answer(goal, client, seq)
        goal[2] = []
        self.publish_status()

    def _answer(self, goal: list[Any], client: int, seq: int) -> None:
        resp = self.action.Impl.GetResultService.Response(
            status=goal[0], result=goal[1] if goal[1] is not None else self.action.Result())
        self.result_ep.reply(client, seq, cdr.serialize(resp))

    def publish_status(self) -> None:
        info = wire.message_class("action_msgs/msg/GoalInfo")
        status = wire.message_class("action_msgs/msg/GoalStatus")
        uuid = wire.message_class("unique_identifier_msgs/msg/UUID")
        arr = self.status_cls(status_list=[
            status(goal_info=info(goal_id=uuid(uuid=list(gid)), stamp=g[3]), status=g[0])
            for gid, g in self.goals.items()])
        self.status_writer.write(wire.raw_sample(self.status_writer.data_type,
                                                 cdr.serialize(arr)))


# -- the instant's snapshot of goals and calls, live, recorded and replayed ---------------
def snapshot_values(goals: dict[str, tuple[str, Any, Any]], calls: dict[str, tuple[str, Any]]
                    ) -> dict[str, Any]:
    """The goals' and calls' part of an instant's snapshot (none for an interface without
    actions or services, whose recordings stay as they were)."""
    out: dict[str, Any] = {}
    if goals:
        out["goals"] = {n: {"status": s, "feedback": f, "result": r}
                        for n, (s, f, r) in goals.items()}
    if calls:
        out["calls"] = {n: {"status": s, "response": r} for n, (s, r) in calls.items()}
    return out


_MESSAGES = (("goals", ("feedback", "result")), ("calls", ("response",)))


def as_recorded(values: dict[str, Any], last: dict[tuple[str, str, str], Any]
                ) -> dict[str, Any]:
    """The goals and calls of a snapshot as the recording keeps them: each status every
    instant; a feedback, a result or a response (its CDR in base64, null for none) only
    in the instant it changed (``last``: what was recorded before, per name)."""
    out: dict[str, Any] = {}
    for key, fields in _MESSAGES:
        if key not in values:
            continue
        table: dict[str, Any] = {}
        for n, v in values[key].items():
            entry: dict[str, Any] = {"status": v["status"]}
            for f in fields:
                msg = v[f]
                if last.get((key, n, f)) is not msg:
                    last[(key, n, f)] = msg
                    entry[f] = None if msg is None else \
                        base64.b64encode(cdr.serialize(msg)).decode("ascii")
            table[n] = entry
        out[key] = table
    return out


def from_recorded(values: dict[str, Any], acts: dict[str, Any], srvs: dict[str, Any],
                  recorded: bool) -> dict[str, Any]:
    """A script's goals and calls checked and decoded (ValueError says what is wrong):
    name -> {"status", and the messages it gives}; a name the model does not have is
    left out of a recorded run's (another model may be replayed), else refused."""
    out: dict[str, Any] = {}
    for key, fields in _MESSAGES:
        table, statuses = (acts, GOAL_STATUSES) if key == "goals" else (srvs, CALL_STATUSES)
        given = values.get(key)
        if given is None:
            continue
        if not isinstance(given, dict):
            raise ValueError(f"`{key}` must be a mapping")
        got: dict[str, Any] = {}
        for n, v in given.items():
            if n not in table:
                if recorded:
                    continue
                raise ValueError(f"no {'action' if key == 'goals' else 'service'} `{n}` "
                                 f"({', '.join(table) or 'none'})")
            if not isinstance(v, dict) or v.get("status") not in statuses:
                raise ValueError(f"`{key}.{n}`: {{status, {', '.join(fields)}}} with a "
                                 f"status among {', '.join(statuses)}")
            entry = {"status": v["status"]}
            cls = table[n]["class"]
            for f in fields:
                if f in v:
                    entry[f] = _decoded(getattr(cls, f.capitalize()), v[f], f"`{n}`'s {f}")
            odd = [k for k in v if k not in ("status", *fields)]
            if odd:
                raise ValueError(f"`{key}.{n}` has no field `{odd[0]}`")
            got[n] = entry
        out[key] = got
    return out


def _decoded(cls: Any, text: Any, what: str) -> Any:
    if text is None:
        return None
    if not isinstance(text, str):
        raise ValueError(f"{what} must be base64 text")
    try:
        data = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise ValueError(f"{what} is not base64") from None
    try:
        return cdr.deserialize(cls, data)
    except cdr.CdrError as e:
        raise ValueError(f"{what} is no {cls._TYPE}: {e}") from None
