#!/usr/bin/env python3
"""The processes bench/ros2.py runs beside the components: the bare Cyclone DDS pair
(the floor of the latency figures) and the steady feeder of the CPU and snapshot figures.

* ``bare-pub``: a plain cyclonedds-python writer of ``std_msgs::msg::dds_::Int64_`` (an
  IDL dataclass, the binding's own serializer, no hfsmc) that writes CLOCK_MONOTONIC in ns
  at ``--rate`` Hz to absolute deadlines once a reader is matched;
* ``bare-sub``: a plain reader on a WaitSet that takes each sample as it comes and notes
  ``monotonic_ns() - data``, written as one line a sample to ``--out`` at the end;
* ``feed``: publishes the topics of ``--spec`` (JSON: ``{"publish": {name: {topic, type,
  qos, rate}}, "subscribe": {...}}``) at their rates, through the runtime of a generated
  Python component folder (``--folder``: its message classes and ``hfsmc_ros2.py``), so
  the samples are ROS 2's bytes. A LaserScan has 360 rays at 3 m (an open room: a
  bump-and-go drives straight on), every other message its defaults. At the end it prints
  one JSON line: what it sent and what its subscriptions received.

Each stops after ``--seconds``. Both peers use the domain of ``$ROS_DOMAIN_ID`` and the
Cyclone settings of ``$CYCLONEDDS_URI``, as the components do.
"""

from __future__ import annotations

import argparse
import json
import math
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
from cyclonedds.idl.types import int64
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Int64_(IdlStruct, typename="std_msgs::msg::dds_::Int64_"):  # ROS 2's DDS name
    """std_msgs/msg/Int64 as a plain cyclonedds-python user declares it."""

    data: int64


def _domain() -> int:
    return int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)


def _bare_entities(topic: str) -> tuple[Any, Any, Any]:
    dp = DomainParticipant(_domain())
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
              Policy.Durability.Volatile, Policy.History.KeepLast(10),
              Policy.DataRepresentation(use_cdrv0_representation=True))
    return dp, Topic(dp, "rt/" + topic, Int64_), (Int64_, qos)


def bare_pub(topic: str, seconds: float, rate: float) -> int:
    dp, top, (kind, qos) = _bare_entities(topic)
    writer: Any = DataWriter(dp, top, qos=qos)  # the binding's status calls are untyped
    end = time.monotonic() + seconds
    while writer.get_publication_matched_status().current_count == 0:
        if time.monotonic() > end:
            print("bare-pub: no reader matched", file=sys.stderr)
            return 1
        time.sleep(0.01)
    period_ns = round(1e9 / rate)
    deadline = time.monotonic_ns()
    sent = 0
    while time.monotonic() < end:
        writer.write(kind(data=time.monotonic_ns()))
        sent += 1
        deadline += period_ns
        pause = deadline - time.monotonic_ns()
        if pause > 0:
            time.sleep(pause / 1e9)
    print(json.dumps({"sent": sent}), flush=True)
    return 0


def bare_sub(topic: str, seconds: float, out: Path) -> int:
    dp, top, (_kind, qos) = _bare_entities(topic)
    reader = DataReader(dp, top, qos=qos)
    ws = WaitSet(dp)
    ws.attach(ReadCondition(reader, SampleState.NotRead | ViewState.Any | InstanceState.Any))
    delays: list[int] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        ws.wait(duration(milliseconds=50))
        for s in reader.take(64):
            if isinstance(s, Int64_):  # not the writer's unregistration at its end
                delays.append(time.monotonic_ns() - s.data)
    out.write_text("".join(f"{d}\n" for d in delays), encoding="ascii")
    return 0


def _message(cls: Any) -> Any:
    if cls._TYPE == "sensor_msgs/msg/LaserScan":
        n = 360
        return cls(angle_min=-math.pi, angle_max=-math.pi + (n - 1) * 2 * math.pi / n,
                   angle_increment=2 * math.pi / n, range_min=0.05, range_max=8.0,
                   ranges=[3.0] * n)
    return cls()


def feed(folder: Path, spec: dict[str, Any], seconds: float) -> int:
    sys.path.insert(0, str(folder))
    import hfsmc_ros2  # type: ignore[import-not-found]  # the component folder's runtime

    pubs: dict[str, Any] = spec.get("publish", {})
    settings = {"node": "bench_feeder", "namespace": "/", "domain": None,
                "distro": spec.get("distro", "jazzy"),
                "subscribe": spec.get("subscribe", {}),
                "publish": {n: {k: v for k, v in s.items() if k != "rate"}
                            for n, s in pubs.items()}}
    node = hfsmc_ros2.connect("feeder", settings)
    msgs = {n: _message(node._pubs[n]["class"]) for n in pubs}
    # every topic on one 10 ms grid: a topic at R Hz goes out every 100 / R ticks
    every = {n: max(1, round(100 / float(s.get("rate", 10)))) for n, s in pubs.items()}
    sent = dict.fromkeys(pubs, 0)
    tick = 0
    deadline = time.monotonic_ns()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for n, k in every.items():
            if tick % k == 0:
                node.publish(n, msgs[n])
                sent[n] += 1
        tick += 1
        deadline += 10_000_000
        pause = deadline - time.monotonic_ns()
        if pause > 0:
            time.sleep(pause / 1e9)
    node.snapshot()
    received = {n: node.count(n) for n in spec.get("subscribe", {})}
    node.close()
    print(json.dumps({"sent": sent, "received": received}), flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=("bare-pub", "bare-sub", "feed"))
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--topic", default="bench_ping_bare")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--folder", type=Path)
    ap.add_argument("--spec", type=str, default="{}")
    ns = ap.parse_args(argv)
    if ns.mode == "bare-pub":
        return bare_pub(ns.topic, ns.seconds, ns.rate)
    if ns.mode == "bare-sub":
        if ns.out is None:
            ap.error("bare-sub needs --out")
        return bare_sub(ns.topic, ns.seconds, ns.out)
    if ns.folder is None:
        ap.error("feed needs --folder")
    return feed(ns.folder, json.loads(ns.spec), ns.seconds)


if __name__ == "__main__":
    sys.exit(main())
