"""The Python component's --playback and --record (docs/recording.md, schemas/recording.md):
interfaces read once per instant, fakes fed from a script, a recording read back with the
real `mcap` reader."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mcap.reader import NonSeekingReader

from hfsmc.model_sources import model_hash, model_sources
from hfsmc.pipeline import compile_file
from tests.support import hfsmc, records, wait_until

MODEL = """\
hfsm: 1
name: probe
language: python
interfaces:
  drone: {type: mavlink}
  camera: {type: camera}
parameters:
  top: {type: float, default: 2.5}
variables:
  seen: 0
states:
  Wait:
    during: |
      img = camera.frame()
      if img is not None:
          seen = int(img[1, 2, 0])
    transitions:
      - {to: Go, when: drone.ready() and seen > 0}
  Go:
    entry: |
      drone.set_mode("GUIDED")
      drone.arm()
      log(f"arm {drone.last_ack('arm')} {drone.altitude()} {drone.altitude() == drone.altitude()}")
    transitions:
      - {to: Fly, when: drone.armed()}
  Fly:
    entry: drone.takeoff(3)
    during: |
      log(f"alt {drone.altitude()} age {camera.age()} count {camera.count()}")
      drone.set_velocity(1, 0, 0, 0.5)
    transitions:
      - {to: Done, when: drone.altitude() > top}
  Done: {final: true}
initial: Wait
"""


def _inputs(folder: Path, lines: list[dict[str, Any]]) -> None:
    folder.mkdir(exist_ok=True)
    (folder / "inputs.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))


def _frame(folder: Path, name: str, value: int) -> np.ndarray[Any, Any]:
    img = np.zeros((24, 32, 3), np.uint8)
    img[1, 2, 0] = value
    img[5:9, 3:7] = (10, 200, 30)
    cv2.imwrite(str(folder / name), img)
    return img


SCRIPT = [
    {"t": 0, "kind": "snapshot", "interface": "drone",
     "values": {"heartbeat_age": 0.5, "vehicle": True, "type": 2}},
    {"t": 300000, "kind": "snapshot", "interface": "drone", "values": {"ready": True}},
    {"t": 500000, "kind": "snapshot", "interface": "camera",
     "values": {"count": 1, "age": 0.01, "frame": "f1.png"}},
    {"t": 800000, "kind": "snapshot", "interface": "drone",
     "values": {"armed": True, "acks": {"arm": "accepted"}, "altitude": 0.1}},
    {"t": 850000, "kind": "snapshot", "interface": "camera",
     "values": {"count": 2, "age": "inf", "frame": "f2.png"}},
    {"t": 1000000, "kind": "snapshot", "interface": "drone", "values": {"altitude": 2.6}},
]


@pytest.fixture(scope="module")
def probe(tmp_path_factory: pytest.TempPathFactory) -> Path:
    home = tmp_path_factory.mktemp("probe")
    (home / "probe.yaml").write_text(MODEL)
    out = hfsmc("build", str(home / "probe.yaml"), "-o", str(home / "probe"))
    assert out.returncode == 0, out.stderr
    return home


def _run(probe: Path, *args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(probe / "probe" / "probe.py"), *args],
                          capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)


def test_fakes_answer_from_the_script_one_snapshot_per_instant(probe: Path, tmp_path: Path) -> None:
    pb = tmp_path / "pb"
    _inputs(pb, SCRIPT)
    _frame(pb, "f1.png", 7)
    _frame(pb, "f2.png", 9)
    done = _run(probe, "--playback", str(pb), "--trace", "-")
    assert done.returncode == 0, done.stderr
    recs = records(done.stdout)
    fired = [(r["t"], r["from"], r["to"]) for r in recs if r["ev"] == "fire"]
    # The frame comes at 0.5 s: Wait's during sees it then, its transition at the next tick.
    assert fired == [(600, "Wait", "Go"), (800, "Go", "Fly"), (1000, "Fly", "Done")]
    logs = [(r["t"], r["msg"]) for r in recs if r["ev"] == "log"]
    # A command acknowledged says `pending` in the instant it was sent; two reads agree (NaN
    # too: the same snapshot, and NaN != NaN, so the model compares the two readings).
    assert logs == [(600, "arm pending nan False"),
                    (800, "alt 0.1 age 0.01 count 1"),
                    (900, "alt 0.1 age inf count 2"),  # at 1 s the transition fires first
                    # Stopped armed: said from the last snapshot, as a replay says it too.
                    (1000, "drone: WARNING: ARMED in  at 2.6 m as the component stops: "
                           "nothing lands the vehicle now")]
    commands = [json.loads(x) for x in (pb / "commands.jsonl").read_text().splitlines()]
    assert commands == [
        {"t": 600000, "interface": "drone", "call": "set_mode", "args": ["GUIDED"]},
        {"t": 600000, "interface": "drone", "call": "arm", "args": []},
        {"t": 800000, "interface": "drone", "call": "takeoff", "args": [3.0]},
        {"t": 800000, "interface": "drone", "call": "set_velocity", "args": [1.0, 0.0, 0.0, 0.5]},
        {"t": 900000, "interface": "drone", "call": "set_velocity", "args": [1.0, 0.0, 0.0, 0.5]},
    ]


def test_skips_and_signals_happen_where_the_script_says(probe: Path, tmp_path: Path) -> None:
    pb = tmp_path / "pb"
    # The root missed ticks after its tick at 0.2 s: next deadline 0.5 s (2 missed). A SIGINT
    # acted on after the 5th tick (0, 0.1, 0.2, 0.5, 0.6), at 0.65 s (it came while waiting).
    _inputs(pb, [{"t": 200000, "kind": "skip", "automaton": "", "deadline": 500000, "missed": 2},
                 {"t": 650000, "kind": "signal", "reason": "sigint", "ticks": 5}])
    done = _run(probe, "--playback", str(pb), "--trace", "-")
    assert done.returncode == 130, done.stderr
    recs = records(done.stdout)
    assert recs[-1] == {"t": 650, "ev": "stop", "reason": "sigint"}
    assert [r["ev"] for r in recs] == ["start", "enter", "exit", "stop"]


def _model(path: Path) -> Any:
    result = compile_file(str(path))
    assert result.model is not None
    return result.model


def _messages(path: Path) -> tuple[dict[str, dict[str, str]], list[tuple[str, dict[str, Any]]]]:
    meta: dict[str, dict[str, str]] = {}
    from mcap.stream_reader import StreamReader
    with path.open("rb") as f:
        for rec in StreamReader(f).records:
            if type(rec).__name__ == "Metadata":
                meta[rec.name] = dict(rec.metadata)  # type: ignore[attr-defined]
    with path.open("rb") as f:
        msgs = [(ch.topic, json.loads(m.data)) for _, ch, m in
                NonSeekingReader(f).iter_messages(log_time_order=False)]
    return meta, msgs


def test_a_recording_holds_what_came_in_and_the_trace(probe: Path, tmp_path: Path) -> None:
    pb = tmp_path / "pb"
    _inputs(pb, SCRIPT)
    f1 = _frame(pb, "f1.png", 7)
    _frame(pb, "f2.png", 9)
    rec = tmp_path / "run.mcap"
    trace = tmp_path / "trace.jsonl"
    done = _run(probe, "--playback", str(pb), "--trace", str(trace), "--record", str(rec),
                "--param", "top=2.0")
    assert done.returncode == 0, done.stderr
    meta, msgs = _messages(rec)
    run = meta["hfsmc.run"]
    sources = model_sources(_model(probe / "probe.yaml"))
    assert sources == (("probe.yaml", MODEL),)
    assert run["model_hash"] == model_hash(sources)
    assert (run["component"], run["language"], run["clock"], run["recording"]) == \
        ("probe", "python", "virtual", "1")
    assert meta["hfsmc.sources"] == {"probe.yaml": MODEL}
    assert meta["hfsmc.parameters"] == {"top": "2.0"}
    assert json.loads(meta["hfsmc.interfaces"]["drone"])["type"] == "mavlink"
    # One snapshot per interface per instant, 0 to 1 s every 100 ms.
    drone = [m for topic, m in msgs if topic == "/hfsmc/interface/drone"]
    assert [m["t"] for m in drone] == list(range(0, 1000001, 100000))
    assert drone[0]["position"] == ["nan", "nan", "nan"] and drone[0]["heartbeat_age"] == 0.5
    assert drone[-1]["altitude"] == 2.6 and drone[-1]["acks"] == {"arm": "accepted"}
    # Frame 1 obtained (by Wait, from 0.5 s on) once, lossless; frame 2 never obtained.
    frames = [m for topic, m in msgs if topic == "/hfsmc/frame/camera"]
    assert [f["count"] for f in frames] == [1] and frames[0]["format"] == "png"
    got = cv2.imdecode(np.frombuffer(base64.b64decode(frames[0]["data"]), np.uint8),
                       cv2.IMREAD_UNCHANGED)
    assert got is not None and np.array_equal(got, f1)
    commands = [(m["t"], m["call"], m["args"]) for topic, m in msgs
                if topic == "/hfsmc/command/drone"]
    played = [json.loads(x) for x in (pb / "commands.jsonl").read_text().splitlines()]
    assert commands == [(c["t"], c["call"], c["args"]) for c in played]
    assert [m for topic, m in msgs if topic == "/hfsmc/trace"] == records(trace.read_text())


def test_a_bad_script_is_one_line_with_its_place(probe: Path, tmp_path: Path) -> None:
    cases = {
        "{\"t\": 0, \"kind\": \"snapshot\", \"interface\": \"drone\", \"values\": {}}\n{oops\n":
            "inputs.jsonl:2: ",
        "{\"t\": 5, \"kind\": \"skip\", \"automaton\": \"\", \"deadline\": 1, \"missed\": 1}\n"
        "{\"t\": 4, \"kind\": \"skip\", \"automaton\": \"\", \"deadline\": 1, \"missed\": 1}\n":
            "inputs.jsonl:2: `t` 4 goes back in time",
        "{\"t\": 0, \"kind\": \"snapshot\", \"interface\": \"drone\", \"values\": "
        "{\"armed\": 1}}\n": "inputs.jsonl:1: `armed` must be true or false",
        "{\"t\": 0, \"kind\": \"snapshot\", \"interface\": \"camera\", \"values\": "
        "{\"frame\": \"none.png\"}}\n": "inputs.jsonl:1: frame `none.png` is not a file",
        "{\"t\": 0, \"kind\": \"wind\"}\n": "inputs.jsonl:1: unknown kind `wind`",
    }
    for k, (text, said) in enumerate(cases.items()):
        pb = tmp_path / f"pb{k}"
        pb.mkdir()
        (pb / "inputs.jsonl").write_text(text)
        done = _run(probe, "--playback", str(pb))
        assert done.returncode == 2, (text, done.stderr)
        assert said in done.stderr and "Traceback" not in done.stderr, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr


def test_a_killed_component_leaves_a_recording_readable_to_its_last_instant(
        probe: Path, tmp_path: Path) -> None:
    pb = tmp_path / "pb"
    _inputs(pb, [{"t": 0, "kind": "snapshot", "interface": "drone", "values": {"vehicle": True}}])
    rec = tmp_path / "run.mcap"
    # The real clock would wait for a vehicle; a playback runs as fast as it can: 10 min of
    # instants in Wait, killed while it writes.
    proc = subprocess.Popen([sys.executable, str(probe / "probe" / "probe.py"), "--playback",
                             str(pb), "--record", str(rec), "--until", "600s"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert wait_until(lambda: rec.exists() and rec.stat().st_size > 200_000, 30)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    time.sleep(0.1)
    from mcap.exceptions import EndOfFile
    from mcap.stream_reader import StreamReader
    seen = []
    with rec.open("rb") as f, contextlib.suppress(EndOfFile, struct.error, UnicodeDecodeError):
        for r in StreamReader(f).records:
            if type(r).__name__ == "Message":
                seen.append(json.loads(r.data))  # type: ignore[attr-defined]
    # Every message read is whole; instants come in order, each with both snapshots.
    ts = [m["t"] for m in seen if "heartbeat_age" in m]
    assert len(ts) > 100 and ts == list(range(0, 100000 * len(ts), 100000))


def test_each_frame_is_recorded_once_even_when_the_pixels_repeat(probe: Path, tmp_path: Path) -> None:
    pb = tmp_path / "pb"
    # Frames 1 and 2 are the same picture (a still scene); frame 2 stays for two instants.
    _inputs(pb, [{"t": 100000, "kind": "snapshot", "interface": "camera",
                  "values": {"count": 1, "age": 0.0, "frame": "f.png"}},
                 {"t": 200000, "kind": "snapshot", "interface": "camera",
                  "values": {"count": 2, "age": 0.0, "frame": "f.png"}}])
    f = _frame(pb, "f.png", 7)
    rec = tmp_path / "run.mcap"
    done = _run(probe, "--playback", str(pb), "--record", str(rec), "--until", "0.4s")
    assert done.returncode == 0, done.stderr
    _, msgs = _messages(rec)
    frames = [m for topic, m in msgs if topic == "/hfsmc/frame/camera"]
    assert [(m["count"], m["format"]) for m in frames] == [(1, "png"), (2, "png")]
    assert {m["crc32"] for m in frames} == {zlib.crc32(f.tobytes())}
