"""Reliability (issue 7), the C++ side: random models in both back ends, runtime faults.

1. Random valid models, generated as pairs of twins (the same automaton, its snippets in
   Python and in C++, built from pairs of equivalent lines), give byte-identical traces
   and equal exit statuses on the virtual clock.  All the C++ twins compile in one
   Superbuild with warnings as errors: any valid model generates C++ that compiles.
2. Runtime faults of the C++ component, mirroring tests/test_reliability.py: a snippet
   that blocks longer than its period, SIGINT and SIGTERM at random moments, a trace on
   a full disk.  These components are built with ASan and UBSan.

What these tests prove and the figures of a run are in docs/reliability.md.
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
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from hfsmc.pipeline import compile_file
from tests.conftest import ROOT
from tests.cppbuild import Superbuild, need_toolchain
from tests.test_roundtrip import dump_yaml

pytestmark = pytest.mark.timeout(1800)  # the first test of a session compiles the projects
TIMEOUT = 120.0
EXIT_OF_REASON = {"final": 0, "until": 0, "shutdown": 0, "sigint": 130, "sigterm": 143,
                  "error": 1, "timeout": 1}
SANITIZER_REPORT = re.compile(r"ERROR: (AddressSanitizer|LeakSanitizer)|runtime error: |"
                              r"Sanitizer")


# ---------------------------------------------------------------------------
# Pairs of twin models

def cpp_string(text: str) -> str:
    """A C++ literal of ``text``'s UTF-8 bytes: octal escapes for anything not plain ASCII
    (and for `?`, against trigraphs); with a NUL, a std::string of explicit length."""
    data = text.encode("utf-8")
    body = "".join(f"\\{b:03o}" if not 0x20 <= b < 0x7F or chr(b) in '"\\?' else chr(b)
                   for b in data)
    return f'std::string("{body}", {len(data)})' if 0 in data else f'"{body}"'


# Pieces of hostile text: quotes, backslashes, comment and directive look-alikes, a
# trigraph, template delimiters, markup, non-ASCII (a line separator, an astral emoji).
PIECES = ['"', "'", "\\", "\\\\", "*/", "/*", "//", '#line 3 "evil.h"', "??/", "??=", "{{",
          "%}", "é", "😀", "\u2028", " ", "a", "Z", "0", "<&>", "\t", "]]>", 'R"(', ')"', "$"]


def hostile(rng: random.Random, nul: bool = False, newline: bool = False) -> str:
    pool = PIECES + (["\0"] if nul else []) + (["\n"] if newline else [])
    return "".join(rng.choice(pool) for _ in range(rng.randint(0, 6)))


# Raw strings cannot hold `)hf"`, and their lines are pasted verbatim: plain text, quotes,
# backslashes, directive and comment look-alikes, line breaks.
RAW_PIECES = ['"', "\\", "*/", "/*", "//", '#line 7 "raw.h"', "é", " ", "a", "\n", "'", "??/"]

# State names: keywords and builtins of C++ and Python, macros of the C library, the
# runtime's and the generated code's own symbols, the model's variable names.
STATE_NAMES = ["class", "int", "delete", "def", "lambda", "None", "True", "False", "template",
               "namespace", "std", "main", "log", "x", "s", "p", "q", "f", "operator", "auto",
               "return", "and", "not", "or", "NULL", "nullptr", "errno", "assert", "EOF",
               "stdin", "_hfsm", "_hfsm_tick_0", "hfsmc", "self", "this", "new", "switch",
               "goto", "import", "__init__", "str", "now", "done", "signal", "exit", "abort",
               "m_", "t", "owner", "cur", "private", "virtual", "co_await", "volatile", "bool",
               "unsigned", "typedef", "A", "B", "Go", "_", "__LINE__", "__FILE__", "Engine"]
DURATIONS: list[str | int] = ["1ms", "50ms", "100ms", "1s", "1.5s", "2m", 250, "0.5ms", "30ms"]
PERIODS: list[str | int] = ["1ms", "20ms", "100ms", "1s", 40, "7ms", "250ms"]
FLOATS = [0.1, 2.0, 1e16, 1e-7, -0.0, 123456789.125, 1e300, -2.5e-300, 5e-324, 0.3]


@dataclass
class Twins:
    """The same model with Python and C++ snippets; ``kinds`` counts the line kinds used."""
    seed: int
    py: dict[str, Any]
    cpp: dict[str, Any]
    kinds: Counter[str] = field(default_factory=Counter)


class PairGen:
    """Draws one pair of twin models from ``random.Random(seed)``."""

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)
        self.seed = seed
        self.kinds: Counter[str] = Counter()
        self.paths: list[str] = []
        self.functions = self.rng.random() < 0.5

    def pair(self, kind: str, py: str, cpp: str) -> tuple[str, str]:
        self.kinds[kind] += 1
        return py, cpp

    def statement(self, where: str) -> tuple[str, str]:
        r = self.rng
        options: list[Callable[[], tuple[str, str]]] = [
            lambda: self.pair("increment", "x = x + 1", "x = x + 1;"),
            self.decrement,
            lambda: self.pair("log s", "log(s)", "log(s);"),
            lambda: self.pair("log q", "log(q)", "log(q);"),
            lambda: self.pair("str int", "log(str(x))", "log(str(x));"),
            lambda: self.pair("str float", "log(str(p))", "log(str(p));"),
            lambda: self.pair("if block", "if x > 2:\n    x = 0", "if (x > 2) {\n    x = 0;\n}"),
            lambda: self.pair("escaped literal", 'log("a < b & \\"c\\"")',
                              'log("a < b & \\"c\\"");'),
            self.assign,
            self.raw_assign,
            lambda: self.pair("comment", "x += 0  # note */ /* #line 9 \"f\" é",
                              "x += 0; // note */ /* #line 9 \"f\" é"),
            lambda: self.pair("block comment", "x += 1  # spans lines",
                              "x += 1; /* spans\n#line 3 \"nope.h\"\n   lines */"),
            lambda: self.pair("now", "log(str(now()))", "log(str(now()));"),
            lambda: self.pair("elapsed", "log(str(elapsed()))", "log(str(elapsed()));"),
            self.active_log,
        ]
        if self.functions:
            options.append(lambda: self.pair("function", "log(str(f()))", "log(str(f()));"))
        roll = r.random()
        if where == "do" and roll < 0.04:
            return self.pair("shutdown", "shutdown()", "shutdown();")
        if where != "on_shutdown" and roll > 0.985:
            return self.pair("error", 'raise RuntimeError("boom */")',
                             'throw std::runtime_error("boom */");')
        return r.choice(options)()

    def decrement(self) -> tuple[str, str]:
        k = self.rng.randint(0, 9)
        return self.pair("decrement", f"x = x - {k}", f"x = x - {k};")

    def assign(self) -> tuple[str, str]:
        text = hostile(self.rng, nul=True, newline=True)
        return self.pair("assign", f"s = {text!r}", f"s = {cpp_string(text)};")

    def raw_assign(self) -> tuple[str, str]:
        text = "".join(self.rng.choice(RAW_PIECES) for _ in range(self.rng.randint(0, 8)))
        return self.pair("raw string", f"s = {text!r}", f's = R"hf({text})hf";')

    def active_log(self) -> tuple[str, str]:
        path = self.rng.choice(self.paths)
        return self.pair("active", f"log(str(active({path!r})))", f'log(str(active("{path}")));')

    def snippet(self, where: str) -> tuple[str, str]:
        lines = [self.statement(where) for _ in range(self.rng.randint(1, 3))]
        return "\n".join(p for p, _ in lines), "\n".join(c for _, c in lines)

    def when(self) -> tuple[str, str]:
        r = self.rng
        k = r.randint(-5, 5)
        text = hostile(r, nul=True)
        path = r.choice(self.paths)
        options = [
            ("gt", f"x > {k}", f"x > {k}"),
            ("done", "done()", "done()"),
            ("true", "True", "true"),
            ("false", "False", "false"),
            ("and not", "elapsed() > 0.5 and not done()", "elapsed() > 0.5 && !done()"),
            ("equal", f"s == {text!r}", f"s == {cpp_string(text)}"),
            ("or", "x < 3 or q != '<&>'", 'x < 3 || q != "<&>"'),
            ("float", "p >= 0", "p >= 0"),
            ("active", f"active({path!r})", f'active("{path}")'),
        ]
        kind, py, cpp = r.choice(options)
        return self.pair("when " + kind, py, cpp)

    def names(self, prefix: str) -> list[str]:
        r = self.rng
        pool = STATE_NAMES + [f"S{r.randint(0, 99)}" for _ in range(5)]
        names = r.sample(pool, r.randint(1, 4))
        self.paths += [prefix + n for n in names]
        return names

    def states(self, depth: int, prefix: str) -> tuple[dict[str, Any], dict[str, Any]]:
        """The (python, cpp) `states` mappings of one sub-automaton."""
        r = self.rng
        names = self.names(prefix)
        py: dict[str, Any] = {}
        cpp: dict[str, Any] = {}
        shapes: dict[str, tuple[bool, bool]] = {}
        for name in names:  # first the shapes, so that every path exists for active()
            composite = depth > 0 and r.random() < 0.45
            shapes[name] = (composite, not composite and r.random() < 0.3)
        children = {name: self.states(depth - 1, prefix + name + "/")
                    for name, (composite, _) in shapes.items() if composite}
        for name in names:
            composite, final = shapes[name]
            pn: dict[str, Any] = {}
            cn: dict[str, Any] = {}
            for kind in ("entry", "during", "exit"):
                if r.random() < 0.5:
                    pn[kind], cn[kind] = self.snippet(kind)
            if composite:
                pn["states"], cn["states"] = children[name]
                pn["initial"] = cn["initial"] = r.choice(sorted(pn["states"]))
                if r.random() < 0.5:
                    pn["period"] = cn["period"] = r.choice(PERIODS)
                if r.random() < 0.5:
                    pn["history"] = cn["history"] = r.random() < 0.5
            elif final:
                pn["final"] = cn["final"] = True
            if not final:
                pt, ct = [], []
                for _ in range(r.randint(0, 3)):
                    p: dict[str, Any] = {"to": r.choice(names)}
                    c: dict[str, Any] = {"to": p["to"]}
                    if r.random() < 0.6:
                        p["when"], c["when"] = self.when()
                    if "when" not in p or r.random() < 0.4:
                        p["after"] = c["after"] = r.choice(DURATIONS)
                    if r.random() < 0.5:
                        p["do"], c["do"] = self.snippet("do")
                    if r.random() < 0.4:
                        p["name"] = c["name"] = hostile(r, nul=True)
                    pt.append(p)
                    ct.append(c)
                if pt:
                    pn["transitions"], cn["transitions"] = pt, ct
            py[name], cpp[name] = pn, cn
        return py, cpp

    def twins(self) -> Twins:
        r = self.rng
        name = f"rnd{self.seed}"
        py: dict[str, Any] = {"hfsm": 1, "name": name, "language": "python"}
        cpp: dict[str, Any] = {"hfsm": 1, "name": name, "language": "cpp"}
        if r.random() < 0.7:
            py["description"] = cpp["description"] = hostile(r, nul=True)
        if r.random() < 0.3:
            py["imports"], cpp["imports"] = ["math"], ["<cstdint>"]
        x, s = r.randint(-10**6, 10**6), hostile(r, nul=True)
        py["variables"] = {"x": x, "s": s}
        cpp["variables"] = {"x": x, "s": s}
        py["parameters"] = cpp["parameters"] = {
            "p": {"type": "float", "default": r.choice([*FLOATS, r.uniform(-1e6, 1e6)])},
            "q": {"type": "str", "default": hostile(r, nul=True)}}
        if self.functions:
            py["functions"] = "def f():\n    return x\n"
            cpp["functions"] = "long long f() {\n    return x;\n}\n"
        root_py, root_cpp = self.states(2, "")
        if r.random() < 0.5:
            py["on_interrupt"] = cpp["on_interrupt"] = r.choice(sorted(root_py))
            if r.random() < 0.5:
                py["interrupt_timeout"] = cpp["interrupt_timeout"] = r.choice(DURATIONS)
        if r.random() < 0.5:
            py["on_shutdown"], cpp["on_shutdown"] = self.snippet("on_shutdown")
        if r.random() < 0.7:
            py["period"] = cpp["period"] = r.choice(PERIODS)
        py["initial"] = cpp["initial"] = r.choice(sorted(root_py))
        py["states"], cpp["states"] = root_py, root_cpp
        return Twins(self.seed, py, cpp, self.kinds)


SEEDS = list(range(1, 25))
TWINS = [PairGen(seed).twins() for seed in SEEDS]


def count_states(states: dict[str, Any]) -> int:
    return sum(1 + count_states(s.get("states", {})) for s in states.values())


def count_transitions(states: dict[str, Any]) -> int:
    return sum(len(s.get("transitions", [])) + count_transitions(s.get("states", {}))
               for s in states.values())


@dataclass
class PropertyProject:
    models: dict[int, tuple[Path, Path]]  # seed: (python model, C++ model)
    build: Superbuild


@pytest.fixture(scope="module")
def twins_project(tmp_path_factory: pytest.TempPathFactory) -> PropertyProject:
    """Every twin's model written; the C++ ones generated and compiled once (-Werror)."""
    need_toolchain()
    base = tmp_path_factory.mktemp("twins")
    models: dict[int, tuple[Path, Path]] = {}
    for twins in TWINS:
        folder = base / f"seed{twins.seed}"
        folder.mkdir()
        py, cpp = folder / f"rnd{twins.seed}.yaml", folder / f"rnd{twins.seed}.cpp.yaml"
        py.write_text(dump_yaml(twins.py), "utf-8")
        cpp.write_text(dump_yaml(twins.cpp), "utf-8")
        models[twins.seed] = (py, cpp)
    return PropertyProject(models, Superbuild(tmp_path_factory.mktemp("twins_cpp"),
                                              [cpp for _, cpp in models.values()]))


def run(cmd: list[str], **kw: Any) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(cmd, capture_output=True, timeout=TIMEOUT, stdin=subprocess.DEVNULL,
                          **kw)


def test_the_twins_are_valid_models_that_exercise_every_kind_of_line() -> None:
    kinds: Counter[str] = Counter()
    names: set[str] = set()
    for twins in TWINS:
        for data in (twins.py, twins.cpp):
            result = compile_file("m.yaml", text=dump_yaml(data))
            assert result.model is not None, (twins.seed, result.diagnostics)
        kinds.update(twins.kinds)

        def walk(states: dict[str, Any]) -> None:
            for n, st in states.items():
                names.add(n)
                walk(st.get("states", {}))
        walk(twins.py["states"])
    assert {"raw string", "assign", "block comment", "comment", "if block", "str float", "active",
            "when equal", "when true", "function", "shutdown", "error"} <= set(kinds), kinds
    assert {"class", "int", "delete", "def"} & names, names
    print(f"twins: {len(TWINS)} pairs, "
          f"{sum(count_states(t.py['states']) for t in TWINS)} states, "
          f"{sum(count_transitions(t.py['states']) for t in TWINS)} transitions, "
          f"{sum(kinds.values())} snippet lines and conditions: {dict(sorted(kinds.items()))}")


@pytest.mark.parametrize("seed", SEEDS)
def test_random_twins_trace_the_same_in_python_and_cpp(
        seed: int, twins_project: PropertyProject, tmp_path: Path) -> None:
    py_model, cpp_model = twins_project.models[seed]
    exe = twins_project.build.executable(cpp_model)  # compiles all the twins, once
    out = tmp_path / "py"
    r = run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(py_model), "-o",
             str(out)], cwd=ROOT)
    assert r.returncode == 0, r.stderr.decode()
    args = ["--clock", "virtual", "--until", "2s", "--trace", "-"]
    py = run([sys.executable, "-I", "-S", str(out / f"rnd{seed}.py"), *args])
    cpp = run([str(exe), *args])
    assert py.stdout.startswith(f'{{"t":0,"ev":"start","name":"rnd{seed}"}}\n'.encode()), (
        py.stderr.decode()[-3000:])
    assert b"Traceback (most recent call last)" not in py.stderr.replace(
        b"RuntimeError: boom", b""), py.stderr.decode()[-3000:]
    assert py.returncode in (0, 1), py.stderr.decode()[-3000:]
    assert cpp.returncode == py.returncode, (py.returncode, cpp.returncode,
                                             cpp.stderr.decode()[-3000:])
    py_lines, cpp_lines = py.stdout.splitlines(), cpp.stdout.splitlines()
    first = next((i for i, (a, b) in enumerate(zip(py_lines, cpp_lines, strict=False)) if a != b),
                 min(len(py_lines), len(cpp_lines)))
    assert cpp.stdout == py.stdout, (
        f"traces differ at line {first + 1} (python {len(py_lines)} lines, C++ "
        f"{len(cpp_lines)}):\n  python: {py_lines[first:first + 3]!r}\n"
        f"  c++:    {cpp_lines[first:first + 3]!r}")
    last = json.loads(py_lines[-1])
    assert last["ev"] == "stop" and EXIT_OF_REASON[last["reason"]] == py.returncode, last


# ---------------------------------------------------------------------------
# Runtime faults of the C++ component

SLOW_MODEL = """\
hfsm: 1
name: slow_cpp
language: cpp
imports: ["<thread>", "<chrono>"]
period: 100ms
variables:
  n: 0
initial: Busy
on_interrupt: Stopped
states:
  Busy:
    during: |
      n += 1;
      log("sleep " + str(n));
      std::this_thread::sleep_for(std::chrono::milliseconds(350));
      log("woke " + str(n));
    transitions: [{to: Done, when: n >= 40}]
  Done: {final: true}
  Stopped: {entry: 'log("interrupted");', final: true}
"""

# Work (about a millisecond of arithmetic) in every entry, exit, during, do and
# on_shutdown, so that signals land inside snippets of every kind, and inside the
# interrupt and the stop.
SIGNALS_MODEL = """\
hfsm: 1
name: sigs_cpp
language: cpp
period: 20ms
variables:
  n: 0
  junk: 0
functions: |
  void work() {
      volatile long long sum = 0;
      for (long long i = 0; i < 300000; ++i) sum = sum + i;
      junk = sum;
  }
initial: Work
on_interrupt: Closing
on_shutdown: 'work(); log("shutdown");'
states:
  Work:
    period: 10ms
    initial: A
    entry: 'work(); log("work in");'
    exit: 'work(); log("work out");'
    states:
      A:
        entry: 'n += 1; work();'
        during: work();
        exit: 'work(); log("a out");'
        transitions: [{to: B, after: 30ms}]
      B:
        entry: 'work(); log("b in");'
        exit: work();
        transitions: [{to: A, after: 30ms, do: work();}]
    transitions: [{to: Done, when: n >= 12}]
  Closing:
    entry: 'work(); log("closing");'
    during: work();
    exit: 'work(); log("closing out");'
    transitions: [{to: Bye, after: 60ms}]
  Bye: {final: true, entry: 'work(); log("bye");'}
  Done: {final: true}
"""

# 1 ms ticks that log: about 120 KiB of trace in 2 s, more than the 64 KiB buffer.
FULL_MODEL = """\
hfsm: 1
name: full_cpp
language: cpp
period: 1ms
variables:
  n: 0
on_shutdown: 'log("on_shutdown after " + str(n) + " ticks */");'
initial: A
states:
  A:
    during: 'n += 1; log("tick " + str(n) + " \\\\ \\" */");'
"""

FAULT_MODELS = {"slow_cpp": SLOW_MODEL, "sigs_cpp": SIGNALS_MODEL, "full_cpp": FULL_MODEL}


@pytest.fixture(scope="module")
def faults(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The fault models' executables, built once with ASan and UBSan (-Werror)."""
    need_toolchain()
    folder = tmp_path_factory.mktemp("fault_models")
    models = {}
    for name, text in FAULT_MODELS.items():
        models[name] = folder / f"{name}.yaml"
        models[name].write_text(text, "utf-8")
    project = Superbuild(tmp_path_factory.mktemp("faults_cpp"), list(models.values()),
                         sanitize=True)
    return {name: project.executable(model) for name, model in models.items()}


def records(trace: str) -> list[dict[str, Any]]:
    """Every line of a trace is one JSON object (a line that is not fails the test)."""
    out = []
    for n, line in enumerate(trace.splitlines(), 1):
        rec = json.loads(line)
        assert isinstance(rec, dict) and "ev" in rec, f"trace line {n}: {line!r}"
        out.append(rec)
    return out


def check_nesting(recs: list[dict[str, Any]]) -> None:
    """Enters and exits nest (a state is entered inside an active parent, exited when
    active and after its active children); times never go back; one `stop`, the last."""
    assert recs and recs[0]["ev"] == "start", recs[:1]
    assert recs[-1]["ev"] == "stop", recs[-1:]
    assert [r["ev"] for r in recs].count("stop") == 1
    assert [r["t"] for r in recs] == sorted(r["t"] for r in recs)
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


def wait_for(path: Path, pattern: str, proc: subprocess.Popen[bytes],
             timeout: float = 60) -> re.Match[str]:
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


def start(processes: list[subprocess.Popen[bytes]], exe: Path, err: Path,
          *args: str) -> subprocess.Popen[bytes]:
    with open(err, "wb") as f:
        proc = subprocess.Popen([str(exe), *args], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=f)
    processes.append(proc)
    return proc


SUMMARY = re.compile(r"^(\w+): stopped \((\w+)\) at (\d+\.\d{3}) s; (\d+) ticks, (\d+) overruns "
                     r"\((\d+\.\d) %\)$", re.M)


def test_a_blocking_snippet_counts_overruns_and_sigint_stops_after_it(
        faults: dict[str, Path], tmp_path: Path,
        processes: list[subprocess.Popen[bytes]]) -> None:
    err, trace = tmp_path / "slow.err", tmp_path / "slow.trace"
    proc = start(processes, faults["slow_cpp"], err, "--monitor", "0", "--trace", str(trace))
    port = int(wait_for(err, r"monitor: listening on 127\.0\.0\.1:(\d+)$", proc).group(1))
    with socket.create_connection(("127.0.0.1", port), timeout=60) as sock:
        wait_for(err, r"Busy: sleep 3$", proc)
        proc.send_signal(signal.SIGINT)  # while the third `during` sleeps
        sent = time.monotonic()
        received = b""
        while chunk := sock.recv(65536):  # until the component closes the connection
            received += chunk
    assert proc.wait(60) == 130
    stopped_after = time.monotonic() - sent
    stderr = err.read_text("utf-8")
    assert not SANITIZER_REPORT.search(stderr), stderr
    messages = [json.loads(line) for line in received.splitlines()]
    counts = [m["overruns"] for m in messages if m["type"] in ("snapshot", "sample")]
    assert counts == sorted(counts), counts
    assert messages[-1] == {"type": "bye", "reason": "sigint"}
    recs = records(trace.read_text("utf-8"))
    check_nesting(recs)
    logs = [(x["t"], x["msg"]) for x in recs if x["ev"] == "log"]
    sleeps = [msg for _, msg in logs if msg.startswith("sleep ")]
    last = int(sleeps[-1].split()[1])
    # The signal came while `sleep 3` ran; `sleep 4` only if this process was descheduled
    # for the whole 350 ms between reading the line and sending the signal.
    assert last in (3, 4), logs
    woke_t = next(t for t, msg in logs if msg == f"woke {last}")
    assert woke_t == 400 * (last - 1), logs  # ticks at 0, 400, 800: the missed ones skipped
    # Stopped within the tick of the blocking snippet: the interrupt is recorded at that
    # tick's instant, and no other snippet ran in between.
    interrupt = next(x for x in recs if x["ev"] == "interrupt")
    assert interrupt == {"t": woke_t, "ev": "interrupt", "reason": "sigint", "to": "Stopped"}
    assert logs[-3:] == [(woke_t, f"sleep {last}"), (woke_t, f"woke {last}"),
                         (woke_t, "interrupted")]
    assert recs[-1] == {"t": woke_t, "ev": "stop", "reason": "sigint"}
    # The stop summary: each 350 ms tick skips the 3 deadlines of its 100 ms period.
    summary = SUMMARY.findall(stderr)
    assert len(summary) == 1, stderr
    name, reason, at, ticks, overruns, share = summary[0]
    assert (name, reason, at, int(ticks)) == ("slow_cpp", "sigint", f"{woke_t / 1000:.3f}", last)
    assert 3 * (last - 1) <= int(overruns) <= 3 * last + 1, summary
    assert share == f"{100 * int(overruns) / (int(ticks) + int(overruns)):.1f}"
    assert max(counts) <= int(overruns), (counts, overruns)
    assert stopped_after < 30, stopped_after  # a bound against hangs: the snippet is 0.35 s
    print(f"blocking snippet: {summary[0]}, stopped {stopped_after:.2f} s after SIGINT")


def sent_statuses(*signums: int | None) -> set[int]:
    return {128 + s for s in signums if s is not None}


def test_sigint_and_sigterm_at_random_moments(
        faults: dict[str, Path], tmp_path: Path,
        processes: list[subprocess.Popen[bytes]]) -> None:
    exe = faults["sigs_cpp"]
    rng = random.Random(1)
    statuses = []
    sent = 0
    seconds = 0  # runs that got a second signal
    late: list[int] = []  # runs whose signal came after the stop record
    runs = 16
    for run_no in range(runs):
        err, trace = tmp_path / f"sigs{run_no}.err", tmp_path / f"sigs{run_no}.trace"
        proc = start(processes, exe, err, "--trace", str(trace))
        wait_for(err, r"Work: work in$", proc)  # the handlers are in place from here on
        first = rng.choice([signal.SIGINT, signal.SIGTERM])
        time.sleep(rng.uniform(0, 0.8))  # a run lasts about 0.7 s: most runs get the signal
        proc.send_signal(first)
        sent += 1
        second = rng.choice([None, signal.SIGINT, signal.SIGTERM])
        if second is not None:  # during the interrupt or the stop: the run ends at once
            time.sleep(rng.uniform(0, 0.08))
            if proc.poll() is None:
                proc.send_signal(second)
                sent += 1
                seconds += 1
        status = proc.wait(60)
        stderr = err.read_text("utf-8", "replace")
        assert not SANITIZER_REPORT.search(stderr), stderr
        assert status in (0, 130, 143), (status, stderr[-2000:])
        recs = records(trace.read_text("utf-8"))
        check_nesting(recs)
        reason = recs[-1]["reason"]
        if status != EXIT_OF_REASON[reason]:
            # Known: a signal that comes after the stop was complete (its record and the
            # summary line written), before the process ends (exit handlers; LeakSanitizer's
            # check under ASan), still ends it with 130/143: the status then disagrees with
            # the `stop` record.
            assert status in sent_statuses(first, second), (status, reason)
            assert f"sigs_cpp: stopped ({reason}) at" in stderr, (status, reason, stderr[-500:])
            late.append(run_no)
        statuses.append(status)
    print(f"signals: {runs} runs, {sent} signals ({seconds} runs with a second), "
          f"exit statuses {statuses}, signal after the stop record in runs {late}")
    assert {130, 143} & set(statuses), statuses


def test_trace_on_a_full_disk_is_said_once_and_the_run_goes_on(faults: dict[str, Path]) -> None:
    for clock in ("virtual", "real"):
        # virtual: the 64 KiB buffer fills and fails mid-run; real: the flush before the
        # first wait fails
        r = run([str(faults["full_cpp"]), "--clock", clock, "--until", "2s" if clock == "virtual"
                 else "300ms", "--trace", "/dev/full"])
        stderr = r.stderr.decode("utf-8")
        assert r.returncode == 0, stderr[-3000:]
        assert not SANITIZER_REPORT.search(stderr), stderr[-3000:]
        lines = stderr.splitlines()
        said = [n for n, line in enumerate(lines) if "trace" in line]
        assert len(said) == 1, [lines[n] for n in said]
        assert lines[said[0]] == ("trace: cannot write to /dev/full: No space left on device; "
                                  "the component goes on without its trace")
        # The run went on to its end after the failure: ticks, then on_shutdown, spoke later.
        after = lines[said[0] + 1:]
        assert any(": tick " in line for line in after), lines[said[0]:said[0] + 5]
        assert any("on_shutdown after" in line for line in after), stderr[-2000:]
        if clock == "virtual":
            assert said[0] > 500, said  # the buffer filled well into the run
            assert any(line.endswith("full_cpp: on_shutdown after 2001 ticks */")
                       for line in after), stderr[-500:]


def test_a_nul_in_a_transition_name_gives_a_python_component_that_runs(tmp_path: Path) -> None:
    model = tmp_path / "nulname.yaml"
    model.write_text('hfsm: 1\nname: nulname\ninitial: A\nstates:\n'
                     '  A: {transitions: [{to: B, after: 1ms, name: "a\\0b\\rc\\u2028d\\\\"}]}\n'
                     '  B: {final: true}\n', "utf-8")
    r = run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(model), "-o",
             str(tmp_path / "py")], cwd=ROOT)
    assert r.returncode == 0, r.stderr.decode()
    r = run([sys.executable, "-I", "-S", str(tmp_path / "py/nulname.py"), "--clock", "virtual"])
    assert r.returncode == 0, r.stderr.decode()
