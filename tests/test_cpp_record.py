"""Recording and playback in the C++ component (docs/recording.md, schemas/recording.md).

One model with a `mavlink` and a `camera` interface, regions and a sub-automaton, in C++
(built once for the module) and its Python twin: with ``--playback DIR`` both write the
same trace and the same ``DIR/commands.jsonl``, which also say what the inputs make
them do; with ``--record FILE`` against the simulator the C++ component writes an MCAP
file that the Python ``mcap`` reader streams back (metadata, one snapshot per interface
and instant, frames with their exact pixels, commands, the trace); killed with SIGKILL
it leaves a file that reads back up to a complete instant."""

from __future__ import annotations

import base64
import json
import signal
import socket
import struct
import subprocess
import sys
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader

from tests.conftest import ROOT
from tests.cppbuild import Superbuild, need_toolchain
from tests.support import free_port, wait_until

pytestmark = pytest.mark.timeout(900)  # the first test waits for the C++ build

HFSMC = [sys.executable, "-m", "hfsmc"]
CUT_ERRORS = (McapError, struct.error, UnicodeDecodeError)  # a stream that ends mid-record

# The C++ model and its Python twin: the same states, timings, log lines and commands.
SHAPE = """\
hfsm: 1
name: rec_probe
{language}interfaces:
  drone: {{type: mavlink, url: "udpin:127.0.0.1:14550"}}
  camera: {{type: camera, url: "http://127.0.0.1:8554/bottom.mjpg"}}
parameters:
  climb: {{type: float, default: 2.5}}
  fly_s: {{type: float, default: 1.0}}
variables:
  blue: 0
period: 100ms
initial: Wait
on_interrupt: Land
states:
  Wait:
    transitions:
      - {{to: Fly, when: drone.ready()}}
  Fly:
    entry: {arm}
    transitions:
      - {{to: Land, when: done()}}
      - {{to: Land, when: elapsed() > fly_s}}
    regions:
      Climb:
        initial: Up
        states:
          Up:
            during: {climb}
            transitions: [{{to: High, when: drone.altitude() > climb}}]
          High: {{final: true}}
      Look:
        period: 200ms
        initial: Scan
        states:
          Scan:
            during: |
{look}
            transitions: [{{to: Seen, when: blue == 7}}]
          Seen: {{final: true}}
  Land:
    entry: {land}
    transitions: [{{to: Done, when: done()}}]
    initial: Landing
    states:
      Landing:
        transitions: [{{to: Landed, when: {disarmed}}}]
      Landed: {{final: true}}
  Done: {{final: true}}
"""
CPP_MODEL = SHAPE.format(
    language="language: cpp\n",
    arm="'drone.arm(); drone.takeoff(climb); log(\"arm: \" + drone.last_ack(\"arm\"));'",
    climb="'drone.set_velocity(0.0, 0.0, -0.5, 0.0);'",
    look="""\
              cv::Mat f = camera.frame();
              if (!f.empty()) {
                cv::Vec3b p = f.at<cv::Vec3b>(5, 6);
                blue = p[0];
                log("frame " + str(camera.count()) + " px " + str(int(p[0])) + " " + str(int(p[1])) + " " + str(int(p[2])));
              }""",
    land="'drone.land(); log(\"land: \" + drone.last_ack(\"land\"));'",
    disarmed='"!drone.armed()"')
PY_MODEL = SHAPE.format(
    language="",
    arm="'drone.arm(); drone.takeoff(climb); log(\"arm: \" + drone.last_ack(\"arm\"))'",
    climb="'drone.set_velocity(0.0, 0.0, -0.5, 0.0)'",
    look="""\
              f = camera.frame()
              if f is not None:
                  b, g, r = (int(x) for x in f[5, 6])
                  blue = b
                  log(f"frame {camera.count()} px {b} {g} {r}")""",
    land="'drone.land(); log(\"land: \" + drone.last_ack(\"land\"))'",
    disarmed="not drone.armed()")


@dataclass
class Components:
    cpp: Path  # the executable
    python: Path  # the component's script
    models: Path  # their folder


@pytest.fixture(scope="module")
def components(tmp_path_factory: pytest.TempPathFactory) -> Components:
    need_toolchain()
    base = tmp_path_factory.mktemp("record")
    (base / "cpp").mkdir()
    (base / "py").mkdir()
    cpp_model, py_model = base / "cpp" / "rec_probe.yaml", base / "py" / "rec_probe.yaml"
    cpp_model.write_text(CPP_MODEL)
    py_model.write_text(PY_MODEL)
    r = subprocess.run([*HFSMC, "build", str(py_model), "-o", str(base / "py_component")],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    exe = Superbuild(base / "build", [cpp_model]).executable(cpp_model)
    return Components(exe, base / "py_component" / "rec_probe.py", base)


def frames(folder: Path) -> None:
    """Two 32 x 24 BGR pictures as PNG: the pixel at row 5, column 6 tells them apart."""
    a = np.zeros((24, 32, 3), np.uint8)
    a[:, :, 0] = 50
    a[5, 6] = (3, 2, 1)
    b = np.full((24, 32, 3), 200, np.uint8)
    b[5, 6] = (7, 8, 9)
    assert cv2.imwrite(str(folder / "a.png"), a) and cv2.imwrite(str(folder / "b.png"), b)


def script(folder: Path, rows: list[dict[str, Any]]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    frames(folder)
    (folder / "inputs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


# Telemetry that changes, two frames, a skip of the Climb region (its ticks at 0.5 and
# 0.6 s are not run), a vehicle that disarms at 1 s.
INPUTS: list[dict[str, Any]] = [
    {"t": 0, "kind": "snapshot", "interface": "drone", "values": {"heartbeat_age": "inf"}},
    {"t": 200000, "kind": "snapshot", "interface": "drone",
     "values": {"heartbeat_age": 0.25, "vehicle": True, "ready": True, "mode": "GUIDED",
                "type": 2, "altitude": 0.1}},
    {"t": 300000, "kind": "snapshot", "interface": "drone",
     "values": {"armed": True, "acks": {"arm": "accepted"}, "altitude": 1.0}},
    {"t": 300000, "kind": "snapshot", "interface": "camera",
     "values": {"count": 3, "age": 0.05, "frame": "a.png"}},
    {"t": 400000, "kind": "skip", "automaton": "Fly/Climb", "deadline": 700000, "missed": 2},
    {"t": 500000, "kind": "snapshot", "interface": "camera",
     "values": {"count": 7, "age": 0.01, "frame": "b.png"}},
    {"t": 700000, "kind": "snapshot", "interface": "drone", "values": {"altitude": 3.0}},
    {"t": 1000000, "kind": "snapshot", "interface": "drone", "values": {"armed": False}},
]
SIGINT_AT_350MS = {"t": 350000, "kind": "signal", "reason": "sigint", "ticks": 7}


def play(command: list[str], folder: Path) -> tuple[int, list[str], list[str]]:
    """Run a component on `folder`: its exit status, trace lines and command lines."""
    r = subprocess.run([*command, "--playback", str(folder), "--trace", str(folder / "trace.jsonl"),
                        "--trace-variables", "--until", "5s"],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode in (0, 130), r.stderr
    return (r.returncode, (folder / "trace.jsonl").read_text().splitlines(),
            (folder / "commands.jsonl").read_text().splitlines())


def both(components: Components, tmp_path: Path, rows: list[dict[str, Any]]
         ) -> tuple[int, list[str], list[str]]:
    """Play `rows` to the C++ and the Python component: they must do the same."""
    cpp = play([str(components.cpp)], script(tmp_path / "cpp", rows))
    py = play([sys.executable, str(components.python)], script(tmp_path / "py", rows))
    assert cpp == py
    return cpp


def events(trace: list[str], *kinds: str) -> list[tuple[int, str]]:
    out = []
    for line in trace:
        r = json.loads(line)
        if r["ev"] in kinds:
            out.append((r["t"], r.get("msg") or r.get("to") or r.get("reason") or ""))
    return out


def test_playback_feeds_both_languages_the_same_world(components: Components,
                                                      tmp_path: Path) -> None:
    status, trace, commands = both(components, tmp_path, INPUTS)
    assert status == 0
    assert events(trace, "fire", "log", "stop") == [
        (200, "Fly"), (200, "arm: pending"),
        (400, "frame 3 px 3 2 1"),  # the frame of the snapshot at 0.3 s, at Look's tick
        (600, "frame 7 px 7 8 9"),  # the exact pixels of b.png
        (700, "Fly/Climb/High"),  # after the skip: Climb ticks again at 0.7 s
        (800, "Fly/Look/Seen"), (900, "Land"), (900, "land: pending"),
        (1000, "Land/Landed"), (1100, "Done"), (1100, "final")]
    assert [json.loads(c) for c in commands] == [
        {"t": 200000, "interface": "drone", "call": "arm", "args": []},
        {"t": 200000, "interface": "drone", "call": "takeoff", "args": [2.5]},
        *({"t": t, "interface": "drone", "call": "set_velocity", "args": [0.0, 0.0, -0.5, 0.0]}
          for t in (200000, 300000, 400000)),
        {"t": 900000, "interface": "drone", "call": "land", "args": []}]
    assert commands[3] == '{"t":300000,"interface":"drone","call":"set_velocity","args":[0.0,0.0,-0.5,0.0]}'


def test_a_played_signal_is_acted_on_after_its_ticks(components: Components,
                                                     tmp_path: Path) -> None:
    rows = sorted([*INPUTS, SIGINT_AT_350MS], key=lambda r: int(r["t"]))
    status, trace, _ = both(components, tmp_path, rows)
    assert status == 130
    assert events(trace, "interrupt", "stop") == [(350, "Land"), (1100, "sigint")]


def test_bad_playback_input_is_said_with_its_line(components: Components, tmp_path: Path) -> None:
    folder = script(tmp_path / "bad", INPUTS[:2])
    with (folder / "inputs.jsonl").open("a") as f:
        f.write('{"t": 300000, "kind": "snapshot", "interface": "drone", "values": {"armed": 1}}\n')
    r = subprocess.run([str(components.cpp), "--playback", str(folder)],
                       capture_output=True, text=True, timeout=60, check=False)
    assert (r.returncode, r.stderr) == (
        2, f"rec_probe: --playback: {folder}/inputs.jsonl:3: `armed` must be true or false\n")
    (folder / "inputs.jsonl").write_text('{"t": 0, "kind": "snapshot"\n')
    r = subprocess.run([str(components.cpp), "--playback", str(folder)],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 2
    assert r.stderr.startswith(f"rec_probe: --playback: {folder}/inputs.jsonl:1: not JSON: ")


def test_played_values_are_recorded_exactly(components: Components, tmp_path: Path) -> None:
    """Numbers read back bit for bit (strtod in, shortest round-trip text out), strings
    with their escapes; the snapshot a recording holds is what the script gave."""
    values = {"heartbeat_age": 0.30000000000000004, "ready": False, "armed": True,
              "mode": "GU\u00efDED \"x\"\n\U0001f681", "position": ["nan", 1.5, "-inf"],
              "altitude": 5e-324, "velocity": [1e300, -0.0, 2.2250738585072014e-308],
              "yaw": -1.2345678901234567e-05, "battery": 87, "acks": {"arm": "denied"},
              "vehicle": True, "type": 13}
    folder = script(tmp_path / "exact", [{"t": 0, "kind": "snapshot", "interface": "drone",
                                          "values": values}])
    r = subprocess.run([str(components.cpp), "--playback", str(folder), "--record",
                        str(folder / "run.mcap"), "--until", "0s"],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    messages, cut = streamed(folder / "run.mcap")
    assert not cut
    first = next(m for topic, m in messages if topic == "/hfsmc/interface/drone")
    # what the script gave, exactly; the fields it did not give keep their "nothing yet"
    assert first["t"] == 0 and {k: first[k] for k in values} == values
    assert json.dumps(first["velocity"][1]) == "-0.0"


# -- --record against the simulator --------------------------------------------------------
@pytest.fixture
def sim(tmp_path: Path) -> Iterator[Path]:
    """`hfsmc sim` on free ports: the configuration that points the component at it."""
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    config = {"interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
                             "camera": {"type": "camera",
                                        "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}
    (tmp_path / "config.yaml").write_text(json.dumps(config))
    with (tmp_path / "sim.log").open("wb") as log:
        p = subprocess.Popen([*HFSMC, "sim", "--world", str(ROOT / "examples/follow_colors/world.yaml"),
                              "--mavlink", f"udpout:127.0.0.1:{udp}", "--camera-port", str(http)],
                             stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        try:
            yield tmp_path / "config.yaml"
        finally:
            p.send_signal(signal.SIGINT)
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=20)


def streamed(path: Path) -> tuple[list[tuple[str, dict[str, Any]]], bool]:
    """The messages (topic, JSON) of a recording in file order, and whether it ended cut."""
    out: list[tuple[str, dict[str, Any]]] = []
    with path.open("rb") as f:
        try:
            for _, channel, message in NonSeekingReader(f).iter_messages(log_time_order=False):
                out.append((channel.topic, json.loads(message.data)))
        except CUT_ERRORS:
            return out, True
    return out, False


def snapshot_times(messages: list[tuple[str, dict[str, Any]]], name: str) -> list[int]:
    return [m["t"] for topic, m in messages if topic == f"/hfsmc/interface/{name}"]


def test_record_against_the_simulator(components: Components, sim: Path, tmp_path: Path) -> None:
    run = tmp_path / "run.mcap"
    r = subprocess.run([str(components.cpp), "--config", str(sim), "--record", str(run),
                        "--trace", str(tmp_path / "trace.jsonl"), "--until", "30s"],
                       capture_output=True, text=True, timeout=90, check=False)
    assert r.returncode == 0, r.stderr
    trace = (tmp_path / "trace.jsonl").read_text().splitlines()
    assert json.loads(trace[-1])["reason"] == "final", r.stderr
    with run.open("rb") as f:
        metadata = {m.name: m.metadata for m in NonSeekingReader(f).iter_metadata()}
    assert metadata["hfsmc.run"]["language"] == "cpp"
    assert metadata["hfsmc.run"]["model_hash"].startswith("sha256:")
    assert metadata["hfsmc.run"]["until_us"] == "30000000"
    assert metadata["hfsmc.parameters"] == {"climb": "2.5", "fly_s": "1.0"}
    assert json.loads(metadata["hfsmc.interfaces"]["drone"])["type"] == "mavlink"
    assert metadata["hfsmc.sources"] == {"rec_probe.yaml": CPP_MODEL}
    messages, cut = streamed(run)
    assert not cut
    # The trace, record for record.
    assert [json.dumps(m, separators=(",", ":")) for topic, m in messages
            if topic == "/hfsmc/trace"] == trace
    # One snapshot per interface and instant: at 0, then every 100 ms (no overrun here).
    stop_ms = json.loads(trace[-1])["t"]
    assert snapshot_times(messages, "drone") == list(range(0, stop_ms * 1000 + 1, 100000))
    assert snapshot_times(messages, "camera") == snapshot_times(messages, "drone")
    # Frames: once each, PNG of the exact pixels the snippet logged.
    logged = {int(line.split()[1]): [int(v) for v in line.split()[3:]]
              for _, line in events(trace, "log") if line.startswith("frame ")}
    images = [m for topic, m in messages if topic == "/hfsmc/frame/camera"]
    assert logged and sorted(m["count"] for m in images) == sorted(logged)
    for m in images:
        img = cv2.imdecode(np.frombuffer(base64.b64decode(m["data"]), np.uint8), cv2.IMREAD_COLOR)
        assert m["format"] == "jpeg" and img is not None and img.shape[2] == 3  # as it came
        assert img[5, 6].tolist() == logged[m["count"]]
        assert m["crc32"] == zlib.crc32(img.tobytes())
    calls = [m["call"] for topic, m in messages if topic == "/hfsmc/command/drone"]
    assert calls[:3] == ["arm", "takeoff", "set_velocity"] and calls[-1] == "land"
    # Kill -9 mid-run: the file reads back, up to a complete instant.
    cut_run = tmp_path / "cut.mcap"
    p = subprocess.Popen([str(components.cpp), "--config", str(sim), "--record", str(cut_run),
                          "--param", "fly_s=60", "--until", "30s"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert wait_until(cut_run.exists, 30)
        time.sleep(1.5)
    finally:
        p.kill()
        p.wait(timeout=20)
    messages, cut = streamed(cut_run)
    assert cut
    drone, camera = snapshot_times(messages, "drone"), snapshot_times(messages, "camera")
    assert len(drone) >= 5 and camera == drone  # the last instant is complete
    assert drone == list(range(0, drone[-1] + 1, 100000))


def _every_instant(until_us: int, camera: dict[int, dict[str, Any]]) -> list[dict[str, Any]]:
    """A recorded run's script (`recorded` first): each interface's snapshot at every 100 ms
    instant, the vehicle's from INPUTS, the camera's from ``camera`` (by time, held)."""
    rows: list[dict[str, Any]] = [{"t": 0, "kind": "recorded"}]
    drone: dict[str, Any] = {}
    cam: dict[str, Any] = {"count": 0, "age": "inf", "frame": None}
    for t in range(0, until_us + 1, 100000):
        for r in INPUTS:
            if r["t"] == t and r.get("interface") == "drone":
                drone.update(r["values"])
        cam = camera.get(t, cam)
        rows.append({"t": t, "kind": "snapshot", "interface": "drone", "values": dict(drone)})
        row = {"t": t, "kind": "snapshot", "interface": "camera",
               "values": {k: v for k, v in cam.items() if k != "unrecorded"}}
        if "unrecorded" in cam:
            row["unrecorded"] = cam["unrecorded"]
        rows.append(row)
    return rows


def test_both_languages_say_which_query_a_recording_cannot_answer(components: Components,
                                                                  tmp_path: Path) -> None:
    """A recorded run's script: a frame the recorded run never read (count 3 from 0.3 s) is
    asked for at Look's tick at 0.4 s; a script that stops at 0 s cannot answer the vehicle's
    query at the next instant. Both write the same first unanswered query, and run on."""
    unread = {"count": 3, "age": 0.05, "frame": None, "unrecorded": ["frame"]}
    _, trace, _ = both(components, tmp_path / "frame", _every_instant(1500000, {300000: unread}))
    for lang in ("cpp", "py"):
        assert (tmp_path / "frame" / lang / "unanswered.jsonl").read_text() == (
            '{"t":400000,"interface":"camera","query":"frame","reason":"frame","count":3}\n')
    assert [why for _, why in events(trace, "stop")] == ["final"]  # run on, as without a frame
    _, trace, _ = both(components, tmp_path / "instant", _every_instant(0, {}))
    for lang in ("cpp", "py"):
        assert (tmp_path / "instant" / lang / "unanswered.jsonl").read_text() == (
            '{"t":100000,"interface":"drone","query":"ready","reason":"instant"}\n')
    # Without `recorded` (a scenario's script), values hold between entries: nothing unanswered.
    both(components, tmp_path / "scenario", _every_instant(0, {})[1:])
    assert not list((tmp_path / "scenario").rglob("unanswered.jsonl"))
