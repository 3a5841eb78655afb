#!/usr/bin/env python3
"""The processes bench/ros2_rpc.py runs beside its client component, on the services and
actions the model uses (`/bench_beep`, a std_srvs/srv/Trigger; `/bench_count`, the model's
own bench_msgs/action/Count):

* ``servers``: the runtime's test servers (hfsmc_ros2_rpc.ServiceServer, ActionServer),
  run from a generated component folder (``--folder``: its runtime and message classes),
  woken by a WaitSet on their requests: Trigger answers at once; a Count goal is accepted,
  executed and succeeds at once (the server keeps its last 10 goals);
* ``bare-server`` and ``bare-client``: the floor, a plain cyclonedds-python server and
  client (IDL dataclasses, the binding's own serializer, no hfsmc) exchanging the same
  requests and replies on the same topics and types: rmw_cyclonedds_cpp's request header
  (the client's id, the sequence number), then the message. The client sends ``--n``
  Trigger requests and ``--n`` SendGoal requests, alternately, each once the answer to the
  one before came (taken on a WaitSet), and writes "call NS" and "goal NS" lines, each
  round trip's time, to ``--out``.

Each stops after ``--seconds`` (the client once done). The domain is ``$ROS_DOMAIN_ID``, the
Cyclone settings ``$CYCLONEDDS_URI``, as for the components.
"""

# No `from __future__ import annotations`: cyclonedds-python reads the IDL classes' field
# types from their annotations, and cannot resolve `bool` or `str` written as text.
import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cyclonedds.core import (
    InstanceState,
    Policy,
    Qos,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, int32, int64, uint8, uint32, uint64
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

SERVICE = "/bench_beep"  # the model's service and action (resolved)
ACTION = "/bench_count"
KINDS = ("call", "goal")
MASK = SampleState.NotRead | ViewState.Any | InstanceState.Any


@dataclass
class Trigger_Request_(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
    rmw_client_id_: uint64
    rmw_sequence_: int64
    structure_needs_at_least_one_member: uint8


@dataclass
class Trigger_Response_(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
    rmw_client_id_: uint64
    rmw_sequence_: int64
    success: bool
    message: str


@dataclass
class UUID_(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    uuid: array[uint8, 16]  # type: ignore[type-arg, valid-type]  # cyclonedds' IDL typing


@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Count_Goal_(IdlStruct, typename="bench_msgs::action::dds_::Count_Goal_"):
    n: int32


@dataclass
class Count_SendGoal_Request_(IdlStruct,
                              typename="bench_msgs::action::dds_::Count_SendGoal_Request_"):
    rmw_client_id_: uint64
    rmw_sequence_: int64
    goal_id: UUID_
    goal: Count_Goal_


@dataclass
class Count_SendGoal_Response_(IdlStruct,
                               typename="bench_msgs::action::dds_::Count_SendGoal_Response_"):
    rmw_client_id_: uint64
    rmw_sequence_: int64
    accepted: bool
    stamp: Time_


def _request(kind: str, client: int, seq: int) -> Any:
    if kind == "call":
        return Trigger_Request_(client, seq, 0)
    uuid = UUID_(list(os.urandom(16)))  # type: ignore[arg-type]
    return Count_SendGoal_Request_(client, seq, uuid, Count_Goal_(seq))


def _reply(kind: str, r: Any) -> Any:
    if kind == "call":
        return Trigger_Response_(r.rmw_client_id_, r.rmw_sequence_, True, "ok")
    return Count_SendGoal_Response_(r.rmw_client_id_, r.rmw_sequence_, True, Time_(0, 0))


def _domain() -> int:
    return int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)


def _bare(client: bool) -> "tuple[Any, dict[str, tuple[Any, Any]], Any]":
    """The participant; per kind its (writer, reader), requests one way, replies the
    other; a WaitSet on the readers."""
    dp = DomainParticipant(_domain())
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
              Policy.Durability.Volatile, Policy.History.KeepLast(10),
              Policy.DataRepresentation(use_cdrv0_representation=True))
    ws = WaitSet(dp)
    out: dict[str, tuple[Any, Any]] = {}
    for kind, name, req, rep in (("call", SERVICE, Trigger_Request_, Trigger_Response_),
                                 ("goal", f"{ACTION}/_action/send_goal",
                                  Count_SendGoal_Request_, Count_SendGoal_Response_)):
        rq = Topic(dp, f"rq{name}Request", req)
        rr = Topic(dp, f"rr{name}Reply", rep)
        writer: Any = DataWriter(dp, rq if client else rr, qos=qos)
        reader: Any = DataReader(dp, rr if client else rq, qos=qos)
        ws.attach(ReadCondition(reader, MASK))
        out[kind] = (writer, reader)
    return dp, out, ws


def bare_server(seconds: float) -> int:
    _dp, ends, ws = _bare(client=False)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        ws.wait(duration(milliseconds=20))
        for kind, (writer, reader) in ends.items():
            for r in reader.take(16):
                if hasattr(r, "rmw_sequence_"):  # not a writer's end (an InvalidSample)
                    writer.write(_reply(kind, r))
    return 0


def bare_client(n: int, seconds: float, out: Path) -> int:
    _dp, ends, ws = _bare(client=True)
    end = time.monotonic() + seconds
    while not all(w.get_publication_matched_status().current_count
                  and r.get_subscription_matched_status().current_count
                  for w, r in ends.values()):
        if time.monotonic() > end:
            print("bare-client: no server matched", file=sys.stderr)
            return 1
        time.sleep(0.01)
    ident = int.from_bytes(os.urandom(8), "little")
    lines = []
    for seq in range(1, n + 1):
        for kind in KINDS:
            writer, reader = ends[kind]
            t0 = time.monotonic_ns()
            writer.write(_request(kind, ident, seq))
            while not any(getattr(r, "rmw_client_id_", None) == ident
                          and r.rmw_sequence_ == seq for r in reader.take(16)):
                if time.monotonic() > end:
                    print(f"bare-client: no reply to {kind} {seq}", file=sys.stderr)
                    return 1
                ws.wait(duration(milliseconds=100))
            lines.append(f"{kind} {time.monotonic_ns() - t0}\n")
    out.write_text("".join(lines), encoding="ascii")
    return 0


def servers(folder: Path, seconds: float) -> int:
    """The runtime's test servers, from a generated component folder."""
    sys.path.insert(0, str(folder))
    import hfsmc_ros2 as ros2  # type: ignore[import-not-found]
    import hfsmc_ros2_rpc as rpc  # type: ignore[import-not-found]
    from bench_msgs.action import Count  # type: ignore[import-not-found]
    from std_srvs.srv import Trigger  # type: ignore[import-not-found]

    node = ros2.Ros2Node("servers", {"node": "bench_rpc_servers", "domain": _domain()})
    beep = rpc.ServiceServer(node._dp, SERVICE, Trigger,
                             lambda r: Trigger.Response(success=True, message="ok"))
    count = rpc.ActionServer(node._dp, ACTION, Count, lambda gid, goal: True, lambda gid: True)
    ws = WaitSet(node._dp)
    for ep in (beep.ep, count.send_ep, count.result_ep, count.cancel_ep):
        ws.attach(ReadCondition(ep.reader, MASK))
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        ws.wait(duration(milliseconds=20))
        beep.poll()
        count.poll()
        for gid, g in list(count.goals.items()):
            if g[0] == 1:  # accepted: run it to its end at once
                count.execute(gid)
                count.finish(gid, 4, Count.Result(done=1))
        for gid in list(count.goals)[:-10]:  # ended and answered long ago: forgotten, as a
            del count.goals[gid]  # real server does, else each status array carries them all
    node.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=("servers", "bare-server", "bare-client"))
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--n", type=int, default=100, help="bare-client: exchanges of each kind")
    ap.add_argument("--out", type=Path, help="bare-client: where the round trips go")
    ap.add_argument("--folder", type=Path, help="servers: a generated component folder")
    ns = ap.parse_args(argv)
    if ns.mode == "servers":
        return servers(ns.folder, ns.seconds)
    if ns.mode == "bare-server":
        return bare_server(ns.seconds)
    return bare_client(ns.n, ns.seconds, ns.out)


if __name__ == "__main__":
    sys.exit(main())
