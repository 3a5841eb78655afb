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
from hfsmc.recording import read_recording
from hfsmc.ros2.definitions import DISTROS
from tests.ros2_support import build, ros2_domain
from tests.support import ROOT

RUNTIME = ROOT / "templates" / "python"
HERE = Path(__file__).resolve().parent / "ros2"
TYPES = ["sensor_msgs/msg/LaserScan", "geometry_msgs/msg/Twist",
         "rmw_dds_common/msg/ParticipantEntitiesInfo"]
FILES = ("hfsmc_ros2.py", "hfsmc_ros2_wire.py", "hfsmc_ros2_playback.py", "hfsmc_record.py",
         "hfsmc_playback.py")


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
        decoded = [(ch.topic, sch.name, sch.encoding, ch.message_encoding, m.log_time, msg)
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
