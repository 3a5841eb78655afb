"""Behavioural conformance: one spec, every back end (docs/semantics.md).

Each model ``tests/conformance/NN_name.yaml`` runs under the virtual clock and
must write ``NN_name.trace`` byte for byte, exit with the expected status and
print the expected stderr; ``tests/conformance/real/`` holds runs under the real
clock that a test interrupts with a signal.  ``tests/conformance/README.md``
describes the files and their metadata header.
"""

from __future__ import annotations

import difflib
import json
import os
import re
import selectors
import shlex
import signal
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from tests.backends import SANITIZER_REPORT, Backend, BuildError, CppBackend, PythonBackend

ROOT = Path(__file__).resolve().parent.parent
CONFORMANCE = ROOT / "tests" / "conformance"
REAL = CONFORMANCE / "real"
TRACE_SCHEMA = ROOT / "schemas" / "trace.schema.json"
TIMEOUT = 30.0  # seconds, for every subprocess

# docs/semantics.md §13: the keys of each record, in order.
RECORD_KEYS: dict[str, tuple[str, ...]] = {
    "start": ("t", "ev", "name"),
    "enter": ("t", "ev", "state"),
    "exit": ("t", "ev", "state"),
    "fire": ("t", "ev", "from", "to", "index"),
    "log": ("t", "ev", "state", "msg"),
    "error": ("t", "ev", "state", "snippet"),
    "interrupt": ("t", "ev", "reason", "to"),
    "stop": ("t", "ev", "reason"),
}
SNIPPETS = {"entry", "during", "exit", "when", "do", "on_shutdown"}
STOP_REASONS = {"final", "until", "shutdown", "sigint", "sigterm", "error", "timeout",
                "time_limit"}
INTERRUPT_REASONS = {"shutdown", "sigint", "sigterm", "error", "time_limit"}
META = re.compile(r"# (args|exit|stderr|wait-for|signal): (.*)")


# ---------------------------------------------------------------------------
# Back ends


def conformance_twins() -> list[Path]:
    """The C++ twins (``NN_name.cpp.yaml``) of both folders: one CMake project."""
    return sorted(CONFORMANCE.glob("*.cpp.yaml")) + sorted(REAL.glob("*.cpp.yaml"))


# The back ends this suite runs. The C++ component runs twice: as built, and with
# AddressSanitizer + UndefinedBehaviorSanitizer (any report fails the case).
BACKENDS: tuple[Backend, ...] = (PythonBackend(),
                                 CppBackend("cpp", sanitize=False, twins=conformance_twins),
                                 CppBackend("cpp-asan", sanitize=True, twins=conformance_twins))


class Components:
    """Builds each (back end, model) once per session."""

    def __init__(self, base: Path) -> None:
        self._base = base
        self._built: dict[tuple[str, Path], list[str] | BuildError] = {}

    def command(self, backend: Backend, model: Path) -> list[str]:
        key = (backend.name, model)
        if key not in self._built:
            out = self._base / backend.name / model.name.split(".")[0]
            try:
                self._built[key] = backend.build(model, out)
            except BuildError as e:
                self._built[key] = e
        built = self._built[key]
        if isinstance(built, BuildError):
            pytest.fail(f"build failed: {built}", pytrace=False)
        return built


@pytest.fixture(scope="session")
def components(tmp_path_factory: pytest.TempPathFactory) -> Components:
    return Components(tmp_path_factory.mktemp("conformance"))


# ---------------------------------------------------------------------------
# Cases


@dataclass(frozen=True)
class Case:
    """A model and what its run must produce, read from its metadata header."""

    model: Path
    expected: Path
    args: tuple[str, ...] = ()
    exit: int = 0
    stderr: tuple[str, ...] = ()
    wait_for: str = ""
    signal_name: str = ""

    @classmethod
    def load(cls, model: Path, expected: Path) -> Case:
        meta: dict[str, list[str]] = {}
        for line in model.read_text("utf-8").splitlines():
            m = META.fullmatch(line)
            if m is None:
                break  # metadata lines come first
            meta.setdefault(m.group(1), []).append(m.group(2))
        return cls(
            model=model,
            expected=expected,
            args=tuple(a for s in meta.get("args", []) for a in shlex.split(s)),
            exit=int(meta.get("exit", ["0"])[-1]),
            stderr=tuple(meta.get("stderr", [])),
            wait_for=meta.get("wait-for", [""])[-1],
            signal_name=meta.get("signal", [""])[-1],
        )


def base_models(folder: Path) -> list[Path]:
    """Models of the reference back end: ``NAME.yaml`` (twins have a second suffix)."""
    return sorted(p for p in folder.glob("*.yaml") if p.name.count(".") == 1)


def cases(folder: Path) -> list[tuple[Backend, Case]]:
    found = []
    for base in base_models(folder):
        stem = base.name.split(".")[0]
        for backend in BACKENDS:
            model = folder / f"{stem}{backend.model_suffix}"
            if model.exists():
                found.append((backend, Case.load(model, folder / f"{stem}.trace")))
    return found


def case_id(item: tuple[Backend, Case]) -> str:
    return f"{item[0].name}-{item[1].model.name.split('.')[0]}"


LOG_LINE = re.compile(r"\[ *\d+\.\d{3}\] |\S+:\d+:\d+: error: |  in ")

# The first C++ case of a session compiles every twin: allow it the time that takes.
BUILD_TIMEOUT_S = 1800


def params(found: list[tuple[Backend, Case]]) -> list[Any]:
    return [pytest.param(b, c, id=case_id((b, c)),
                         marks=[pytest.mark.timeout(BUILD_TIMEOUT_S)] if isinstance(b, CppBackend) else [])
            for b, c in found]


VIRTUAL_CASES = cases(CONFORMANCE)
REAL_CASES = cases(REAL)


def diff(expected: bytes, actual: bytes) -> str:
    def lines(data: bytes) -> list[str]:
        return [line.decode("utf-8", "backslashreplace") + "\n" for line in data.split(b"\n")]

    return "".join(difflib.unified_diff(lines(expected), lines(actual), "expected", "actual"))


def check_run(case: Case, trace: bytes, expected: bytes, returncode: int, stderr: bytes) -> None:
    """Fail with every difference between a run and its case at once."""
    problems = []
    if trace != expected:
        problems.append(f"trace differs from {case.expected.relative_to(ROOT)}:\n"
                        f"{diff(expected, trace)}")
    if returncode != case.exit:
        problems.append(f"exit status {returncode}, expected {case.exit}")
    text = stderr.decode("utf-8", "backslashreplace")
    problems += [f"stderr does not match /{rx}/" for rx in case.stderr if not re.search(rx, text)]
    if SANITIZER_REPORT.search(text):
        problems.append("a sanitizer reported a problem")
    if problems:
        pytest.fail("\n".join(problems) + f"\n--- stderr ---\n{text}", pytrace=False)


@pytest.mark.parametrize(("backend", "case"), params(VIRTUAL_CASES))
def test_conformance(backend: Backend, case: Case, components: Components) -> None:
    cmd = [*components.command(backend, case.model), "--clock", "virtual", "--trace", "-", *case.args]
    try:
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired as e:  # run() has killed and reaped the process
        pytest.fail(f"{shlex.join(cmd)} still running after {TIMEOUT} s\n"
                    f"{diff(case.expected.read_bytes(), e.stdout or b'')}", pytrace=False)
    check_run(case, proc.stdout, case.expected.read_bytes(), proc.returncode, proc.stderr)
    if isinstance(backend, CppBackend):
        # Without --trace (nor a view or --record) a model of one period runs the engine's
        # fast lockstep, which keeps no record and no chain: the same run, seen in its
        # status and its log lines (the drivers' own lines come when their threads say).
        quiet = [*components.command(backend, case.model), "--clock", "virtual", *case.args]
        bare = subprocess.run(quiet, cwd=ROOT, capture_output=True, timeout=TIMEOUT)
        assert (bare.returncode, log_lines(bare.stderr)) == (proc.returncode, log_lines(proc.stderr))


def log_lines(stderr: bytes) -> list[str]:
    """The lines of log() and of errors in snippets: `[  t] PATH: text`, `FILE:L:C: error`."""
    return [line for line in stderr.decode("utf-8", "backslashreplace").splitlines()
            if LOG_LINE.match(line)]


# ---------------------------------------------------------------------------
# Real clock, interrupted from outside


def read_lines(proc: subprocess.Popen[bytes], deadline: float) -> Iterator[bytes]:
    """Yield the lines ``proc`` writes on stdout as they come, until EOF or ``deadline``."""
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    pending = b""
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while (left := deadline - time.monotonic()) > 0:
            if not sel.select(left):
                continue
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            pending += chunk
            *lines, pending = pending.split(b"\n")
            yield from (line + b"\n" for line in lines)
    if pending:
        yield pending


def without_t(trace: bytes) -> bytes:
    """The trace with every record's ``t`` removed, in the same compact form."""
    out = []
    for line in trace.splitlines():
        try:
            record = json.loads(line)
        except ValueError:
            out.append(line)  # kept as is: the diff shows it
            continue
        record.pop("t", None)
        out.append(json.dumps(record, separators=(",", ":")).encode())
    return b"".join(line + b"\n" for line in out)


def record_times(trace: bytes) -> list[int]:
    return [json.loads(line)["t"] for line in trace.splitlines() if line.startswith(b'{"t":')]


@pytest.mark.parametrize(("backend", "case"), params(REAL_CASES))
def test_real_clock_signal(backend: Backend, case: Case, components: Components) -> None:
    assert case.wait_for and case.signal_name, f"{case.model}: needs `# wait-for:` and `# signal:`"
    cmd = [*components.command(backend, case.model), "--clock", "real", "--trace", "-", *case.args]
    wanted = without_t(case.wait_for.encode())
    deadline = time.monotonic() + TIMEOUT
    seen = b""
    with subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE) as proc:
        try:
            lines = read_lines(proc, deadline)
            for line in lines:
                seen += line
                if without_t(line) == wanted:
                    proc.send_signal(getattr(signal, case.signal_name))
                    break
            else:
                pytest.fail(f"no {case.wait_for} within {TIMEOUT} s; stdout so far:\n"
                            f"{seen.decode('utf-8', 'backslashreplace')}", pytrace=False)
            seen += b"".join(lines)
            try:
                out, stderr = proc.communicate(timeout=max(deadline - time.monotonic(), 1.0))
            except subprocess.TimeoutExpired:
                pytest.fail(f"still running {TIMEOUT} s after start; stdout so far:\n"
                            f"{seen.decode('utf-8', 'backslashreplace')}", pytrace=False)
            seen += out
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    check_run(case, without_t(seen), case.expected.read_bytes(), proc.returncode, stderr)
    times = record_times(seen)
    assert times == sorted(times), f"t goes back in time: {times}"


# ---------------------------------------------------------------------------
# The expected traces themselves


def trace_problems(data: bytes, with_t: bool = True) -> list[str]:
    """What keeps ``data`` from being a trace as docs/semantics.md §13 describes it (compact JSON
    lines, keys in order, whole-ms ``t`` never going back, start first, stop last)."""
    problems: list[str] = []
    if not data.endswith(b"\n"):
        problems.append("does not end with a newline")
    lines = data.decode("ascii", "replace").splitlines()
    last_t = 0
    for n, line in enumerate(lines, 1):
        try:
            pairs = json.loads(line, object_pairs_hook=lambda p: p)
        except ValueError as e:
            problems.append(f"line {n}: not JSON: {e}")
            continue
        if not isinstance(pairs, list):
            problems.append(f"line {n}: not an object")
            continue
        record: dict[str, Any] = dict(pairs)
        keys = RECORD_KEYS.get(record.get("ev", ""))
        if keys is None:
            problems.append(f"line {n}: unknown ev {record.get('ev')!r}")
            continue
        if not with_t:
            keys = keys[1:]
        if tuple(k for k, _ in pairs) != keys:
            problems.append(f"line {n}: keys {[k for k, _ in pairs]}, expected {list(keys)}")
        if json.dumps(record, separators=(",", ":")) != line:
            problems.append(f"line {n}: not in compact json.dumps form")
        problems += [f"line {n}: {p}" for p in value_problems(record, with_t, last_t)]
        if with_t and isinstance(record.get("t"), int):
            last_t = record["t"]
    evs = [json.loads(line).get("ev") for line in lines if line.startswith("{")]
    if evs[:1] != ["start"] or evs.count("start") != 1:
        problems.append("the first record, and only it, must be `start`")
    if evs[-1:] != ["stop"] or evs.count("stop") != 1:
        problems.append("the last record, and only it, must be `stop`")
    return problems


def value_problems(record: dict[str, Any], with_t: bool, last_t: int) -> list[str]:
    problems = []
    if with_t:
        t = record.get("t")
        if type(t) is not int or t < last_t:
            problems.append(f"t {t!r} is not a whole number of ms >= {last_t}")
    ev = record["ev"]
    if ev == "fire" and (type(record.get("index")) is not int or record["index"] < 0):
        problems.append(f"bad index {record.get('index')!r}")
    if ev == "error" and record.get("snippet") not in SNIPPETS:
        problems.append(f"bad snippet {record.get('snippet')!r}")
    if ev == "interrupt" and record.get("reason") not in INTERRUPT_REASONS:
        problems.append(f"bad interrupt reason {record.get('reason')!r}")
    if ev == "stop" and record.get("reason") not in STOP_REASONS:
        problems.append(f"bad stop reason {record.get('reason')!r}")
    return problems


VIRTUAL_TRACES = sorted(CONFORMANCE.glob("*.trace"))
REAL_TRACES = sorted(REAL.glob("*.trace"))


def test_enough_cases() -> None:
    assert len(base_models(CONFORMANCE)) >= 32
    assert len(base_models(REAL)) >= 1


@pytest.mark.parametrize("folder", [CONFORMANCE, REAL], ids=["virtual", "real"])
def test_models_and_traces_pair_up(folder: Path) -> None:
    models = {p.name.split(".")[0] for p in folder.glob("*.yaml")}
    traces = {p.stem for p in folder.glob("*.trace")}
    assert models == traces


@pytest.mark.parametrize("trace", VIRTUAL_TRACES + REAL_TRACES,
                         ids=[p.relative_to(CONFORMANCE).as_posix() for p in VIRTUAL_TRACES + REAL_TRACES])
def test_trace_fixture_format(trace: Path) -> None:
    assert trace_problems(trace.read_bytes(), with_t=trace.parent != REAL) == []


@pytest.mark.parametrize("trace", VIRTUAL_TRACES, ids=[p.name for p in VIRTUAL_TRACES])
def test_trace_fixture_matches_schema(trace: Path) -> None:
    assert TRACE_SCHEMA.exists(), f"{TRACE_SCHEMA.relative_to(ROOT)} is missing"
    schema = json.loads(TRACE_SCHEMA.read_text("utf-8"))
    validator_class = jsonschema.validators.validator_for(schema)
    validator_class.check_schema(schema)
    validator = validator_class(schema)
    for n, line in enumerate(trace.read_text("ascii").splitlines(), 1):
        errors = [e.message for e in validator.iter_errors(json.loads(line))]
        assert errors == [], f"{trace.name}:{n}: {line}"


GOOD = b'{"t":0,"ev":"start","name":"m"}\n{"t":0,"ev":"stop","reason":"final"}\n'


@pytest.mark.parametrize("bad", [
    pytest.param(GOOD.replace(b'"t":0,"ev":"start"', b'"ev":"start","t":0'), id="key-order"),
    pytest.param(GOOD.replace(b'"t":0,', b'"t": 0,', 1), id="space"),
    pytest.param(GOOD.replace(b'"t":0,"ev":"stop"', b'"t":0.5,"ev":"stop"'), id="fractional-t"),
    pytest.param(GOOD.replace(b'"name":"m"', b'"name":"\xc3\xa9"'), id="raw-non-ascii"),
    pytest.param(GOOD.replace(b'"reason":"final"', b'"reason":"done"'), id="bad-reason"),
    pytest.param(GOOD.replace(b'"t":0,"ev":"stop"', b'"t":-1,"ev":"stop"'), id="t-goes-back"),
    pytest.param(GOOD[:-1], id="no-final-newline"),
    pytest.param(GOOD.split(b"\n")[0] + b"\n", id="no-stop"),
    pytest.param(GOOD.replace(b'"ev":"start","name":"m"', b'"ev":"begin","name":"m"'), id="unknown-ev"),
    pytest.param(b'{"t":0,"ev":"start","name":"m"}\n{"t":0,"ev":"fire","from":"A","index":0,"to":"B"}\n'
                 b'{"t":0,"ev":"stop","reason":"final"}\n', id="fire-key-order"),
])
def test_trace_checker_rejects(bad: bytes) -> None:
    assert trace_problems(GOOD) == []
    assert trace_problems(bad) != []
