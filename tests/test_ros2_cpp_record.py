"""A C++ component's `--record` of a ros2 interface is a Python one's (docs/ros2.md,
"Recordings, replay and rosbags"): the Python and the C++ twin of tests/ros2/models/pingpong
talk to each other over real DDS (loopback, a leased domain), both recording; the two
recordings have the same channels (topics, schemas, encodings, metadata), the same JSON
snapshot and settings layout and the same publish commands; the C++ one's topics decode
with mcap-ros2-support; each replays identical with the other twin."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.cppbuild import Superbuild
from tests.ros2_support import ros2_domain
from tests.support import ROOT, hfsmc
from tests.test_ros2_cpp_component import ENV, crossed

MODELS = ROOT / "tests" / "ros2" / "models"
PY_MODEL = MODELS / "pingpong" / "pingpong.yaml"
CPP_MODEL = MODELS / "pingpong_cpp" / "pingpong_cpp.yaml"


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The twins run against each other, each with --record: language -> its recording."""
    tmp = tmp_path_factory.mktemp("ros2cpprec")
    sb = Superbuild(tmp / "build", [CPP_MODEL], build_type="Release")
    sb.build()
    built = hfsmc("build", str(PY_MODEL), "-o", str(tmp / "py"))
    assert built.returncode == 0, built.stderr
    out = {"cpp": tmp / "cpp.mcap", "python": tmp / "py.mcap"}
    with ros2_domain() as dom:
        cpp_config = crossed(sb.folder(CPP_MODEL) / "pingpong_cpp.yaml", "a", "b", dom)
        py_config = crossed(tmp / "py" / "pingpong.yaml", "b", "a", dom)
        cpp = subprocess.Popen([str(sb.executable(CPP_MODEL)), "--config", str(cpp_config),
                                "--until", "30s", "--record", str(out["cpp"])],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=ENV)
        try:
            py = subprocess.run([sys.executable, str(tmp / "py" / "pingpong.py"), "--config",
                                 str(py_config), "--until", "30s", "--record", str(out["python"])],
                                capture_output=True, text=True, timeout=60, env=ENV)
            _, cpp_err = cpp.communicate(timeout=60)
        finally:
            if cpp.poll() is None:
                cpp.kill()
                cpp.communicate()
    assert cpp.returncode == 0 and "stopped (final)" in cpp_err, cpp_err
    assert py.returncode == 0 and "stopped (final)" in py.stderr, py.stderr
    return out


def _read(path: Path) -> tuple[list[dict[str, Any]], dict[str, dict[str, str]], list[Any]]:
    """The channels (with their schemas and message counts), the metadata, the messages."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = summary.statistics.channel_message_counts
        channels = []
        for ch in summary.channels.values():
            sc = summary.schemas.get(ch.schema_id)
            channels.append({"topic": ch.topic, "encoding": ch.message_encoding,
                             "metadata": dict(ch.metadata), "count": counts.get(ch.id, 0),
                             "schema": sc and (sc.name, sc.encoding, sc.data)})
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        messages = [(ch.topic, m.log_time, m.data) for _, ch, m in reader.iter_messages()]
    return channels, metadata, messages


def _shape(value: Any) -> Any:
    """A JSON value's keys and kinds, not its numbers."""
    if isinstance(value, dict):
        return {k: _shape(v) for k, v in value.items()}
    return "float" if value == "inf" else type(value).__name__  # an age: seconds or "inf"


def test_the_cpp_recording_has_the_python_layout(recordings: dict[str, Path]) -> None:
    got = {lang: _read(path) for lang, path in recordings.items()}
    own = {lang: [c for c in chans if c["encoding"] != "json"] for lang, (chans, _, _) in got.items()}
    # One cdr channel per subscription and per publication, named after the resolved topic,
    # the ros2msg schema of std_msgs/msg/Int32, whose it is in the metadata. The twins' topics
    # are crossed: the C++ one publishes what the Python one reads.
    for lang in got:
        roles = {c["metadata"].get("hfsmc.subscription") or c["metadata"]["hfsmc.publication"]
                 for c in own[lang]}
        assert roles == {"inbox", "outbox"}, own[lang]

    def key(c: dict[str, Any]) -> tuple[Any, ...]:
        return (c["encoding"], c["schema"], tuple(sorted(c["metadata"].items())))
    assert sorted(map(key, own["cpp"])) == sorted(map(key, own["python"]))
    topics = {lang: {c["metadata"].get("hfsmc.subscription") or c["metadata"]["hfsmc.publication"]:
                     c["topic"] for c in own[lang]} for lang in got}
    assert topics["cpp"] == {"outbox": "/a_to_b", "inbox": "/b_to_a"}
    assert topics["python"] == {"outbox": "/b_to_a", "inbox": "/a_to_b"}
    # The JSON channels: the same names, schemas (the same text) and encodings.
    json_ch = {lang: {c["topic"]: c["schema"] for c in chans if c["encoding"] == "json"}
               for lang, (chans, _, _) in got.items()}
    for topic in ("/hfsmc/interface/link", "/hfsmc/command/link"):
        assert json_ch["cpp"][topic][:2] == json_ch["python"][topic][:2]
    assert json_ch["cpp"]["/hfsmc/interface/link"] == json_ch["python"]["/hfsmc/interface/link"]
    # The settings and each snapshot: the same keys and kinds.
    settings = {lang: json.loads(meta["hfsmc.interfaces"]["link"]) for lang, (_, meta, _) in got.items()}
    # Python's also carry what C++ components have not yet (actions, services, introspection:
    # docs/ros2.md): the rest is alike.
    extra = set(settings["python"]["options"]) - set(settings["cpp"]["options"])
    assert extra <= {"actions", "services", "introspection"}, extra
    for key in extra:
        del settings["python"]["options"][key]
    assert _shape(settings["cpp"]) == _shape(settings["python"])
    assert settings["cpp"]["options"]["subscribe"]["inbox"] == {
        "topic": "b_to_a", "type": "std_msgs/msg/Int32", "qos": "default"}
    snaps = {lang: [json.loads(d) for t, _, d in msgs if t == "/hfsmc/interface/link"]
             for lang, (_, _, msgs) in got.items()}
    assert {json.dumps(_shape(s)) for s in snaps["cpp"][1:]} == \
        {json.dumps(_shape(s)) for s in snaps["python"][1:]}
    # A publish: a command with its CDR in base64, and the same bytes on its channel.
    _, _, msgs = got["cpp"]
    commands = [json.loads(d) for t, _, d in msgs if t == "/hfsmc/command/link"]
    sent = [d for t, _, d in msgs if t == "/a_to_b"]
    import base64

    assert [c["call"] for c in commands] == ["publish"] * len(sent)
    assert [base64.b64decode(c["args"][1]) for c in commands] == sent
    # A sample is written once, at the instant it entered the snapshot (a new count).
    counts = [s["subscriptions"]["inbox"]["count"] for s in snaps["cpp"]]
    assert len([t for t, _, _ in msgs if t == "/b_to_a"]) == len(set(counts) - {0})


def test_the_cpp_recordings_topics_decode_as_ros2_messages(recordings: dict[str, Path]) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with recordings["cpp"].open("rb") as f:
        decoded: dict[str, list[int]] = {}
        for _, ch, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages(topics=["/a_to_b", "/b_to_a"]):
            decoded.setdefault(ch.topic, []).append(msg.data)
    # What it published: how many numbers it had read, each instant (0, 0, 1, 2, 2, ...).
    sent = decoded["/a_to_b"]
    assert sent == sorted(sent) and sorted(set(sent)) == list(range(sent[-1] + 1)), sent
    # What it read: the other side's counts, again until it moved on; each new one in order.
    read = decoded["/b_to_a"]
    assert [v for i, v in enumerate(read) if i == 0 or v != read[i - 1]][:5] == [0, 1, 2, 3, 4]


@pytest.mark.parametrize(("recorded", "model", "label"), [
    ("cpp", PY_MODEL, "(cpp -> python)"),
    ("python", CPP_MODEL, "(python -> cpp)"),
    ("cpp", CPP_MODEL, "(cpp -> cpp)"),
])
def test_each_recording_replays_identical_in_both_languages(
        recordings: dict[str, Path], recorded: str, model: Path, label: str) -> None:
    done = hfsmc("replay", str(recordings[recorded]), "--model", str(model), timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"{label}: identical:" in done.stdout, done.stdout


def test_a_cpp_replay_of_a_changed_model_finds_the_other_bytes(
        recordings: dict[str, Path], tmp_path: Path) -> None:
    model = tmp_path / "pingpong_cpp.yaml"
    text = CPP_MODEL.read_text()
    assert "m.data = static_cast<int32_t>(got);" in text
    model.write_text(text.replace("m.data = static_cast<int32_t>(got);",
                                  "m.data = static_cast<int32_t>(got + 1);"))
    done = hfsmc("replay", str(recordings["python"]), "--model", str(model), timeout=600)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "different" in done.stdout and "(command 1):" in done.stdout, done.stdout
