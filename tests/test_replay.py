"""`hfsmc replay RECORDING`: a recorded run run again from the recording, and compared.

The cheap recordings are made by the Python component of a small model in `--playback` of a
hand-written script, with `--record` (deterministic, about a second); one real simulated
follow_colors flight (slow, in lockstep with the simulator) is replayed with the same model,
a changed threshold and the C++ twin, whose own flight (in real time) replays with the Python
model.  Broken files (cut, corrupted, not MCAP) are read at the unit level."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.writer import Writer

from hfsmc.commands.replay import NOT_EVIDENCE
from hfsmc.commands.replay_model import virtual_sources
from hfsmc.recording import RecordingError, read_recording
from tests.conftest import ROOT

HOP = """\
hfsm: 1
name: hop
language: python
interfaces:
  drone: {type: mavlink, url: "udpin:127.0.0.1:0"}
parameters:
  height: {type: float, default: 2.0}
period: 100ms
initial: Wait
states:
  Wait:
    transitions:
      - {to: Climb, when: drone.ready(), do: "drone.arm(); drone.takeoff(height)"}
  Climb:
    during: drone.set_velocity(0.0, 0.0, -1.0, 0.0)
    transitions:
      - {to: Done, when: drone.altitude() > height}
  Done: {final: true}
"""
# The vehicle as the script has it: ready at 0.3 s, climbing past 2 m at 1 s.
INPUTS = [
    {"t": 0, "kind": "snapshot", "interface": "drone",
     "values": {"vehicle": True, "heartbeat_age": 0.1, "altitude": 0.0}},
    {"t": 300000, "kind": "snapshot", "interface": "drone", "values": {"ready": True}},
    {"t": 500000, "kind": "snapshot", "interface": "drone",
     "values": {"armed": True, "altitude": 0.5}},
    {"t": 800000, "kind": "snapshot", "interface": "drone", "values": {"altitude": 1.5}},
    {"t": 1000000, "kind": "snapshot", "interface": "drone", "values": {"altitude": 2.5}},
]


ALLOW = "--allow-recorded-code"


def hfsmc(*args: str, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "XDG_CACHE_HOME": str(cwd / "cache")}
    return subprocess.run([sys.executable, "-m", "hfsmc", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL, env=env)


@pytest.fixture(scope="module")
def hop(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with hop.yaml and hop.mcap: its run in --playback of INPUTS, recorded."""
    d = tmp_path_factory.mktemp("hop")
    (d / "hop.yaml").write_text(HOP)
    r = hfsmc("build", "hop.yaml", "-o", "component", cwd=d)
    assert r.returncode == 0, r.stderr
    (d / "script").mkdir()
    (d / "script" / "inputs.jsonl").write_text("".join(json.dumps(e) + "\n" for e in INPUTS))
    run = subprocess.run([sys.executable, str(d / "component" / "hop.py"), "--playback", "script",
                          "--record", "hop.mcap", "--until", "5s"], cwd=d, capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    return d


def test_replay_of_the_recorded_model_is_identical(hop: Path) -> None:
    r = hfsmc("replay", "hop.mcap", ALLOW, cwd=hop)
    assert r.returncode == 0, r.stdout + r.stderr
    # 11: the stop says the vehicle is still armed (from the last snapshot, a fake too).
    assert r.stdout == ("replay of hop.mcap (python -> python): identical: 11 trace records, "
                        "9 commands, 0-1.000 s\n")
    # The same model given with --model: its hash is the recorded one.
    r = hfsmc("replay", "hop.mcap", "--model", "hop.yaml", cwd=hop)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith("hop.yaml is the recorded model (sha256:"), r.stdout


def test_a_changed_condition_is_the_first_difference(hop: Path) -> None:
    (hop / "higher.yaml").write_text(HOP.replace("altitude() > height", "altitude() > height + 1"))
    r = hfsmc("replay", "hop.mcap", "--model", "higher.yaml", cwd=hop)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert re.fullmatch(r"higher\.yaml is not the recorded model \(changed: higher\.yaml; hash "
                        r"sha256:\w+\.\.\. against the recorded sha256:\w+\.\.\.\)", lines[0])
    assert lines[1:6] == [
        "replay of hop.mcap (python -> python): different",
        "at 1.000 s in Climb (trace record 6):",
        "  recorded: took Climb -> Done (when: drone.altitude() > height; hop.yaml:17)",
        "  now:      not taken: Climb -> Done (when: drone.altitude() > height + 1; "
        "higher.yaml:17)",
        "  instead:  at 1.000 s: exit Climb (the replay reached the end of the recording and "
        "stopped)"], r.stdout
    assert lines[-1] == NOT_EVIDENCE


def test_a_changed_command_is_the_first_difference(hop: Path) -> None:
    (hop / "taller.yaml").write_text(HOP.replace("takeoff(height)", "takeoff(height + 1)"))
    r = hfsmc("replay", "hop.mcap", "--model", "taller.yaml", cwd=hop)
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stdout.splitlines()[1:] == [
        "replay of hop.mcap (python -> python): different",
        "at 0.300 s (command 2):",
        "  recorded: drone.takeoff(2.0) at 0.300 s",
        "  now:      drone.takeoff(3.0) at 0.300 s",
        "  the trace is the same up to this command",
        "  active when the instant began: Wait",
        NOT_EVIDENCE]


def test_a_signal_is_replayed(hop: Path, tmp_path: Path) -> None:
    """A recording that ended on SIGINT (from a script here: the recording holds it as a real
    run's would) replays identically.  (Skips, which only the real clock makes, are replayed
    in the flight below: a loaded machine makes some.)"""
    script = tmp_path / "script"
    script.mkdir()
    signal = {"t": 700000, "kind": "signal", "reason": "sigint", "ticks": 7}
    (script / "inputs.jsonl").write_text("".join(
        json.dumps(e) + "\n" for e in [*INPUTS[:3], signal, *INPUTS[3:]]))
    run = subprocess.run([sys.executable, str(hop / "component" / "hop.py"), "--playback",
                          str(script), "--record", "sig.mcap"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 130, run.stderr
    rec = read_recording(tmp_path / "sig.mcap")
    assert [(g.t, g.reason) for g in rec.signals] == [(700000, "sigint")]
    assert rec.stop == {"t": 700, "ev": "stop", "reason": "sigint"}
    r = hfsmc("replay", "sig.mcap", ALLOW, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout == ("replay of sig.mcap (python -> python): identical: 8 trace records, "
                        "6 commands, 0-0.700 s\n")


def test_a_component_that_cannot_run_is_said_with_its_words(hop: Path) -> None:
    (hop / "whole.yaml").write_text(HOP.replace("{type: float, default: 2.0}",
                                                "{type: int, default: 2}"))
    r = hfsmc("replay", "hop.mcap", "--model", "whole.yaml", cwd=hop)
    assert r.returncode == 1
    assert r.stdout.startswith("whole.yaml is not the recorded model (changed: whole.yaml;")
    assert r.stderr == ("hfsmc replay: the component failed (exit status 2)\n"
                        "  hop: --param: parameter `height` is an int, not `2.0`\n")


def test_a_model_in_the_other_language_needs_its_twin(hop: Path) -> None:
    r = hfsmc("replay", "hop.mcap", ALLOW, "-t", "cpp", cwd=hop)
    assert r.returncode == 2
    assert r.stderr == ("hfsmc: error: -t cpp: the snippets of the recorded model (hop.yaml) "
                        "are python; give the model's cpp twin with --model\n")


def test_a_cut_recording_replays_up_to_the_cut(hop: Path, tmp_path: Path) -> None:
    data = (hop / "hop.mcap").read_bytes()
    whole = read_recording(hop / "hop.mcap")
    assert not whole.cut
    metadata_end = None
    for n in range(8, len(data), 23):  # every 23rd byte: inside every kind of record
        (tmp_path / "cut.mcap").write_bytes(data[:n])
        try:
            rec = read_recording(tmp_path / "cut.mcap")
        except RecordingError as e:
            assert "cut" in str(e) or "no hfsmc" in str(e), str(e)
            continue
        metadata_end = metadata_end or n
        assert rec.cut and rec.sources == whole.sources
        assert rec.trace == whole.trace[:len(rec.trace)]
        assert rec.commands == whole.commands[:len(rec.commands)]
        assert rec.snapshots == whole.snapshots[:len(rec.snapshots)]
    assert metadata_end is not None
    # Cut in the middle of the run: replayed up to there, and said so.
    (tmp_path / "cut.mcap").write_bytes(data[:len(data) * 2 // 3])
    rec = read_recording(tmp_path / "cut.mcap")
    assert 0 < len(rec.trace) < len(whole.trace)
    (tmp_path / "hop.yaml").write_text(HOP)
    r = hfsmc("replay", "cut.mcap", ALLOW, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == (f"the recording ends at {rec.end_us / 1e6:.3f} s (cut: the component "
                        "did not close it)")
    assert lines[1].startswith("replay of cut.mcap (python -> python): identical up to the "
                               f"cut: {len(rec.trace)} trace records, {len(rec.commands)} "
                               "commands"), lines
    # Cut before the metadata is complete: nothing to replay.
    (tmp_path / "early.mcap").write_bytes(data[:40])
    r = hfsmc("replay", "early.mcap", cwd=tmp_path)
    assert (r.returncode, r.stdout) == (1, "")
    assert r.stderr.startswith("early.mcap: ") and "cut" in r.stderr and \
        len(r.stderr.splitlines()) == 1, r.stderr


def test_broken_files_are_said_in_one_line(hop: Path, tmp_path: Path) -> None:
    data = bytearray((hop / "hop.mcap").read_bytes())
    last_trace = data.rfind(b'"ev":"stop"')
    data[last_trace + 6] ^= 0x20  # "stop" -> "Stop": the file's checksum no longer matches
    (tmp_path / "corrupted.mcap").write_bytes(bytes(data))
    (tmp_path / "model.yaml").write_text(HOP)
    with (tmp_path / "other.mcap").open("wb") as f:  # an MCAP file, not a recording
        w = Writer(f)
        w.start()
        w.add_metadata("something", {"a": "b"})
        w.finish()  # type: ignore[no-untyped-call]
    with (tmp_path / "newer.mcap").open("wb") as f:  # a later recording version
        w = Writer(f)
        w.start()
        for name in ("hfsmc.parameters", "hfsmc.interfaces"):
            w.add_metadata(name, {})
        w.add_metadata("hfsmc.run", {"recording": "2", "language": "python"})
        w.add_metadata("hfsmc.sources", {"model.yaml": HOP})
        w.finish()  # type: ignore[no-untyped-call]
    for name, message in [
            ("corrupted.mcap", "corrupted: its data does not match its checksum"),
            ("model.yaml", "not an MCAP file (a recording is written by a component's "
                           "--record FILE)"),
            ("other.mcap", "not an hfsmc recording, or cut before its metadata: no hfsmc.run, "
                           "hfsmc.parameters, hfsmc.interfaces, hfsmc.sources metadata"),
            ("newer.mcap", "recording version `2`: this hfsmc reads version 1 (a newer hfsmc "
                           "wrote it?)"),
            ("missing.mcap", "cannot read it: No such file or directory")]:
        r = hfsmc("replay", name, cwd=tmp_path)
        assert (r.returncode, r.stdout, r.stderr) == (1, "", f"{name}: {message}\n")


def test_recorded_sources_keep_their_relative_paths_in_memory() -> None:
    main, texts = virtual_sources([("m.yaml", "a"), ("../../lib/x.yaml", "b"),
                                   ("sub/y.yaml", "c")])
    assert main == "/recording/m/m/m.yaml"
    assert texts == {"/recording/m/m/m.yaml": "a", "/recording/lib/x.yaml": "b",
                     "/recording/m/m/sub/y.yaml": "c"}


# --- a real simulated flight -------------------------------------------------------------------
# The take-off (vehicle ready at about 5 s, at altitude at about 11 s), the first stage, and
# at the time limit a landing (about 10 s) through on_interrupt: the vehicle ends disarmed.
TIME_LIMIT_S = 20


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """follow_colors flown by its Python component in the simulator up to its time limit and
    landed, recorded: the folder holding flight.mcap. In lockstep (docs/worlds.md#simulated-time):
    a recording made on the simulator's clock replays like any other."""
    from tests.support import flight

    d = tmp_path_factory.mktemp("flown")
    with flight(d, component_args=("--record", str(d / "flight.mcap"),
                                   "--time-limit", f"{TIME_LIMIT_S}s"), lockstep=True) as f:
        status = f.component.wait(timeout=TIME_LIMIT_S + 90)
        f.sim.wait(timeout=30)  # it stops with its component
        assert status == 124, (f.folder / "component.log").read_text()[-3000:]
    return d


@pytest.mark.slow
def test_a_flight_replays_identically(flown: Path) -> None:
    rec = read_recording(flown / "flight.mcap")
    assert not rec.cut and rec.time_limit_us == TIME_LIMIT_S * 1_000_000 and rec.frames
    assert rec.stop == {"t": rec.end_us // 1000, "ev": "stop", "reason": "time_limit"}
    r = hfsmc("replay", "flight.mcap", ALLOW, cwd=flown)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout == (f"replay of flight.mcap (python -> python): identical: {len(rec.trace)} "
                        f"trace records, {len(rec.commands)} commands, "
                        f"0-{rec.end_us / 1e6:.3f} s\n")


@pytest.mark.slow
def test_a_changed_threshold_diverges_at_its_instant(flown: Path) -> None:
    """Waiting 3 s for the vehicle instead of 90: the take-off gives up at 3 s, before the
    vehicle was ready (at about 5 s in the recording)."""
    rec = read_recording(flown / "flight.mcap")
    ready = next(r.record for r in rec.trace if r.record.get("to") == "TakeOff/Climb")
    assert int(ready["t"]) > 3000, ready
    model = ROOT / "examples" / "follow_colors" / "follow_colors.yaml"
    changed = flown / "model" / "follow_colors.yaml"
    changed.parent.mkdir(exist_ok=True)
    changed.write_text(model.read_text().replace("ready_timeout: 90", "ready_timeout: 3"))
    for lib in ("takeoff.yaml", "land.yaml"):
        (flown / "lib").mkdir(exist_ok=True)
        (flown / "lib" / lib).write_text((ROOT / "examples" / "lib" / lib).read_text())
    r = hfsmc("replay", "flight.mcap", "--model", "model/follow_colors.yaml", cwd=flown)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("model/follow_colors.yaml is not the recorded model (changed: "
                               "follow_colors.yaml; hash sha256:"), lines
    line = next(n for n, text in enumerate((ROOT / "examples/lib/takeoff.yaml").read_text()
                                           .splitlines(), 1) if "to: NotReady" in text)
    assert lines[1:5] == [
        "replay of flight.mcap (python -> python): different",
        "at 3.000 s in TakeOff/WaitReady (trace record 4):",
        f"  recorded: nothing then; at {int(ready['t']) / 1000:.3f} s took TakeOff/WaitReady -> TakeOff/Climb "
        f"(when: drone.ready(); ../lib/takeoff.yaml:{line - 1})",
        "  now:      took TakeOff/WaitReady -> TakeOff/NotReady (when: elapsed() >= "
        f"ready_timeout; lib/takeoff.yaml:{line})"], r.stdout
    assert lines[-1] == NOT_EVIDENCE


@pytest.mark.slow
@pytest.mark.timeout(1500)
def test_flights_replay_across_languages(flown: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The Python flight (in lockstep) replays with the C++ twin; the twin, built by that
    replay, flies and records the same flight in real time on purpose (a recording made on the
    real clock replays too), which replays with the Python model (no other C++ build)."""
    from hfsmc.component import cache_folder
    from tests.cppbuild import need_toolchain
    from tests.support import flight

    need_toolchain()
    twin = ROOT / "examples" / "follow_colors_cpp" / "follow_colors_cpp.yaml"
    r = hfsmc("replay", "flight.mcap", "--model", str(twin), cwd=flown, timeout=1400)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.splitlines() == [
        f"{twin} is a cpp model, the recorded one (follow_colors.yaml) python: replayed as its "
        "twin", r.stdout.splitlines()[1]]
    assert r.stdout.splitlines()[1].startswith(
        "replay of flight.mcap (python -> cpp): identical: "), r.stdout

    monkeypatch.setenv("XDG_CACHE_HOME", str(flown / "cache"))
    exe = cache_folder(str(twin), "follow_colors_cpp-cpp") / "build" / "follow_colors_cpp"
    d = flown / "cpp"
    with flight(d, command=[str(exe)], component_args=(
            "--record", str(d / "flight.mcap"), "--time-limit", f"{TIME_LIMIT_S}s")) as f:
        status = f.component.wait(timeout=TIME_LIMIT_S + 90)
        f.stop_sim()
        assert status == 124, (f.folder / "component.log").read_text()[-3000:]
    rec = read_recording(d / "flight.mcap")
    assert rec.language == "cpp" and rec.stop is not None and rec.frames
    model = ROOT / "examples" / "follow_colors" / "follow_colors.yaml"
    r = hfsmc("replay", "flight.mcap", "--model", str(model), cwd=d)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.splitlines()[1] == (
        f"replay of flight.mcap (cpp -> python): identical: {len(rec.trace)} trace records, "
        f"{len(rec.commands)} commands, 0-{rec.end_us / 1e6:.3f} s"), r.stdout
