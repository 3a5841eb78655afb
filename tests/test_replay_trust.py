"""A recording is data (docs/recording.md, "Trust"): replaying one never builds or runs the
code it carries unless asked, its model hash and paths are checked, what it makes hfsmc hold
is bounded, and a what-if replay never takes a query the recording cannot answer for
evidence.

Forged recordings are made here with the real `mcap` writer (or, for what no writer would
write, record by record as the MCAP specification lays them out) from the hop model's
recording of tests/test_replay.py."""

from __future__ import annotations

import hashlib
import io
import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import zstandard
from mcap.reader import NonSeekingReader
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from hfsmc.commands.scenario_run import find_scenarios
from hfsmc.recording import MAX_DEPTH, sources_hash
from tests import test_replay
from tests.test_replay import ALLOW, HOP, hfsmc

hop = test_replay.hop  # the fixture: hop.yaml and its run recorded, as test_replay makes them

# A snippet that writes a file: what a forged recording would run, were it run.
PWNED = "pwned.txt"


def read_all(path: Path) -> tuple[dict[str, dict[str, str]], list[tuple[str, int, bytes]]]:
    """A recording's metadata and messages (topic, log time, data)."""
    meta: dict[str, dict[str, str]] = {}
    with path.open("rb") as f:
        for rec in StreamReader(f).records:
            if type(rec).__name__ == "Metadata":
                meta[rec.name] = dict(rec.metadata)  # type: ignore[attr-defined]
    with path.open("rb") as f:
        msgs = [(ch.topic, m.log_time, m.data) for _, ch, m in
                NonSeekingReader(f).iter_messages(log_time_order=False)]
    return meta, msgs


def write_mcap(path: Path, meta: dict[str, dict[str, str]], msgs: list[tuple[str, int, bytes]],
               compression: CompressionType = CompressionType.NONE, raw: bytes = b"") -> None:
    """A recording with these metadata and messages; ``raw`` (records as bytes) goes after
    the messages, before the file is closed."""
    with path.open("wb") as f:
        w = Writer(f, compression=compression, use_chunking=compression != CompressionType.NONE)
        w.start()
        for name, values in meta.items():
            w.add_metadata(name, values)
        schema = w.register_schema("hfsmc", "jsonschema", b"{}")
        channels: dict[str, int] = {}
        for topic, t, data in msgs:
            if topic not in channels:
                channels[topic] = w.register_channel(topic, "json", schema)
            w.add_message(channels[topic], t, data, t)
        f.flush()
        f.write(raw)
        w.finish()  # type: ignore[no-untyped-call]


def forged(hop: Path, name: str, sources: dict[str, str] | None = None,
           run: dict[str, str] | None = None, rehash: bool = True,
           msgs: list[tuple[str, int, bytes]] | None = None) -> Path:
    """hop.mcap with other sources (their hash recomputed unless told not to), other run
    metadata or other messages."""
    meta, recorded = read_all(hop / "hop.mcap")
    if sources is not None:
        meta["hfsmc.sources"] = sources
        if rehash:
            meta["hfsmc.run"]["model_hash"] = sources_hash(tuple(sources.items()))
    meta["hfsmc.run"].update(run or {})
    path = hop / name
    write_mcap(path, meta, recorded if msgs is None else msgs)
    return path


def files_below(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def evil(target: Path) -> str:
    """The hop model whose first state writes ``target`` on entry."""
    return HOP.replace("  Wait:\n", f"  Wait:\n    entry: \"open({str(target)!r}, 'w').write('x')\"\n")


# --- the gate ------------------------------------------------------------------------------

def test_a_recording_is_not_run_without_being_asked(hop: Path) -> None:
    r = hfsmc("replay", "hop.mcap", cwd=hop)
    assert r.returncode == 1
    digest = sources_hash((("hop.yaml", HOP),))
    assert r.stdout.splitlines() == [
        "hop.mcap holds a run of the python component `hop` (hfsmc "
        f"{r.stdout.split('(hfsmc ')[1].split(')')[0]}), 0-1.000 s, and the model it ran:",
        f"  hop.yaml ({len(HOP)} bytes, {len(HOP.splitlines())} lines)",
        f"  hash {digest} (recomputed from these files: the recorded hash)",
        "A model is code: replaying builds and runs it. Replay the run with your model:",
        "  hfsmc replay hop.mcap --model PATH/hop.yaml",
        "or, for a recording you trust, build and run the code it carries:",
        f"  hfsmc replay hop.mcap {ALLOW}"]
    assert r.stderr == ("hfsmc replay: not run: a recording's model is code, built and run "
                        "only when asked (--model MODEL or --allow-recorded-code)\n")
    assert not (hop / "cache" / "hfsmc" / "replay").exists()


def test_a_forged_recording_runs_only_with_allow_recorded_code(hop: Path, tmp_path: Path) -> None:
    """Its sources write a file when run: not by a plain replay, not with --model (the user's
    model runs), not by `hfsmc test` (the model beside it runs); with the flag, it does (the
    gate is what stops it)."""
    target = tmp_path / PWNED
    path = forged(hop, "evil.mcap", sources={"hop.yaml": evil(target)})
    r = hfsmc("replay", path.name, cwd=hop)
    assert r.returncode == 1 and not target.exists(), r.stderr
    r = hfsmc("replay", path.name, "--model", "hop.yaml", cwd=hop)
    assert r.returncode == 0 and not target.exists(), r.stdout + r.stderr
    assert r.stdout.startswith("hop.yaml is not the recorded model (changed: hop.yaml;")
    r = hfsmc("test", path.name, cwd=hop)  # with hop.yaml, beside it
    assert r.returncode == 0 and not target.exists(), r.stdout + r.stderr
    assert r.stdout.startswith("evil.mcap::python PASSED\n"), r.stdout
    r = hfsmc("replay", path.name, ALLOW, cwd=hop)
    assert target.read_text() == "x", r.stdout + r.stderr


@pytest.mark.parametrize(("change", "said"), [
    ({"model_hash": "sha256:../../../../project"}, "its model hash `sha256:../../../../project` "
                                                   "is not sha256: and 64 hex digits"),
    ({"model_hash": "sha256:" + "0" * 64}, "its model hash is not the hash of the model sources "
                                            "it holds (the sources or the hash were changed)"),
    ({"model_hash": ""}, "its model hash `` is not sha256: and 64 hex digits"),
])
def test_a_forged_model_hash_is_refused_and_nothing_is_written(hop: Path, tmp_path: Path,
                                                                 change: dict[str, str],
                                                                 said: str) -> None:
    path = forged(hop, "hash.mcap", run=change)
    before = files_below(hop)
    for args in ([], [ALLOW], ["--model", "hop.yaml"]):
        r = hfsmc("replay", path.name, *args, cwd=hop)
        assert (r.returncode, r.stdout, r.stderr) == (1, "", f"hash.mcap: corrupted: {said}\n")
    assert files_below(hop) == before  # no cache folder, no Makefile, nothing


@pytest.mark.parametrize(("sources", "said"), [
    ({"hop.yaml": HOP, "/etc/hfsmc.yaml": "x"}, "a model source's path `/etc/hfsmc.yaml`"),
    ({"../../hop.yaml": HOP}, "the model file `../../hop.yaml` is not a file name"),
    ({"hop.yaml": HOP, "lib/..": "x"}, "a model source's path `lib/..`"),
    ({"hop.yaml": HOP, "a\\..\\b.yaml": "x"}, "a model source's path `a\\\\..\\\\b.yaml`"),
])
def test_forged_source_paths_are_refused(hop: Path, sources: dict[str, str], said: str) -> None:
    path = forged(hop, "paths.mcap", sources=sources)
    r = hfsmc("replay", path.name, ALLOW, cwd=hop)
    assert (r.returncode, r.stdout) == (1, ""), r.stderr
    assert r.stderr.startswith(f"paths.mcap: corrupted: {said}"), r.stderr


def test_used_files_that_climb_are_read_from_the_recording_only(hop: Path, tmp_path: Path) -> None:
    """A used file at `../../../x/evil.yaml`: the recorded model is compiled in memory, so
    nothing is written at that path (nor read from it), even when the recorded code runs."""
    used = "hfsm: 1\nname: part\nlanguage: python\ninitial: A\nstates:\n  A: {final: true}\n"
    climbing = "../../../x/evil.yaml"
    model = HOP.replace("  Done: {final: true}", f"  Done:\n    use: {climbing}")
    outside = (hop / climbing).resolve()
    path = forged(hop, "climb.mcap", sources={"hop.yaml": model, climbing: used})
    r = hfsmc("replay", path.name, ALLOW, cwd=hop)
    assert r.returncode == 1, r.stdout + r.stderr  # it differs (Done is no longer final)
    assert r.stdout.startswith("replay of climb.mcap (python -> python): different"), r.stdout
    assert not outside.exists() and not outside.parent.exists()
    cache = hop / "cache" / "hfsmc" / "replay"
    assert {p.name for p in cache.iterdir()} >= {sources_hash(
        (("hop.yaml", model), (climbing, used))).removeprefix("sha256:")[:16]}
    written = [p.read_text("utf-8", "replace") for p in cache.rglob("*") if p.is_file()]
    assert model not in written and used not in written  # the component only: no source


def test_a_link_in_the_cache_cannot_send_the_build_elsewhere(hop: Path, tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    folder = hop / "linked"
    folder.mkdir()
    (folder / "hop.mcap").write_bytes((hop / "hop.mcap").read_bytes())
    digest = sources_hash((("hop.yaml", HOP),)).removeprefix("sha256:")[:16]
    cache = folder / "cache" / "hfsmc" / "replay"
    cache.mkdir(parents=True)
    (cache / digest).symlink_to(outside)
    r = hfsmc("replay", "hop.mcap", ALLOW, cwd=folder)
    assert (r.returncode, r.stdout) == (1, ""), r.stderr
    assert r.stderr.startswith(f"hop.mcap: the replay cache folder {cache / digest}/python leads "
                               f"out of {cache} (a symbolic link?): not built"), r.stderr
    assert list(outside.iterdir()) == []


# --- bounds and corruption -----------------------------------------------------------------

def _chunk(records: bytes, claimed: int, compressed: bytes) -> bytes:
    """An MCAP Chunk record (opcode 0x06) holding ``compressed`` (zstd), which says it
    inflates to ``claimed`` bytes."""
    body = (struct.pack("<QQQI", 0, 0, claimed, 0) + struct.pack("<I", 4) + b"zstd"
            + struct.pack("<Q", len(compressed)) + compressed)
    return b"\x06" + struct.pack("<Q", len(body)) + body


def _zeros_message(channel: int, size: int) -> bytes:
    """A Message record (opcode 0x05) of ``size`` zero bytes, zstd-compressed as it streams
    (the test never holds it whole)."""
    head = struct.pack("<HIQQ", channel, 0, 0, 0)
    out = io.BytesIO()
    with zstandard.ZstdCompressor().stream_writer(out, closefd=False) as w:
        w.write(b"\x05" + struct.pack("<Q", len(head) + size) + head)
        block = bytes(1 << 20)
        for _ in range(size >> 20):
            w.write(block)
    return out.getvalue()


def test_chunks_that_would_inflate_past_the_bound_are_refused(hop: Path) -> None:
    """300 MB of zeros in a 10 kB chunk: refused before inflating it when the chunk says
    so; read no further than it says when it lies."""
    meta, msgs = read_all(hop / "hop.mcap")
    size = 300 << 20
    bomb = _zeros_message(1, size)
    assert len(bomb) < 100_000
    for name, claimed, said in [
            ("bomb.mcap", size + 27, f"too large: a chunk would inflate to {size + 27} bytes "
                                     "(hfsmc reads chunks of 64 MiB at most)"),
            ("liar.mcap", 1000, "corrupted: a chunk inflates to more bytes than the 1000 it says")]:
        write_mcap(hop / name, meta, msgs[:1], raw=_chunk(b"", claimed, bomb))
        r = hfsmc("replay", name, ALLOW, cwd=hop)
        assert (r.returncode, r.stdout) == (1, ""), r.stderr
        assert r.stderr.startswith(f"{name}: {said}") and len(r.stderr.splitlines()) == 1, r.stderr


def test_a_compressed_recording_replays(hop: Path) -> None:
    """Chunks are read (bounded): a recording saved compressed by another tool replays."""
    meta, msgs = read_all(hop / "hop.mcap")
    for kind, name in ((CompressionType.ZSTD, "zstd.mcap"), (CompressionType.LZ4, "lz4.mcap")):
        write_mcap(hop / name, meta, msgs, compression=kind)
        r = hfsmc("replay", name, "--model", "hop.yaml", cwd=hop)
        assert r.returncode == 0, r.stdout + r.stderr


def _message(topic: str, body: str, at_ns: int | None = None) -> tuple[str, int, bytes]:
    return topic, at_ns or 0, body.encode()


def test_every_corruption_is_one_line_and_exit_1(hop: Path) -> None:
    meta, msgs = read_all(hop / "hop.mcap")
    start = int(meta["hfsmc.run"]["start_unix_ns"])
    data = (hop / "hop.mcap").read_bytes()
    deep = "[" * 100_000 + "]" * 100_000
    nested = "[" * (MAX_DEPTH + 2) + "]" * (MAX_DEPTH + 2)
    cases: dict[str, tuple[Any, str]] = {
        "magic.mcap": (b"\x89MCAX0\r\n" + data[8:], "not an MCAP file"),
        "short.mcap": (data[:5], "the recording ends before its metadata (cut at the start"),
        "deep_trace.mcap": ([*msgs, _message("/hfsmc/trace", '{"t":1,"ev":"log","msg":' + deep
                                             + "}", start)],
                            "corrupted: a /hfsmc/trace message nests too deeply"),
        "nested.mcap": ([*msgs, _message("/hfsmc/interface/drone", '{"t":0,"x":' + nested + "}",
                                         start)],
                        "corrupted: a /hfsmc/interface/drone message nests too deeply"),
        "schema.mcap": ([*msgs, _message("/hfsmc/command/drone", '{"t":5,"args":[]}', start)],
                        "corrupted: a /hfsmc/command/drone message at 0.000 s lacks or garbles "
                        "'call'"),
        "count.mcap": ([*msgs, _message("/hfsmc/frame/camera",
                                        '{"count":-5,"data":""}', start)],
                       "corrupted: a /hfsmc/frame/camera message at 0.000 s lacks or garbles a "
                       "whole number from 0 to"),
        "huge.mcap": ([*msgs, _message("/hfsmc/interface/drone",
                                       '{"t":0,"battery":' + "9" * 40 + "}", start)],
                      "corrupted: a /hfsmc/interface/drone message holds a whole number out of "
                      "range"),
        "time.mcap": ([*msgs, _message("/hfsmc/skip",
                                       '{"t":-1,"automaton":"","deadline":0,"missed":0}', start)],
                      "corrupted: a /hfsmc/skip message at 0.000 s lacks or garbles a whole "
                      "number"),
        "before.mcap": ([*msgs, _message("/hfsmc/trace", '{"t":0,"ev":"x"}', 5)],
                        "corrupted: a /hfsmc/trace message logged at 5 ns, before the run's "
                        "start or too late"),
        "name.mcap": ([*msgs, _message("/hfsmc/frame/..", '{"count":1,"data":""}', start)],
                      "corrupted: interface name `..` is not a name"),
        "big.mcap": ([*msgs, _message("/hfsmc/trace", '{"t":0,"msg":"' + "x" * (2 << 20) + '"}',
                                      start)],
                     f"corrupted: a /hfsmc/trace message of {(2 << 20) + 16} bytes (at most "
                     "1048576 are read)"),
        "format.mcap": ([*msgs, _message("/hfsmc/frame/camera",
                                         '{"count":1,"data":"","format":"gif"}', start)],
                        "corrupted: a /hfsmc/frame/camera message at 0.000 s lacks or garbles the "
                        "frame format (png or jpeg, not `gif`)"),
    }
    for name, (content, said) in cases.items():
        if isinstance(content, bytes):
            (hop / name).write_bytes(content)
        else:
            write_mcap(hop / name, meta, content)
        r = hfsmc("replay", name, ALLOW, cwd=hop)
        assert (r.returncode, r.stdout) == (1, ""), (name, r.stdout, r.stderr)
        assert r.stderr.startswith(f"{name}: {said}"), (name, r.stderr)
        assert len(r.stderr.splitlines()) == 1 and "Traceback" not in r.stderr, r.stderr
    # Metadata nested too deeply, or not JSON.
    for name, value, said in [("param.mcap", deep, "nests too deeply"),
                              ("paramjson.mcap", "{", "is not JSON")]:
        bad = {**meta, "hfsmc.parameters": {"height": value}}
        write_mcap(hop / name, bad, msgs)
        r = hfsmc("replay", name, ALLOW, cwd=hop)
        assert (r.returncode, r.stderr) == (1, f"{name}: corrupted: the metadata of parameter "
                                               f"`height` {said}\n")
    # A message of a channel never declared (written record by record).
    record = struct.pack("<HIQQ", 7, 0, start, start) + b"{}"
    raw = b"\x05" + struct.pack("<Q", len(record)) + record
    write_mcap(hop / "orphan.mcap", meta, msgs, raw=raw)
    r = hfsmc("replay", "orphan.mcap", ALLOW, cwd=hop)
    assert (r.returncode, r.stderr) == (1, "orphan.mcap: corrupted: a message of channel 7, "
                                           "which was never declared\n")


SCENARIO = """\
model: hop.yaml
until: 3s
inputs:
  drone:
    - {at: 0s, connected: true, altitude: 0}
    - {at: 0.3s, ready: true}
    - {at: 1s, altitude: 2.5}
expect:
  - entered: Done
  - stop: final
"""


def test_hfsmc_test_reports_a_bad_recording_and_runs_the_others(hop: Path) -> None:
    (hop / "tests").mkdir(exist_ok=True)
    (hop / "tests" / "climb.yaml").write_text(SCENARIO.replace("model: hop.yaml",
                                                               "model: ../hop.yaml"))
    deep = "[" * 100_000 + "]" * 100_000
    meta, msgs = read_all(hop / "hop.mcap")
    write_mcap(hop / "tests" / "deep.mcap", meta,
               [*msgs, ("/hfsmc/trace", int(meta["hfsmc.run"]["start_unix_ns"]),
                        ('{"t":1,"msg":' + deep + "}").encode())])
    (hop / "tests" / "copy.mcap").write_bytes((hop / "hop.mcap").read_bytes())
    (hop / "tests" / "nomodel.mcap").write_bytes(forged(hop, "x.mcap", sources={
        "other.yaml": HOP}).read_bytes())
    r = hfsmc("test", "tests", "--junit", "junit.xml", cwd=hop)
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    # Found in the folder, in order; the recording beside tests/ replays with ../hop.yaml.
    assert lines[:4] == ["tests/climb.yaml::python PASSED", "tests/copy.mcap::python PASSED",
                         "tests/deep.mcap::python ERROR", "tests/nomodel.mcap::python ERROR"]
    text = r.stdout
    assert ("tests/deep.mcap: cannot be replayed: corrupted: a /hfsmc/trace message nests "
            "too deeply") in text
    assert ("tests/nomodel.mcap: cannot be replayed: no model `other.yaml` beside it to replay "
            "it with (a recording's own model is code, run only with --allow-recorded-code; "
            "or hfsmc replay tests/nomodel.mcap --model MODEL)") in text
    assert lines[-1].strip("= ").startswith("2 passed, 2 errors in ")
    junit = (hop / "junit.xml").read_text()
    assert 'errors="2"' in junit and 'failures="0"' in junit and junit.count("<error ") == 2
    # An empty folder is said, not silently passed.
    (hop / "empty").mkdir(exist_ok=True)
    r = hfsmc("test", "empty", cwd=hop)
    assert r.returncode == 2
    assert r.stderr.startswith("hfsmc test: no scenario in empty (docs/testing.md: ")


def test_scenarios_are_found_in_folders_as_pytest_finds_tests(tmp_path: Path) -> None:
    for rel in ("a/tests/one.yaml", "a/tests/deeper/two.yml", "a/tests/images/p.png",
                "a/model.yaml", "b/test_three.yaml", "b/four_test.yaml", "b/flight.mcap",
                "c/tests/flight.mcap", ".hidden/tests/x.yaml", "build/tests/y.yaml"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    found, empty = find_scenarios([str(tmp_path), str(tmp_path / "b" / "flight.mcap")])
    assert [os.path.relpath(p, tmp_path) for p in found] == [
        "a/tests/one.yaml", "a/tests/deeper/two.yml", "b/four_test.yaml", "b/test_three.yaml",
        "c/tests/flight.mcap", "b/flight.mcap"]
    assert empty == []
    assert find_scenarios([str(tmp_path / "a" / "tests" / "images")]) == (
        [], [str(tmp_path / "a" / "tests" / "images")])


# --- what-if replays never invent evidence -----------------------------------------------

LOOKER = """\
hfsm: 1
name: looker
language: python
interfaces:
  camera: {type: camera, url: "http://127.0.0.1:1/x.mjpg"}
variables:
  seen: 0
period: 100ms
initial: Look
states:
  Look:
    entry: |
      img = camera.frame()
      seen = -1 if img is None else int(img[0, 0, 0])
      log(f"seen {seen}")
    transitions:
      - {to: Done, when: elapsed() >= 0.5}
  Done: {final: true}
"""


def test_a_what_if_replay_stops_at_the_first_query_the_recording_cannot_answer(
        tmp_path: Path) -> None:
    """The recorded model read frame 1 only; a changed model that reads each frame asks for
    frame 2 at 0.1 s, one that ticks every 50 ms asks at 0.05 s, an instant never recorded:
    the report compares what came before and says what was asked then."""
    (tmp_path / "looker.yaml").write_text(LOOKER)
    r = hfsmc("build", "looker.yaml", "-o", "component", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    script = tmp_path / "script"
    script.mkdir()
    rows = []
    for n in range(1, 7):
        img = np.full((4, 4, 3), 10 * n, np.uint8)
        assert cv2.imwrite(str(script / f"f{n}.png"), img)
        rows.append({"t": (n - 1) * 100_000, "kind": "snapshot", "interface": "camera",
                     "values": {"count": n, "age": 0.0, "frame": f"f{n}.png",
                                "crc32": zlib.crc32(img.tobytes())}})
    (script / "inputs.jsonl").write_text("".join(json.dumps(x) + "\n" for x in rows))
    run = subprocess.run([sys.executable, str(tmp_path / "component" / "looker.py"),
                          "--playback", "script", "--record", "look.mcap", "--until", "2s"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    r = hfsmc("replay", "look.mcap", "--model", "looker.yaml", cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr  # the recorded model: every answer recorded

    every = LOOKER.replace("    transitions:\n      - {to: Done",
                           "    during: img = camera.frame()\n    transitions:\n      - {to: Done")
    (tmp_path / "every.yaml").write_text(every)
    r = hfsmc("replay", "look.mcap", "--model", "every.yaml", cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stdout.splitlines()[1:] == [
        "replay of look.mcap (python -> python): identical up to 0.100 s: 3 trace records, "
        "0 commands, 0-0.100 s",
        "at 0.100 s the model asked camera.frame() for frame 2, which the recorded run never "
        "read: the recording holds no evidence from there on (nothing after it is compared)"]

    (tmp_path / "fast.yaml").write_text(every.replace("period: 100ms", "period: 50ms"))
    r = hfsmc("replay", "look.mcap", "--model", "fast.yaml", cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stdout.splitlines()[-1] == (
        "at 0.050 s the model asked camera.frame() at an instant the recorded run did not "
        "have: the recording holds no evidence from there on (nothing after it is compared)")

    # A model with an interface the recording does not hold.
    (tmp_path / "two.yaml").write_text(every.replace(
        "interfaces:\n", "interfaces:\n  drone: {type: mavlink, url: \"udpin:127.0.0.1:0\"}\n")
        .replace("during: img = camera.frame()", "during: alt = drone.altitude()"))
    r = hfsmc("replay", "look.mcap", "--model", "two.yaml", cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stdout.splitlines()[-1].startswith(
        "at 0.000 s the model asked drone.altitude() of an interface the recording does not "
        "hold: "), r.stdout


def test_hash_is_the_one_components_record() -> None:
    """sources_hash (the reader's check) is the hash a component writes (model_sources)."""
    from hfsmc.model_sources import model_hash

    sources = (("a.yaml", "x"), ("../b.yaml", "y"))
    h = hashlib.sha256(b"a.yaml\0x\0../b.yaml\0y\0").hexdigest()
    assert sources_hash(sources) == model_hash(sources) == f"sha256:{h}"
