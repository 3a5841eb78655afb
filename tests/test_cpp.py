"""The C++ component (docs/cpp.md): CMake projects that build with no other step, compile
errors at model positions, hostile names and strings, signals, the monitor, config.

Behaviour is checked by the conformance suite (tests/test_conformance.py runs every
model's C++ twin, also under ASan/UBSan); this file checks what is C++-specific.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import ROOT, examples
from tests.cppbuild import Superbuild, generate, need_toolchain

pytestmark = pytest.mark.timeout(1800)  # the first test of a session compiles the projects
TIMEOUT = 60.0

# Names and strings that could break generated C++: keywords as state names, comment
# and directive look-alikes, quotes, backslashes, non-ASCII, NUL.
HOSTILE_SNIPPET_TEXT = 'x */ #line 1 "evil.h" \\" """ é 😀 \\\\'
HOSTILE_MODEL = '''hfsm: 1
name: hostile_{lang}
language: {lang}
description: "ends with a backslash \\\\ and holds */ and #line 3"
parameters:
  greeting: {{type: str, default: "nul\\0 and \\"quotes\\" é"}}
variables:
  n: 0
period: 10ms
initial: class
states:
  class:
    entry: log(greeting){semi}
    transitions:
      - name: "*/ weird \\" name é \\\\"
        to: int
        after: 20ms
  int:
    entry: |
      n += 1{semi}
      log({text}){semi}
    transitions:
      - {{to: delete, when: n >= 1}}
  delete: {{final: true}}
'''


def hostile_model(lang: str) -> str:
    """The hostile model with its snippets in ``lang`` (python or cpp)."""
    text = repr(HOSTILE_SNIPPET_TEXT) if lang == "python" else cpp_literal(HOSTILE_SNIPPET_TEXT)
    return HOSTILE_MODEL.format(lang=lang, semi=";" if lang == "cpp" else "", text=text)


def cpp_literal(text: str) -> str:
    return '"' + "".join(f"\\{b:03o}" if not 0x20 <= b < 0x7F or chr(b) in '"\\?' else chr(b)
                         for b in text.encode("utf-8")) + '"'


@pytest.fixture(scope="session")
def project(tmp_path_factory: pytest.TempPathFactory) -> Superbuild:
    """The C++ examples and the hostile model, generated and compiled once (-Werror)."""
    need_toolchain()
    models = tmp_path_factory.mktemp("models")
    hostile = models / "hostile_cpp.yaml"
    hostile.write_text(hostile_model("cpp"),
                       "utf-8")
    last = models / "last_cpp.yaml"
    last.write_text(LAST_INSTANT, "utf-8")
    return Superbuild(tmp_path_factory.mktemp("cpp"), [*examples("cpp"), hostile, last])


def run(cmd: list[str], **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT, **kw)  # type: ignore[call-overload, no-any-return]


def python_trace(model: Path, tmp: Path, *args: str) -> str:
    out = tmp / "py"
    r = run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(model), "-o", str(out)])
    assert r.returncode == 0, r.stderr
    name = re.search(r"^name:\s*(\w+)", model.read_text("utf-8"), re.M)
    assert name
    r = run([sys.executable, str(out / f"{name.group(1)}.py"), "--clock", "virtual", "--trace", "-",
             *args])
    assert r.returncode in (0, 130), r.stderr
    return r.stdout


def test_examples_exist_in_cpp() -> None:
    assert examples("cpp"), "no C++ example (examples/NAME/NAME.yaml with language: cpp)"


@pytest.mark.parametrize("example", examples("cpp"), ids=lambda p: p.stem)
def test_example_builds_with_plain_cmake_and_runs(example: Path, tmp_path: Path) -> None:
    """docs/cpp.md: `cmake -S DIR -B DIR/build && cmake --build DIR/build`, nothing else."""
    need_toolchain()
    out = tmp_path / "component"
    generate(example, out)
    assert (out / "CMakeLists.txt").is_file() and (out / f"{example.stem}.yaml").is_file()
    for step in (["cmake", "-S", str(out), "-B", str(out / "build")],
                 ["cmake", "--build", str(out / "build"), "-j", str(os.cpu_count() or 2)]):
        r = subprocess.run(step, capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    exe = out / "build" / example.stem
    if "interfaces:" in example.read_text("utf-8"):
        return  # a drone example: it flies in the simulator in tests/test_missions.py
    r = run([str(exe), "--clock", "virtual", "--until", "20s", "--trace", "-"])
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[0] == f'{{"t":0,"ev":"start","name":"{example.stem}"}}'


@pytest.mark.parametrize("name", ["blinker", "regions_arm"])
def test_cpp_example_traces_like_its_python_twin(project: Superbuild, tmp_path: Path,
                                                 name: str) -> None:
    """examples/NAME_cpp gives the trace of examples/NAME, byte for byte (regions_arm: three
    regions at different periods, one with history, done() when all are final)."""
    twin = ROOT / f"examples/{name}_cpp/{name}_cpp.yaml"
    cpp = run([str(project.executable(twin)), "--clock", "virtual", "--trace", "-"])
    assert cpp.returncode == 0, cpp.stderr
    py = python_trace(ROOT / f"examples/{name}/{name}.yaml", tmp_path)
    assert cpp.stdout.replace(f'"name":"{name}_cpp"', f'"name":"{name}"') == py
    assert py.count('"ev":"fire"') > 20
    assert py.splitlines()[-1].endswith('"ev":"stop","reason":"final"}')
    if name == "regions_arm":  # back from Charging: Cycle resumes at Grip, Led and Battery restart
        assert ('{"t":2000,"ev":"enter","state":"Working/Cycle/Grip"}\n'
                '{"t":2000,"ev":"enter","state":"Working/Led/Lit"}\n'
                '{"t":2000,"ev":"enter","state":"Working/Battery/Ok"}\n') in py


def test_hostile_names_and_strings_compile_and_trace_like_python(project: Superbuild,
                                                                   tmp_path: Path) -> None:
    hostile = next(m for m in project.models if m.name == "hostile_cpp.yaml")
    cpp = run([str(project.executable(hostile)), "--clock", "virtual", "--trace", "-"])
    assert cpp.returncode == 0, cpp.stderr
    py_model = tmp_path / "hostile_python.yaml"
    py_model.write_text(hostile_model("python"), "utf-8")
    py = python_trace(py_model, tmp_path)
    assert cpp.stdout.replace("hostile_cpp", "hostile_python") == py
    logs = [json.loads(line)["msg"] for line in py.splitlines() if '"ev":"log"' in line]
    assert logs == ['nul\0 and "quotes" é', HOSTILE_SNIPPET_TEXT]


def test_generated_source_keeps_comments_on_one_line(project: Superbuild) -> None:
    hostile = next(m for m in project.models if m.name == "hostile_cpp.yaml")
    src = (project.folder(hostile) / "src/hostile_cpp.cpp").read_text("utf-8")
    for line in src.splitlines():
        if line.lstrip().startswith("//"):
            assert not line.endswith("\\"), line


SNIPPET_ERRORS = '''hfsm: 1
name: typo
language: cpp
variables:
  count: 0
initial: A
states:
  A:
    entry: |
      count += 1;
      std::string s = count;
    during: undefined_thing();
    transitions:
      - to: B
        when: count > "x"
  B: {final: true}
'''


def test_compile_reports_snippet_errors_at_model_positions(tmp_path: Path) -> None:
    need_toolchain()
    model = tmp_path / "typo.yaml"
    model.write_text(SNIPPET_ERRORS, "utf-8")
    out = tmp_path / "typo"
    r = run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp", model.name, "-o", str(out),
             "--compile"], cwd=tmp_path)
    assert r.returncode == 1
    assert "Traceback" not in r.stderr
    found = re.findall(r"^typo\.yaml:(\d+):(\d+): error\[E144\]", r.stderr, re.M)
    # line 11: `std::string s = count;` (col 23: `count`); 12: the undefined name (col 13);
    # 15: comparing a number with a string literal.
    assert ("11", "23") in found, r.stderr
    assert ("12", "13") in found, r.stderr
    assert any(line == "15" for line, _ in found), r.stderr
    assert "std::string s = count;" in r.stderr  # the model's line is shown under the message


def test_compile_succeeds_and_says_where_the_executable_is(tmp_path: Path) -> None:
    need_toolchain()
    out = tmp_path / "blinker_cpp"
    r = run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp",
             "examples/blinker_cpp/blinker_cpp.yaml", "-o", str(out), "--compile"], cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert os.access(out / "build/blinker_cpp", os.X_OK)
    again = run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp",
                 "examples/blinker_cpp/blinker_cpp.yaml", "-o", str(out), "--compile"], cwd=ROOT)
    assert again.returncode == 0 and "up to date" in again.stderr


def test_sigint_with_nested_composites_lands_in_on_interrupt(project: Superbuild) -> None:
    """VisualStates' C++ output crashed on Ctrl+C with nested sub-automata."""
    exe = project.executable(ROOT / "examples/blinker_cpp/blinker_cpp.yaml")
    with subprocess.Popen([str(exe), "--trace", "-"], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True) as proc:
        assert proc.stdout is not None
        for line in proc.stdout:
            if '"enter","state":"Blinking/Dark"' in line:
                proc.send_signal(signal.SIGINT)
                break
        out, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 130, err
    lines = out.splitlines()
    assert '"ev":"interrupt","reason":"sigint","to":"Done"' in "".join(lines)
    assert lines[-1].endswith('"ev":"stop","reason":"sigint"}')
    assert "stopped (sigint)" in err


def test_second_signal_inside_a_long_snippet_ends_at_once(tmp_path: Path) -> None:
    need_toolchain()
    model = tmp_path / "stuck.yaml"
    model.write_text('''hfsm: 1
name: stuck
language: cpp
imports: ["<thread>", "<chrono>"]
period: 10ms
initial: Run
on_interrupt: Stuck
states:
  Run:
    transitions: [{to: Stuck, when: "false"}]
  Stuck:
    entry: log("stuck"); std::this_thread::sleep_for(std::chrono::seconds(30));
    transitions: [{to: Done, after: 10ms}]
  Done: {final: true}
''', "utf-8")
    out = tmp_path / "stuck"
    r = run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp", str(model), "-o", str(out),
             "--compile"], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    for clock in ("real", "virtual"):
        trace = tmp_path / f"{clock}.jsonl"
        with subprocess.Popen([str(out / "build/stuck"), "--trace", str(trace), "--clock", clock],
                              stderr=subprocess.PIPE, text=True) as proc:
            assert proc.stderr is not None
            time.sleep(0.3)
            proc.send_signal(signal.SIGINT)  # the interrupt enters Stuck, which blocks
            for line in proc.stderr:
                if "stuck" in line:
                    break
            started = time.monotonic()
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=TIMEOUT)
        assert proc.returncode == 130
        assert time.monotonic() - started < 10  # not the 30 s of the snippet
        records = [json.loads(r) for r in trace.read_text().splitlines()]
        assert records[-1]["ev"] == "stop" and records[-1]["reason"] == "sigint"
        [interrupt] = [r for r in records if r["ev"] == "interrupt"]
        if clock == "virtual":  # the stop record's time is the engine's, the interrupt's
            assert records[-1]["t"] == interrupt["t"] > 0, (interrupt, records[-1])
        else:  # the later of the engine's and the real clock's
            assert records[-1]["t"] >= interrupt["t"] > 0, (interrupt, records[-1])


def test_config_file_beside_the_component_and_bad_config(project: Superbuild,
                                                         tmp_path: Path) -> None:
    twin = ROOT / "examples/blinker_cpp/blinker_cpp.yaml"
    exe = project.executable(twin)
    config = project.folder(twin) / "blinker_cpp.yaml"
    data = json.loads("\n".join(ln for ln in config.read_text().splitlines()
                                if not ln.startswith("#")))
    assert data["parameters"] == {"blinks": 10}
    own = tmp_path / "two.yaml"
    own.write_text("parameters:\n  blinks: 2\n")  # any YAML: yaml-cpp reads it
    r = run([str(exe), "--clock", "virtual", "--trace", "-", "--config", str(own)])
    assert r.returncode == 0 and "stopped after 2 blinks" in r.stderr, r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("parameters: {blinks: [1,\n")
    r = run([str(exe), "--config", str(bad)])
    assert r.returncode == 2 and f"{bad}:" in r.stderr, r.stderr
    r = run([str(exe), "--param", "blinks=many"])
    assert r.returncode == 2 and "parameter `blinks` is an int" in r.stderr
    r = run([str(exe), "--until", "soon"])
    assert r.returncode == 2 and "not a duration" in r.stderr


def test_hfsmc_view_watches_a_cpp_component(project: Superbuild) -> None:
    exe = project.executable(ROOT / "examples/blinker_cpp/blinker_cpp.yaml")
    with subprocess.Popen([str(exe), "--monitor", "0", "--until", "4s"], stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True) as comp:
        assert comp.stderr is not None
        line = comp.stderr.readline()
        m = re.search(r"monitor: listening on (\S+)", line)
        assert m, line
        view = run([sys.executable, "-m", "hfsmc", "view", m.group(1)])
        comp.wait(timeout=TIMEOUT)
    assert view.returncode == 0, view.stderr
    assert "in Blinking/" in view.stdout
    assert "hfsmc view: component stopped (until)" in view.stdout + view.stderr


# The transition that stops the run changes a variable: samples are 100 ms apart, and the
# stop takes one more (tests/test_monitor.py checks the Python component alike).
LAST_INSTANT = """\
hfsm: 1
name: last_cpp
language: cpp
variables: {legs: 0}
initial: A
states:
  A: {transitions: [{to: Done, after: 2s, do: "legs += 2;"}]}
  Done: {final: true}
"""


def test_the_last_sample_of_a_cpp_component_has_the_values_it_ended_with(project: Superbuild) -> None:
    exe = project.executable(project.models[-1])
    with subprocess.Popen([str(exe), "--monitor", "0"], stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True) as comp:
        assert comp.stderr is not None
        m = re.search(r"monitor: listening on 127\.0\.0\.1:(\d+)", comp.stderr.readline())
        assert m
        got = b""
        with socket.create_connection(("127.0.0.1", int(m.group(1))), timeout=TIMEOUT) as sock:
            while chunk := sock.recv(1 << 16):
                got += chunk
        assert comp.wait(timeout=TIMEOUT) == 0
    msgs = [json.loads(line) for line in got.splitlines()]
    assert msgs[-1] == {"type": "bye", "reason": "final"}
    samples = [msg["variables"] for msg in msgs if msg["type"] == "sample"]
    assert samples[0] == {"legs": "0"} and samples[-1] == {"legs": "2"}, samples[-3:]


def test_hfsmc_run_compiles_a_cpp_model_into_the_cache_and_runs_it(tmp_path: Path) -> None:
    need_toolchain()
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    r = run([sys.executable, "-m", "hfsmc", "run", "examples/blinker_cpp/blinker_cpp.yaml", "--",
             "--clock", "virtual", "--until", "3s", "--trace", "-"], cwd=ROOT, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-1] == '{"t":3000,"ev":"stop","reason":"until"}'
    assert list((tmp_path / "cache/hfsmc/run").glob("blinker_cpp-cpp-*/build/blinker_cpp"))
