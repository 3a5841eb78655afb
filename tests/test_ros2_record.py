"""A ros2 interface's topics in a recording (templates/python/hfsmc_record.py,
hfsmc_ros2.py): each sample's CDR on an MCAP channel named after the topic, with a
`ros2msg` schema, read as ROS 2 messages by the `mcap` library's ROS 2 decoder (as
Foxglove reads them); publishes as commands with their bytes; the recording read back by
hfsmc, turned into a playback script and fed to the ros2 fake, which answers with the
same messages, so the same snippet publishes the same bytes. Real DDS on loopback."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hfsmc.commands.replay import read_jsonl, write_playback
from hfsmc.emit.python import INTERFACE_FILES
from hfsmc.recording import read_recording
from hfsmc.ros2.definitions import DISTROS
from tests.ros2_support import build, ros2_domain
from tests.support import ROOT

RUNTIME = ROOT / "templates" / "python"
HERE = Path(__file__).resolve().parent / "ros2"
TYPES = ["sensor_msgs/msg/LaserScan", "geometry_msgs/msg/Twist",
         "rmw_dds_common/msg/ParticipantEntitiesInfo"]
FILES = (*INTERFACE_FILES["ros2"], "hfsmc_record.py", "hfsmc_playback.py")


@pytest.fixture(scope="module", params=DISTROS)
def recorded(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
             ) -> tuple[str, Path, Path]:
    """A recording made by the runtime: (distro, its folder, the .mcap)."""
    distro = str(request.param)
    out = tmp_path_factory.mktemp(f"ros2rec_{distro}")
    build(distro, TYPES, out)
    for name in FILES:
        shutil.copy(RUNTIME / name, out / name)
    shutil.copy(HERE / "record_peer.py", out / "record_peer.py")
    mcap = out / "run.mcap"
    with ros2_domain() as dom:
        done = subprocess.run([sys.executable, "record_peer.py", "record", distro, str(dom),
                               str(mcap)], cwd=out, capture_output=True, text=True,
                              timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    return distro, out, mcap


def _messages(mcap: Path) -> list[tuple[Any, Any, Any]]:
    from mcap.reader import make_reader

    with mcap.open("rb") as f:
        return list(make_reader(f).iter_messages())


def test_topics_decode_as_ros2_messages(recorded: tuple[str, Path, Path]) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    _, _, mcap = recorded
    with mcap.open("rb") as f:
        decoded: list[Any] = [
            (ch.topic, sch.name if sch else "", sch.encoding if sch else "",
             ch.message_encoding, m.log_time, msg)
            for sch, ch, m, msg in make_reader(f, decoder_factories=[DecoderFactory()])
            .iter_decoded_messages(topics=["/tb2/scan", "/tb2/cmd_vel"])]
    scans = [d for d in decoded if d[0] == "/tb2/scan"]
    cmds = [d for d in decoded if d[0] == "/tb2/cmd_vel"]
    assert {d[1:4] for d in scans} == {("sensor_msgs/msg/LaserScan", "ros2msg", "cdr")}
    assert {d[1:4] for d in cmds} == {("geometry_msgs/msg/Twist", "ros2msg", "cdr")}
    assert len(scans) >= 5, decoded
    for d in scans:  # as the sim sent them: ranges [k, k, k] for an even k, range_max 10
        r = list(d[5].ranges)
        assert len(r) == 3 and len(set(r)) == 1 and r[0] % 2 == 0 and d[5].range_max == 10.0
    firsts = [d[5].ranges[0] for d in scans]
    assert firsts == sorted(set(firsts))  # each sample once, when it entered a snapshot
    # each publish follows the scan of its instant: linear.x is that scan's first range
    by_time = {d[4]: d[5].ranges[0] for d in scans}
    latest = None
    for d in sorted(scans + cmds, key=lambda d: (d[4], d[0] == "/tb2/cmd_vel")):
        if d[0] == "/tb2/scan":
            latest = by_time[d[4]]
        else:
            assert d[5].linear.x == latest
    assert len(cmds) >= len(scans)


def test_snapshots_and_commands_on_their_json_channels(recorded: tuple[str, Path, Path]) -> None:
    _, _, mcap = recorded
    msgs = _messages(mcap)
    snaps = [json.loads(m.data) for _, ch, m in msgs if ch.topic == "/hfsmc/interface/robot"]
    assert len(snaps) == 40
    assert {s["t"] for s in snaps} == {k * 50_000 for k in range(40)}
    last = snaps[-1]["subscriptions"]["scan"]
    assert set(last) == {"count", "age", "publishers", "dropped"}  # the bytes are elsewhere
    assert last["count"] >= 5 and last["publishers"] == 1 and last["dropped"] == 0
    assert snaps[0]["subscribers"] == {"cmd_vel": 0}
    cmds = [(m.log_time, json.loads(m.data)) for _, ch, m in msgs
            if ch.topic == "/hfsmc/command/robot"]
    wire = {m.log_time: m.data for _, ch, m in msgs if ch.topic == "/tb2/cmd_vel"}
    assert cmds and len(cmds) == len(wire)
    for at, c in cmds:
        assert c["call"] == "publish" and c["args"][0] == "cmd_vel"
        assert base64.b64decode(c["args"][1]) == wire[at]  # the same bytes as sent
    meta = {ch.topic: dict(ch.metadata) for _, ch, _ in msgs}
    assert meta["/tb2/scan"] == {"hfsmc.interface": "robot", "hfsmc.subscription": "scan"}
    assert meta["/tb2/cmd_vel"] == {"hfsmc.interface": "robot", "hfsmc.publication": "cmd_vel"}


def test_played_back_the_fake_publishes_the_same_bytes(recorded: tuple[str, Path, Path],
                                                       tmp_path: Path) -> None:
    _, out, mcap = recorded
    rec = read_recording(mcap)
    assert {(t.role, t.name, t.topic, t.type) for t in rec.topics} == {
        ("subscription", "scan", "/tb2/scan", "sensor_msgs/msg/LaserScan"),
        ("publication", "cmd_vel", "/tb2/cmd_vel", "geometry_msgs/msg/Twist")}
    assert rec.samples and all(s.data[:4] == b"\x00\x01\x00\x00" for s in rec.samples)
    write_playback(rec, tmp_path)
    done = subprocess.run([sys.executable, "record_peer.py", "play", "-", str(tmp_path)],
                          cwd=out, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[-1]) == {"unanswered": None}
    now = [(c["t"], c["interface"], c["call"], c["args"])
           for c in read_jsonl(tmp_path / "commands.jsonl")]
    then = [(c.t, c.interface, c.call, list(c.args)) for c in rec.commands]
    assert now == then and len(now) >= 5


def test_a_sample_the_recording_lacks_is_no_evidence(recorded: tuple[str, Path, Path],
                                                     tmp_path: Path) -> None:
    """The recording's first scan left out (as a cut might): the snippet that reads it is
    told nothing, and the first such query is noted."""
    _, out, mcap = recorded
    rec = read_recording(mcap)
    first = next(s for s in rec.samples if rec.topics[s.topic].role == "subscription")
    import dataclasses

    rec = dataclasses.replace(rec, samples=tuple(s for s in rec.samples if s is not first))
    write_playback(rec, tmp_path)
    done = subprocess.run([sys.executable, "record_peer.py", "play", "-", str(tmp_path)],
                          cwd=out, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    asked = json.loads(done.stdout.splitlines()[-1])["unanswered"]
    assert asked == {"t": first.t, "interface": "robot", "query": "scan", "reason": "scan"}


def _hfsmc(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hfsmc", *args], capture_output=True,
                          text=True, timeout=120, check=False)


def test_export_rosbag_reads_back_with_rosbags(recorded: tuple[str, Path, Path],
                                               tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    distro, _, mcap = recorded
    bag = tmp_path / "bag"
    bag.mkdir()  # an empty folder is fine
    done = _hfsmc("export", "rosbag", str(mcap), str(bag))
    assert done.returncode == 0, done.stderr
    assert "2 topics" in done.stdout and "/tb2/scan (sensor_msgs/msg/LaserScan)" in done.stdout
    rec = read_recording(mcap)
    want = sorted((rec.topics[s.topic].topic, rec.start_ns + s.t * 1000, s.data)
                  for s in rec.samples)
    store = get_typestore(Stores.ROS2_JAZZY if distro == "jazzy" else Stores.ROS2_HUMBLE)
    with Reader(bag) as reader:
        assert "storage_identifier: mcap" in (bag / "metadata.yaml").read_text()
        types = {c.topic: c.msgtype for c in reader.connections}
        got = sorted((c.topic, ts, bytes(raw)) for c, ts, raw in reader.messages())
        hashes = {c.topic: c.digest for c in reader.connections}
    assert types == {"/tb2/scan": "sensor_msgs/msg/LaserScan",
                     "/tb2/cmd_vel": "geometry_msgs/msg/Twist"}
    assert got == want  # the same messages, byte for byte, at the same times
    assert hashes["/tb2/cmd_vel"] == store.hash_rihs01("geometry_msgs/msg/Twist")
    for topic, _, raw in got:  # and they decode, with the distro's own definitions
        msg: Any = store.deserialize_cdr(raw, types[topic])
        if topic == "/tb2/scan":
            assert len(msg.ranges) == 3


def _rewrite(src: Path, dst: Path, change: Any) -> None:
    """A copy of a recording with each message's bytes passed through ``change``."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with src.open("rb") as f, dst.open("wb") as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        w = Writer(out)
        w.start()
        for meta in reader.iter_metadata():
            w.add_metadata(meta.name, meta.metadata)
        for s in summary.schemas.values():
            w.register_schema(s.name, s.encoding, s.data)  # ids 1.. in the same order
        for c in summary.channels.values():
            w.register_channel(c.topic, c.message_encoding, c.schema_id, c.metadata)
        for _, ch, m in reader.iter_messages():
            w.add_message(ch.id, m.log_time, change(ch.topic, m.data), m.publish_time)
        w.finish()  # type: ignore[no-untyped-call]


def test_export_refuses_and_says_why_in_one_line(recorded: tuple[str, Path, Path],
                                                 tmp_path: Path) -> None:
    _, _, mcap = recorded
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    done = _hfsmc("export", "rosbag", str(mcap), str(full))
    assert done.returncode == 1 and (full / "keep.txt").read_text() == "mine"
    assert done.stderr == f"hfsmc export: {full} is not empty (an export writes a new " \
                          "rosbag folder, never into another's)\n"
    bad = tmp_path / "bad.mcap"
    first: list[bytes] = []

    def garble(topic: str, data: bytes) -> bytes:
        if topic == "/tb2/scan" and not first:
            first.append(data)
            return data[:9]  # cut short: no LaserScan
        return data

    _rewrite(mcap, bad, garble)
    done = _hfsmc("export", "rosbag", str(bad), str(tmp_path / "out"))
    assert done.returncode == 1 and not (tmp_path / "out").exists()
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("hfsmc export: a /tb2/scan sample at "), lines
    assert "is no sensor_msgs/msg/LaserScan" in lines[0] and "Traceback" not in done.stderr
    none = tmp_path / "none.mcap"  # a recording of the same run with no topic
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with mcap.open("rb") as f, none.open("wb") as out:
        reader = make_reader(f)
        w = Writer(out)
        w.start()
        for m in reader.iter_metadata():
            w.add_metadata(m.name, m.metadata)
        s = w.register_schema("hfsmc.TraceRecord", "jsonschema", b"{}")
        c = w.register_channel("/hfsmc/trace", "json", s)
        w.add_message(c, int(read_recording(mcap).start_ns), b'{"t":0,"ev":"start"}', 0)
        w.finish()  # type: ignore[no-untyped-call]
    done = _hfsmc("export", "rosbag", str(none), str(tmp_path / "out"))
    assert done.returncode == 1 and done.stderr.startswith("hfsmc export: it holds no ROS 2 topic")
