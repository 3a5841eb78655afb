"""Reliability (issue 7): hostile model files, `kill -9` of a build, runtime faults.

Every attack here runs hfsmc or a generated component as a real process, bounded
in time, and cleans it up.  What these tests prove and the figures of a run are
in docs/reliability.md.  Covered elsewhere, not repeated here: the bad models
of tests/invalid/ (tests/test_invalid.py, which now also holds the alias bomb,
the network entity and the NUL snippet added for this issue), an exception in
every snippet kind (tests/test_conformance.py), garbage, floods and killed
viewers on the monitor port (tests/test_monitor.py), link loss, garbage
datagrams and SIGINT in flight (tests/test_missions.py, tests/test_drivers.py,
tests/test_sim_vehicle.py).
"""

from __future__ import annotations

import json
import random
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from hfsmc.frontend.source import MAX_FILE_BYTES
from hfsmc.fsutil import write_tree
from tests.conftest import ROOT

HFSMC = [sys.executable, "-m", "hfsmc"]
EXIT_OF_REASON = {"final": 0, "until": 0, "shutdown": 0, "sigint": 130, "sigterm": 143}
GIB_IN_KIB = 1024 * 1024


def hfsmc(*args: str, cwd: Path = ROOT, timeout: float = 120,
          ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*HFSMC, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def build(tmp: Path, name: str, text: str) -> Path:
    """Write the model, build it, return the component's main file."""
    model = tmp / f"{name}.yaml"
    model.write_text(text, "utf-8")
    r = hfsmc("build", str(model), "-o", str(tmp / f"{name}_component"))
    assert r.returncode == 0, r.stderr
    return tmp / f"{name}_component" / f"{name}.py"


def run_component(main: Path, *args: str, timeout: float = 60,
                  ) -> subprocess.CompletedProcess[str]:
    """A component runs with the standard library alone: no site-packages, no hfsmc."""
    return subprocess.run([sys.executable, "-I", "-S", str(main), *args], capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def records(trace: str) -> list[dict[str, Any]]:
    """Every line of a trace is one JSON object (a line that is not fails the test)."""
    out = []
    for n, line in enumerate(trace.splitlines(), 1):
        rec = json.loads(line)
        assert isinstance(rec, dict) and "ev" in rec, f"trace line {n}: {line!r}"
        out.append(rec)
    return out


def check_nesting(recs: list[dict[str, Any]]) -> None:
    """Enters and exits nest: a state is entered inside an active parent, exited when active
    and after its active children; the last record is `stop`."""
    assert recs and recs[0]["ev"] == "start", recs[:1]
    assert recs[-1]["ev"] == "stop", recs[-1:]
    assert [r["ev"] for r in recs].count("stop") == 1
    active: set[str] = set()
    for r in recs:
        path = r.get("state", "")
        if r["ev"] == "enter":
            parent = path.rpartition("/")[0]
            assert path not in active and (not parent or parent in active), (r, active)
            active.add(path)
        elif r["ev"] == "exit":
            assert path in active, (r, active)
            assert not any(a.startswith(path + "/") for a in active), (r, active)
            active.remove(path)


# ---------------------------------------------------------------------------
# Hostile model files

# Runs a command and prints the largest resident set of its process tree (KiB) on the last
# line of stderr: RUSAGE_CHILDREN of this fresh interpreter sees that one command only.
_MEASURE = """
import resource, subprocess, sys
r = subprocess.run(sys.argv[1:], capture_output=True, timeout=120)
sys.stdout.buffer.write(r.stdout)
sys.stderr.buffer.write(r.stderr)
sys.stderr.write(f"\\nmaxrss-kib {resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}\\n")
sys.exit(r.returncode)
"""


def measured(*args: str) -> tuple[subprocess.CompletedProcess[str], int]:
    r = subprocess.run([sys.executable, "-c", _MEASURE, *HFSMC, *args], cwd=ROOT,
                       capture_output=True, text=True, timeout=150, stdin=subprocess.DEVNULL)
    m = re.search(r"\nmaxrss-kib (\d+)\n\Z", r.stderr)
    assert m, r.stderr[-2000:]
    return r, int(m.group(1))


def deep_yaml(depth: int) -> str:
    return ("hfsm: 1\nname: deep\ninitial: S\nstates:\n  S: "
            + "{initial: S, states: {S: " * depth + "{final: true}" + "}}" * depth + "\n")


def deep_xml(depth: int) -> str:
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<hfsm version="1" name="deep">\n'
            '<automaton initial="S">\n' + '<state name="S">\n<automaton initial="S">\n' * depth
            + '<state name="S" final="true"/>\n' + "</automaton>\n</state>\n" * depth
            + "</automaton>\n</hfsm>\n")


@pytest.mark.parametrize("kind", ["yaml", "xml"])
def test_10000_deep_state_nesting_is_a_positioned_e006(kind: str, tmp_path: Path) -> None:
    text = deep_yaml(10_000) if kind == "yaml" else deep_xml(10_000)
    path = tmp_path / f"deep.{kind}"
    path.write_text(text, "utf-8")
    r, rss_kib = measured("check", str(path))
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stdout + r.stderr and "RecursionError" not in r.stdout + r.stderr
    m = re.search(rf"^{re.escape(str(path))}:(\d+):(\d+): error\[E006\]", r.stderr, re.M)
    assert m, r.stderr
    assert int(m.group(1)) >= 1 and int(m.group(1)) <= text.count("\n"), m.group(0)
    # A 20,000-level document held in memory whole would still fit; the bound is far above
    # what the check uses (about 40 MiB) and far below what an expansion would take.
    assert rss_kib < GIB_IN_KIB, f"max RSS {rss_kib} KiB"


def test_a_file_over_the_size_limit_is_refused_unread(tmp_path: Path) -> None:
    path = tmp_path / "huge.yaml"
    head = b"hfsm: 1\nname: huge\ninitial: A\nstates: {A: {final: true}}\n"
    with open(path, "wb") as f:
        f.write(head)
        f.write(b"# " + b"x" * (MAX_FILE_BYTES - len(head)) + b"\n")
    r, rss_kib = measured("check", str(path))
    assert r.returncode == 1
    assert re.search(rf"^{re.escape(str(path))}:1:1: error\[E001\]", r.stderr, re.M), r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert rss_kib < MAX_FILE_BYTES // 1024, f"max RSS {rss_kib} KiB: the file was read whole"


# State names that are keywords or builtins of Python (and of C++), or spell the generated
# code's own symbols; variables and functions named after modules and runtime names.
NAMES_MODEL = """\
hfsm: 1
name: names
imports: [math]
variables:
  hits: 0
  sys: 1
  os: 2
  json: 3
  time: 4
  signal: 5
  Engine: 6
functions: |
  def main():
      return sys + os + json + time + signal + Engine
  def setup(x):
      return x
initial: class
on_interrupt: int
states:
  class:
    entry: |
      hits += 1
      log("class " + str(main()))
    transitions: [{to: _hfsm_tick_0, after: 100ms}]
  _hfsm_tick_0:
    initial: def
    states:
      def: {transitions: [{to: lambda, when: elapsed() >= 0.1}]}
      lambda: {final: true}
    transitions: [{to: None, when: done()}]
  None: {transitions: [{to: self, after: 100ms, do: 'log("do " + str(setup(hits)))'}]}
  self: {transitions: [{to: __init__, after: 100ms}]}
  __init__: {transitions: [{to: main, after: 100ms}]}
  main: {transitions: [{to: log, after: 100ms}]}
  log: {transitions: [{to: 'True', after: 100ms}]}
  'True': {transitions: [{to: import, after: 100ms}]}
  import: {transitions: [{to: _hfsm, after: 100ms}]}
  _hfsm: {transitions: [{to: _hfsm_rt, after: 100ms}]}
  _hfsm_rt: {transitions: [{to: namespace, after: 100ms}]}
  namespace: {transitions: [{to: template, after: 100ms}]}
  template: {transitions: [{to: Engine, after: 100ms}]}
  Engine: {entry: 'log(active("_hfsm_tick_0"))', transitions: [{to: int, after: 100ms}]}
  int: {final: true, entry: 'log(hits)'}
"""


def run_virtual(tmp_path: Path, name: str, model: str) -> list[dict[str, Any]]:
    """Build a model, run it to its end on the virtual clock: its well-nested trace."""
    r = run_component(build(tmp_path, name, model), "--clock", "virtual", "--trace", "-")
    assert r.returncode == 0, r.stderr
    recs = records(r.stdout)
    check_nesting(recs)
    return recs


def test_keyword_and_runtime_symbol_names_build_and_run(tmp_path: Path) -> None:
    recs = run_virtual(tmp_path, "names", NAMES_MODEL)
    entered = [x["state"] for x in recs if x["ev"] == "enter"]
    assert entered == ["class", "_hfsm_tick_0", "_hfsm_tick_0/def", "_hfsm_tick_0/lambda",
                       "None", "self", "__init__", "main", "log", "True", "import", "_hfsm",
                       "_hfsm_rt", "namespace", "template", "Engine", "int"]
    assert [x["msg"] for x in recs if x["ev"] == "log"] == ["class 21", "do 1", "False", "1"]
    assert recs[-1] == {"t": 1500, "ev": "stop", "reason": "final"}


# Snippet strings holding the template's delimiters, triple quotes, C comment ends,
# `#line` directives, backslashes and line separators: generated code stays valid and
# the trace logs every string as it was written.
# <DQ3> and <SQ3> stand for three double and three single quotes (this file is Python).
DELIMITERS_MODEL = r"""hfsm: 1
name: delims
description: '{{ name }} {% raw %} <DQ3> */ #line 1 \ \\'
variables:
  s: "{{ s }} \"\"\" */"
parameters:
  p: {type: str, default: "{% endraw %} <SQ3> \\ #line 9"}
initial: A
functions: |
  def f():
      <DQ3>{{ doc }} {% endraw %} <SQ3> */<DQ3>
      return <SQ3>{% for x in y %}<SQ3>
on_shutdown: 'log("*/ {{ end }}")'
states:
  A:
    entry: |
      log("{{ jinja }} {% block %} {# c #}")
      log(f())
      log(<DQ3>triple "quoted" <SQ3> <DQ3>)
      log("/* c */ */ #line 1 \"x.c\"")
      log('back\\slash \\n \\x00 \\')
      log(s + "}}")
      log(p)
    during: |
      #line 42 "evil.c"
      pass  # */ {{ }} <DQ3>
    transitions:
      - to: B
        after: 100ms
        do: 'log("\\\\ {%- -%} \u2028 {{")'
  B: {final: true}
""".replace("<DQ3>", '"' * 3).replace("<SQ3>", "'" * 3)
DELIMITER_LOGS = [
    "{{ jinja }} {% block %} {# c #}",
    "{% for x in y %}",
    "triple \"quoted\" ''' ",
    '/* c */ */ #line 1 "x.c"',
    "back\\slash \\n \\x00 \\",
    '{{ s }} """ */}}',
    "{% endraw %} ''' \\ #line 9",
    "\\\\ {%- -%} \u2028 {{",
    "*/ {{ end }}",
]


def test_snippets_with_template_delimiters_are_kept_verbatim(tmp_path: Path) -> None:
    recs = run_virtual(tmp_path, "delims", DELIMITERS_MODEL)
    assert [x["msg"] for x in recs if x["ev"] == "log"] == DELIMITER_LOGS


@pytest.mark.parametrize("description", ['say "hi"', "a\0b"], ids=["final_quote", "nul"])
def test_any_description_gives_a_component_that_compiles(description: str,
                                                         tmp_path: Path) -> None:
    model = ("hfsm: 1\nname: desc\ndescription: " + json.dumps(description)
             + "\ninitial: A\nstates: {A: {final: true}}\n")
    r = run_component(build(tmp_path, "desc", model), "--clock", "virtual")
    assert r.returncode == 0, r.stderr


def test_a_reused_anchor_prints_no_library_warning(tmp_path: Path) -> None:
    path = tmp_path / "anchors.yaml"
    path.write_text("hfsm: 1\nname: anchors\ninitial: A\nstates:\n  A: &s {final: true}\n"
                    "  B: &s {final: true}\n", "utf-8")
    r = hfsmc("check", str(path))
    assert "Warning" not in r.stderr and "<unicode string>" not in r.stderr, r.stderr


# ---------------------------------------------------------------------------
# Atomic output: kill -9 of `hfsmc build` at random moments

def big_model(states: int, variant: int) -> str:
    lines = ["hfsm: 1", "name: big", "variables:", "  k: 0", "initial: S0", "states:"]
    for i in range(states):
        lines += [f"  S{i}:", f"    entry: k = {i} + {variant}",
                  f"    transitions: [{{to: S{(i + 1) % states}, after: 100ms}}]"]
    return "\n".join(lines) + "\n"


def folder_bytes(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def stages(parent: Path, name: str) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(f".{name}."))


def test_kill_9_during_build_leaves_the_old_or_the_new_component(tmp_path: Path) -> None:
    for v in (0, 1):
        (tmp_path / f"v{v}").mkdir()
        (tmp_path / f"v{v}" / "big.yaml").write_text(big_model(2000, v), "utf-8")
    out = tmp_path / "out"

    def command(v: int) -> list[str]:
        return [*HFSMC, "build", f"v{v}/big.yaml", "-o", "out"]

    reference: dict[int, dict[str, bytes]] = {}
    duration = 0.0
    for v in (0, 1):  # the second build replaces a component, as the killed ones do
        t0 = time.monotonic()
        subprocess.run(command(v), cwd=tmp_path, check=True, capture_output=True, timeout=120)
        duration = time.monotonic() - t0
        reference[v] = folder_bytes(out)
    assert reference[0] != reference[1] and set(reference[0]) == set(reference[1])
    current = 1
    rng = random.Random(1)
    # 15 kills at uniform moments of the build, then 10 aimed at its writing phase: a short,
    # random time after the staging folder appears beside the target.
    plan: list[float | None] = [rng.uniform(0, duration) for _ in range(15)] + [None] * 10
    outcomes = []
    staged = 0  # kills that landed while a staging folder stood beside the target
    for delay in plan:
        new = 1 - current
        proc = subprocess.Popen(command(new), cwd=tmp_path, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            if delay is None:
                deadline = time.monotonic() + 60
                while not stages(tmp_path, "out") and proc.poll() is None:
                    assert time.monotonic() < deadline, "the build neither staged nor ended"
                    time.sleep(0.0005)
                time.sleep(rng.uniform(0, 0.02))
            else:
                time.sleep(delay)
            staged += bool(stages(tmp_path, "out")) and proc.poll() is None
            proc.send_signal(signal.SIGKILL)
        finally:
            proc.kill()
            proc.wait(30)
        assert out.is_dir(), "the component folder is gone"
        now = folder_bytes(out)
        assert now in (reference[0], reference[1]), (
            f"half-written component after kill -9 at {delay}: "
            f"{sorted(k for k in now if now[k] != reference[new].get(k))}")
        outcomes.append("new" if now == reference[new] else "old")
        current = new if now == reference[new] else current
    assert "old" in outcomes  # the kills did land before the swap
    left = len(stages(tmp_path, "out"))
    print(f"kill -9: {len(plan)} builds killed ({staged} while staging), "
          f"{outcomes.count('old')} left the old component, {outcomes.count('new')} the new, "
          f"{left} staging folder(s) left until the next build")
    # A later build after all those kills works and clears the stages the killed ones left.
    new = 1 - current
    subprocess.run(command(new), cwd=tmp_path, check=True, capture_output=True, timeout=120)
    assert folder_bytes(out) == reference[new]
    assert stages(tmp_path, "out") == []
    r = run_component(out / "big.py", "--clock", "virtual", "--until", "1s")
    assert r.returncode == 0, r.stderr


def test_a_build_removes_only_the_stages_of_dead_builds(
        tmp_path: Path, processes: list[subprocess.Popen[bytes]]) -> None:
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    processes.append(live)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait(30)
    kept = [f".v.{live.pid}.abc_1.new", f".v.2.{dead.pid}.abc_1.new", f".v.{dead.pid}.x.y.new",
            f".w.{dead.pid}.abc_1.new"]  # a live build; a stage of `v.2`; no stage; one of `w`
    gone = [f".v.{dead.pid}.abc_1.new"]
    for name in kept + gone:
        (tmp_path / name).mkdir()
        (tmp_path / name / "v.py").write_bytes(b"half")
    write_tree(tmp_path / "v", {"v.py": b"whole"})
    assert (tmp_path / "v" / "v.py").read_bytes() == b"whole"
    assert stages(tmp_path, "v") + stages(tmp_path, "w") == sorted(kept)


# ---------------------------------------------------------------------------
# Runtime faults of the Python component

SLOW_MODEL = """\
hfsm: 1
name: slow
imports: [time]
period: 100ms
variables:
  n: 0
initial: Busy
on_interrupt: Stopped
states:
  Busy:
    during: |
      n += 1
      log("sleep " + str(n))
      time.sleep(0.35)
      log("woke " + str(n))
    transitions: [{to: Done, when: n >= 40}]
  Done: {final: true}
  Stopped: {entry: 'log("interrupted")', final: true}
"""


def wait_for(path: Path, pattern: str, proc: subprocess.Popen[bytes],
             timeout: float = 30) -> re.Match[str]:
    """Poll a growing file until a line matches (the process must still run)."""
    deadline = time.monotonic() + timeout
    while True:
        text = path.read_text("utf-8", "replace")
        m = re.search(pattern, text, re.M)
        if m:
            return m
        assert proc.poll() is None and time.monotonic() < deadline, (pattern, text)
        time.sleep(0.005)


@pytest.fixture
def processes() -> Iterator[list[subprocess.Popen[bytes]]]:
    made: list[subprocess.Popen[bytes]] = []
    yield made
    for p in made:
        if p.poll() is None:
            p.kill()
        p.wait(10)


def start(processes: list[subprocess.Popen[bytes]], main: Path, err: Path,
          *args: str) -> subprocess.Popen[bytes]:
    with open(err, "wb") as f:
        proc = subprocess.Popen([sys.executable, "-I", "-S", str(main), *args],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=f)
    processes.append(proc)
    return proc


def test_a_blocking_snippet_counts_overruns_and_sigint_stops_after_it(
        tmp_path: Path, processes: list[subprocess.Popen[bytes]]) -> None:
    main = build(tmp_path, "slow", SLOW_MODEL)
    err, trace = tmp_path / "slow.err", tmp_path / "slow.trace"
    proc = start(processes, main, err, "--monitor", "0", "--trace", str(trace))
    port = int(wait_for(err, r"^monitor: listening on 127\.0\.0\.1:(\d+)$", proc).group(1))
    with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
        wait_for(err, r"Busy: sleep 3$", proc)
        proc.send_signal(signal.SIGINT)  # while the third `during` sleeps
        received = b""
        while chunk := sock.recv(65536):  # until the component closes the connection
            received += chunk
    assert proc.wait(30) == 130
    messages = [json.loads(line) for line in received.splitlines()]
    counts = [m["overruns"] for m in messages if m["type"] in ("snapshot", "sample")]
    # Each tick takes 350 ms of a 100 ms period: 3 deadlines skipped per tick, 6 by the
    # third tick. At least one sample follows the first tick, whatever the load.
    assert counts and max(counts) >= 3, counts
    assert counts == sorted(counts), counts
    assert messages[-1] == {"type": "bye", "reason": "sigint"}
    recs = records(trace.read_text("utf-8"))
    check_nesting(recs)
    logs = [(x["t"], x["msg"]) for x in recs if x["ev"] == "log"]
    sleeps = [msg for _, msg in logs if msg.startswith("sleep ")]
    last = int(sleeps[-1].split()[1])
    # The signal came while `sleep 3` ran; `sleep 4` is allowed only if this test process was
    # descheduled for the whole 350 ms between reading the line and sending the signal.
    assert last in (3, 4), logs
    woke_t = next(t for t, msg in logs if msg == f"woke {last}")
    interrupt = next(x for x in recs if x["ev"] == "interrupt")
    # Stopped within the tick of the blocking snippet: the interrupt is recorded at that
    # tick's instant, no other snippet ran in between.
    assert interrupt == {"t": woke_t, "ev": "interrupt", "reason": "sigint", "to": "Stopped"}
    assert logs[-3:] == [(woke_t, f"sleep {last}"), (woke_t, f"woke {last}"),
                         (woke_t, "interrupted")]
    assert recs[-1] == {"t": woke_t, "ev": "stop", "reason": "sigint"}


SIGNALS_MODEL = """\
hfsm: 1
name: sigs
period: 20ms
variables:
  n: 0
  junk: 0
functions: |
  def work():
      global junk
      junk = sum(range(30000))
initial: Work
on_interrupt: Closing
on_shutdown: 'work(); log("shutdown")'
states:
  Work:
    period: 10ms
    initial: A
    entry: 'work(); log("work in")'
    exit: 'work(); log("work out")'
    states:
      A:
        entry: 'n += 1; work()'
        during: work()
        exit: 'work(); log("a out")'
        transitions: [{to: B, after: 30ms}]
      B:
        entry: 'work(); log("b in")'
        exit: work()
        transitions: [{to: A, after: 30ms, do: work()}]
    transitions: [{to: Done, when: n >= 12}]
  Closing:
    entry: 'work(); log("closing")'
    during: work()
    exit: 'work(); log("closing out")'
    transitions: [{to: Bye, after: 60ms}]
  Bye: {final: true, entry: 'work(); log("bye")'}
  Done: {final: true}
"""


def test_sigint_and_sigterm_at_random_moments(
        tmp_path: Path, processes: list[subprocess.Popen[bytes]]) -> None:
    main = build(tmp_path, "sigs", SIGNALS_MODEL)
    rng = random.Random(1)
    statuses = []
    seconds = 0  # runs that got a second signal
    for run in range(10):
        err, trace = tmp_path / f"sigs{run}.err", tmp_path / f"sigs{run}.trace"
        proc = start(processes, main, err, "--trace", str(trace))
        wait_for(err, r"Work: work in$", proc)  # the handlers are in place from here on
        first = rng.choice([signal.SIGINT, signal.SIGTERM])
        time.sleep(rng.uniform(0, 0.7))  # the run lasts about 0.66 s: most runs get the signal
        proc.send_signal(first)
        second = rng.choice([None, signal.SIGINT, signal.SIGTERM])
        if second is not None:  # during the interrupt or the stop: the run ends at once
            time.sleep(rng.uniform(0, 0.08))
            if proc.poll() is None:
                proc.send_signal(second)
                seconds += 1
        status = proc.wait(30)
        recs = records(trace.read_text("utf-8"))
        check_nesting(recs)
        reason = recs[-1]["reason"]
        assert status == EXIT_OF_REASON[reason], (status, reason)
        assert status in (0, 130, 143), status
        assert "Traceback" not in err.read_text("utf-8")
        statuses.append(status)
    print(f"signals: 10 runs ({seconds} with a second signal), exit statuses {statuses}")
    assert {130, 143} & set(statuses), statuses


def test_trace_on_a_full_disk_is_said_once_and_the_run_goes_on(tmp_path: Path) -> None:
    blinker = tmp_path / "blinker"
    r = hfsmc("build", "examples/blinker/blinker.yaml", "-o", str(blinker))
    assert r.returncode == 0, r.stderr
    slow = build(tmp_path, "delims", DELIMITERS_MODEL)
    runs: list[tuple[Path, list[str]]] = [
        # virtual: the 64 KiB buffer fills and fails mid-run; real: the flush before each
        # wait fails at the first one
        (blinker / "blinker.py", ["--clock", "virtual", "--param", "blinks=400"]),
        (slow, ["--clock", "real"]),
    ]
    for main, args in runs:
        r = run_component(main, *args, "--trace", "/dev/full")
        assert r.returncode == 0, r.stderr
        lines = r.stderr.splitlines()
        said = [n for n, line in enumerate(lines) if "trace" in line]
        assert len(said) == 1, r.stderr
        assert lines[said[0]] == ("trace: cannot write to /dev/full: [Errno 28] No space left "
                                  "on device; the component goes on without its trace")
        assert "Traceback" not in r.stderr
        # The run went on to its end after the failure: its on_shutdown spoke later.
        last = "stopped after 400 blinks" if main.name == "blinker.py" else "*/ {{ end }}"
        assert any(last in line for line in lines[said[0] + 1:]), r.stderr[-2000:]
