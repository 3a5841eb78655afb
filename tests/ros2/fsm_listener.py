# mypy: ignore-errors
# (it imports the runtime and the messages generated beside it, which mypy cannot see)
"""A plain Cyclone DDS reader of what ``introspection: true`` publishes, for
tests/test_ros2_introspection.py: run from a component folder (its runtime and message
packages). It keeps the raw CDR of every sample (no decoding: the test decodes with
rosbags).

usage: fsm_listener.py DOMAIN STATUS_TOPIC SECONDS
Prints {"ready": true}, then one JSON line per sample, {"topic", "cdr" (hex)}; stops after
SECONDS, or a second after the first status whose component has stopped."""

from __future__ import annotations

import json
import sys
import time

import hfsmc_ros2_wire as wire
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

domain, status_topic, seconds = int(sys.argv[1]), sys.argv[2], float(sys.argv[3])
dp = DomainParticipant(domain)
readers = {}
for topic, type_name in (("/fsm_viewer", "yasmin_msgs/msg/StateMachine"),
                         (status_topic, "std_msgs/msg/String")):
    kind = wire.dds_type(wire.message_class(type_name))
    readers[topic] = DataReader(dp, Topic(dp, "rt" + topic, kind),
                                qos=wire.dds_qos(("reliable", "volatile", 1000)))
print(json.dumps({"ready": True}), flush=True)
end = time.monotonic() + seconds
stopped = False
while time.monotonic() < end:
    for topic, reader in readers.items():
        for sample in reader.take(100):
            raw = sample.__dict__.get("raw")
            if raw is None:
                continue
            print(json.dumps({"topic": topic, "cdr": bytes(raw).hex()}), flush=True)
            if not stopped and topic == status_topic and b'"stop":{' in bytes(raw):
                # the last status; the other topic's last samples come from another writer,
                # with no order between the two: read on a moment for them
                stopped = True
                end = min(end, time.monotonic() + 1.0)
    time.sleep(0.01)
