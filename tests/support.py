"""Helpers the test files share: free ports, waiting, processes, a tmux screen, traces,
the monitor's clients, the blinker example's structure and trace, and the browser.

Fixtures built on them (``processes``, ``logged``, ``tmux``, ``clients``, ``browsers``) are in
tests/conftest.py.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import count
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from referencing import Registry, Resource

ROOT = Path(__file__).resolve().parent.parent


# -- ports and waiting ------------------------------------------------------------------------
def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port of 127.0.0.1 that was free a moment ago (TCP, or UDP with SOCK_DGRAM)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_until(what: Callable[[], object], timeout: float, step: float = 0.01) -> bool:
    """Poll until true; whether it became true in time."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(step)
    return bool(what())


def wait_for_line(path: Path, pattern: str | re.Pattern[str], proc: subprocess.Popen[bytes],
                  timeout: float = 60, step: float = 0.005) -> re.Match[str]:
    """Poll a growing file (a process's log) until ``pattern`` matches in it, a line at a time
    with a str pattern; fails when the process ends first or ``timeout`` seconds pass.
    The match's ``.string`` is the whole text read."""
    found = re.compile(pattern, re.M) if isinstance(pattern, str) else pattern
    deadline = time.monotonic() + timeout
    while True:
        text = path.read_text("utf-8", "replace") if path.exists() else ""
        m = found.search(text)
        if m:
            return m
        if proc.poll() is not None or time.monotonic() > deadline:
            raise AssertionError(f"no {found.pattern!r} (exit {proc.poll()}):\n{text[-3000:]}")
        time.sleep(step)


def stop_processes(made: list[subprocess.Popen[bytes]]) -> None:
    """Kill what still runs of ``made`` and reap every one (bounded in time)."""
    for p in made:
        if p.poll() is None:
            p.kill()
        p.wait(10)


def interrupt(proc: subprocess.Popen[Any], timeout: float = 10,
              signum: int = signal.SIGINT) -> int:
    """Stop a process with ``signum`` (SIGINT: as Ctrl+C does); killed if it has not ended
    within ``timeout`` seconds. Its exit status."""
    if proc.poll() is None:
        proc.send_signal(signum)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
    return proc.returncode


def close_pipes(proc: subprocess.Popen[Any], reader: threading.Thread) -> None:
    """After a process ended: the thread reading its output joined, its pipes closed."""
    reader.join(timeout=5)
    for stream in (proc.stdin, proc.stdout):
        if stream is not None:
            with contextlib.suppress(OSError):
                stream.close()


class Worker(ABC):
    """Runs ``self._run`` on a daemon thread from ``start_worker`` until ``stop_worker``, which
    sets ``self._stop`` (the loop must look at it); ``self._lock`` guards what it shares."""

    def start_worker(self) -> None:
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def stop_worker(self, timeout: float) -> None:
        self._stop.set()
        self._thread.join(timeout=timeout)

    @abstractmethod
    def _run(self) -> None: ...


@contextlib.contextmanager
def simulator(tmp: Path, port: int, *args: str) -> Iterator[subprocess.Popen[bytes]]:
    """`hfsmc sim` sending to udp PORT, started and ready to serve (its first line said)."""
    log_path = tmp / "sim.log"
    with log_path.open("w") as log:
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--mavlink",
                                f"udpout:127.0.0.1:{port}", "--boot-time", "1", *args],
                               cwd=ROOT, stdout=log, stderr=log, stdin=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 30
        while "sim: MAVLink to" not in log_path.read_text():
            assert sim.poll() is None and time.monotonic() < end, log_path.read_text()
            time.sleep(0.05)
        yield sim
    finally:
        interrupt(sim)
    assert sim.returncode == 0, log_path.read_text()


@contextlib.contextmanager
def python_vehicle(tmp: Path, autopilot: str, boot_time: str) -> Iterator[Any]:
    """The Python mavlink driver (templates/python) connected to `hfsmc sim` of
    ``autopilot`` ("ardupilot" or "px4") in real time."""
    sys.path.insert(0, str(ROOT / "templates" / "python"))
    import hfsmc_mavlink  # type: ignore[import-not-found]
    port = free_port(socket.SOCK_DGRAM)
    extra = ("--autopilot", "px4", "--source-port", "0") if autopilot == "px4" else ()
    try:
        with simulator(tmp, port, "--no-camera", "--boot-time", boot_time, *extra):
            v = hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {})
            try:
                yield v
            finally:
                v.close()
    finally:
        sys.path.remove(str(ROOT / "templates" / "python"))


def until_snapshot(v: Any, cond: Callable[[], bool], timeout: float) -> bool:
    """Whether ``cond`` held within ``timeout`` s, a driver's snapshot taken before each try."""
    def check() -> bool:
        v.snapshot()
        return cond()
    return wait_until(check, timeout, 0.05)


def hfsmc(*args: str, cwd: Path = ROOT, timeout: float = 120,
          ) -> subprocess.CompletedProcess[str]:
    """`hfsmc ARGS` run by this interpreter, its output captured."""
    return subprocess.run([sys.executable, "-m", "hfsmc", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def py(*args: object) -> str:
    """A shell command line running this interpreter with ``args``."""
    return " ".join(shlex.quote(str(a)) for a in (sys.executable, *args))


class Process:
    """A process whose stdout and stderr go to files; killed at the end of the test
    (the ``logged`` fixture)."""

    def __init__(self, args: list[str], tmp: Path, name: str) -> None:
        self.err_path = tmp / f"{name}.err"
        self.out_path = tmp / f"{name}.out"
        with open(self.err_path, "w") as err, open(self.out_path, "w") as out:
            self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=out, stderr=err,
                                         cwd=tmp)

    def wait_for(self, pattern: str, where: str = "err", timeout: float = 15) -> re.Match[str]:
        path = self.err_path if where == "err" else self.out_path
        deadline = time.monotonic() + timeout
        while not (m := re.search(pattern, path.read_text())):
            assert time.monotonic() < deadline and self.proc.poll() is None, path.read_text()
            time.sleep(0.02)
        return m

    def kill(self, sig: int = signal.SIGKILL) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        return self.proc.wait(10)


# -- the web view in a browser -------------------------------------------------------------------
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
# The flags every test browser gets (the ``browsers`` fixture): headless, and nothing of its own
# on the network.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--window-size=1280,800")
needs_browser = pytest.mark.skipif(
    not (os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER)),
    reason="chromium and chromium-driver are not installed (`make deps` installs them)")
# What `hfsmc view --web` prints on stdout, and the URL (with the run's token) in it.
WEB_URL = r"web view on (http://127\.0\.0\.1:\d+/\?token=[\w-]+) "


def screenshot(driver: Any, name: str, tmp_path: Path) -> None:
    """Saved for a person to look at: in $HFSMC_SCREENSHOTS when set, else beside the test."""
    folder = Path(os.environ.get("HFSMC_SCREENSHOTS") or tmp_path)
    folder.mkdir(parents=True, exist_ok=True)
    assert driver.save_screenshot(str(folder / f"{name}.png"))


def chromium(profile: Path, *flags: str) -> Any:
    """Debian's chromium driven by its chromedriver (never a driver Selenium would fetch)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    os.environ["SE_OFFLINE"] = "true"  # never let Selenium Manager fetch a driver
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (*CHROMIUM_FLAGS, *flags, f"--user-data-dir={profile}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(15)
    driver.set_script_timeout(10)
    return driver


# -- traces -------------------------------------------------------------------------------------
def records(trace: str) -> list[dict[str, Any]]:
    """Every line of a trace is one JSON object (a line that is not fails the test)."""
    out = []
    for n, line in enumerate(trace.splitlines(), 1):
        rec = json.loads(line)
        assert isinstance(rec, dict) and "ev" in rec, f"trace line {n}: {line!r}"
        out.append(rec)
    return out


def check_nesting(recs: list[dict[str, Any]], regions: Collection[str] = ()) -> None:
    """Enters and exits nest (a state is entered inside an active parent, exited when
    active and after its active children); times never go back; one `stop`, the last.
    ``regions`` are the paths of the model's regions (`Mission/Watch`): a region's states
    are entered inside the state that holds the region."""
    assert recs and recs[0]["ev"] == "start", recs[:1]
    assert recs[-1]["ev"] == "stop", recs[-1:]
    assert [r["ev"] for r in recs].count("stop") == 1
    assert [r["t"] for r in recs] == sorted(r["t"] for r in recs)
    active: set[str] = set()
    for r in recs:
        path = r.get("state", "")
        if r["ev"] == "enter":
            parent = path.rpartition("/")[0]
            if parent in regions:
                parent = parent.rpartition("/")[0]
            assert path not in active and (not parent or parent in active), (r, active)
            active.add(path)
        elif r["ev"] == "exit":
            assert path in active, (r, active)
            assert not any(a.startswith(path + "/") for a in active), (r, active)
            active.remove(path)


# -- the blinker example: its structure and a trace ---------------------------------------------
BLINKER = "examples/blinker/blinker.yaml"

# The blinker's structure, as the monitor sends it (tests/cpp/observers_main.cpp gives the same).
STRUCTURE: dict[str, Any] = {
    "name": "blinker",
    "automata": [{"owner": "", "region": None, "use": None, "period_ms": 100, "initial": "Blinking", "history": False},
                 {"owner": "Blinking", "region": None, "use": None, "period_ms": 50, "initial": "Lit", "history": True}],
    "states": [{"path": "Blinking", "final": False, "composite": True},
               {"path": "Blinking/Lit", "final": False, "composite": False},
               {"path": "Blinking/Dark", "final": False, "composite": False},
               {"path": "Paused", "final": False, "composite": False},
               {"path": "Done", "final": True, "composite": False}],
    "transitions": [{"from": "Blinking", "to": "Done", "index": 0, "name": "enough"},
                    {"from": "Blinking", "to": "Paused", "index": 1, "name": "pause"},
                    {"from": "Blinking/Lit", "to": "Blinking/Dark", "index": 0, "name": None},
                    {"from": "Blinking/Dark", "to": "Blinking/Lit", "index": 0, "name": None},
                    {"from": "Paused", "to": "Blinking", "index": 0, "name": "resume"}],
    "variables": ["led", "count", "pauses"],
    "parameters": {"blinks": "10"},
}

# The blinker's trace until it is interrupted while paused (docs/semantics.md's records).
TRACE = """\
{"t":0,"ev":"start","name":"blinker"}
{"t":0,"ev":"enter","state":"Blinking"}
{"t":0,"ev":"enter","state":"Blinking/Lit"}
{"t":500,"ev":"fire","from":"Blinking/Lit","to":"Blinking/Dark","index":0}
{"t":500,"ev":"exit","state":"Blinking/Lit"}
{"t":500,"ev":"enter","state":"Blinking/Dark"}
{"t":3000,"ev":"fire","from":"Blinking","to":"Paused","index":1}
{"t":3000,"ev":"exit","state":"Blinking/Dark"}
{"t":3000,"ev":"exit","state":"Blinking"}
{"t":3000,"ev":"enter","state":"Paused"}
{"t":3000,"ev":"log","state":"Paused","msg":"paused with the LED off"}
{"t":3200,"ev":"interrupt","reason":"sigint","to":"Done"}
{"t":3200,"ev":"exit","state":"Paused"}
{"t":3200,"ev":"enter","state":"Done"}
{"t":3200,"ev":"exit","state":"Done"}
{"t":3200,"ev":"log","state":"","msg":"stopped after 1 blinks and 1 pauses"}
{"t":3200,"ev":"stop","reason":"sigint"}
"""
RECORDS: list[dict[str, Any]] = [json.loads(line) for line in TRACE.splitlines()]

# A state with two regions (tests/cpp/observers_main.cpp --regions gives the same), as the
# monitor sends it, and a run of it: the views' region case.
PARALLEL_STRUCTURE: dict[str, Any] = {
    "name": "par",
    "automata": [{"owner": "", "region": None, "use": None, "period_ms": 100, "initial": "Mission", "history": False},
                 {"owner": "Mission", "region": "Nav", "use": None, "period_ms": 100, "initial": "A", "history": False},
                 {"owner": "Mission", "region": "Watch", "use": None, "period_ms": 300, "initial": "Ok", "history": True}],
    "states": [{"path": "Mission", "final": False, "composite": True},
               {"path": "Mission/Nav/A", "final": False, "composite": False},
               {"path": "Mission/Nav/B", "final": True, "composite": False},
               {"path": "Mission/Watch/Ok", "final": False, "composite": False},
               {"path": "Mission/Watch/Seen", "final": True, "composite": False},
               {"path": "Done", "final": True, "composite": False}],
    "transitions": [{"from": "Mission", "to": "Done", "index": 0, "name": "all done"},
                    {"from": "Mission/Nav/A", "to": "Mission/Nav/B", "index": 0, "name": None},
                    {"from": "Mission/Watch/Ok", "to": "Mission/Watch/Seen", "index": 0, "name": "seen"}],
    "variables": ["n"],
    "parameters": {},
}
PARALLEL_TRACE = """\
{"t":0,"ev":"start","name":"par"}
{"t":0,"ev":"enter","state":"Mission"}
{"t":0,"ev":"enter","state":"Mission/Nav/A"}
{"t":0,"ev":"enter","state":"Mission/Watch/Ok"}
{"t":200,"ev":"fire","from":"Mission/Nav/A","to":"Mission/Nav/B","index":0}
{"t":200,"ev":"exit","state":"Mission/Nav/A"}
{"t":200,"ev":"enter","state":"Mission/Nav/B"}
{"t":900,"ev":"fire","from":"Mission/Watch/Ok","to":"Mission/Watch/Seen","index":0}
{"t":900,"ev":"exit","state":"Mission/Watch/Ok"}
{"t":900,"ev":"enter","state":"Mission/Watch/Seen"}
{"t":900,"ev":"log","state":"Mission/Watch/Seen","msg":"seen"}
{"t":1000,"ev":"fire","from":"Mission","to":"Done","index":0}
{"t":1000,"ev":"exit","state":"Mission/Watch/Seen"}
{"t":1000,"ev":"exit","state":"Mission/Nav/B"}
{"t":1000,"ev":"exit","state":"Mission"}
{"t":1000,"ev":"enter","state":"Done"}
{"t":1000,"ev":"exit","state":"Done"}
{"t":1000,"ev":"stop","reason":"final"}
"""
PARALLEL_RECORDS: list[dict[str, Any]] = [json.loads(line) for line in PARALLEL_TRACE.splitlines()]

# STRUCTURE as the component tells it when Blinking's sub-automaton is used from another
# file (tests/cpp/observers_main.cpp --use).
USED_STRUCTURE: dict[str, Any] = {**STRUCTURE, "automata": [
    STRUCTURE["automata"][0], {**STRUCTURE["automata"][1], "use": "lib/blink.yaml"}]}

# A model that uses one file twice, that file using another: paths through instances
# (First/Hold/Wait), a file named as each using model writes it (lib/climb.yaml, hold.yaml).
USED_MODELS = {
    "legs.yaml": """\
hfsm: 1
name: legs
parameters:
  high: {type: float, default: 2.0}
variables: {legs: 0}
period: 100ms
initial: First
states:
  First:
    use: lib/climb.yaml
    with: {target: 1.0}
    transitions: [{to: Second, when: done(), do: "legs += 1"}]
  Second:
    use: lib/climb.yaml
    with: {target: $high}
    transitions: [{to: Done, when: done(), do: "legs += 1"}]
  Done: {final: true}
""",
    "lib/climb.yaml": """\
hfsm: 1
name: climb
parameters:
  target: {type: float, default: 2.0}
variables: {height: 0.0}
period: 100ms
initial: Climb
states:
  Climb:
    during: "height += 0.5"
    transitions: [{to: Hold, when: height >= target}]
  Hold:
    use: hold.yaml
    transitions: [{to: Up, when: done()}]
  Up: {final: true}
""",
    "lib/hold.yaml": """\
hfsm: 1
name: hold
period: 100ms
initial: Wait
states:
  Wait: {transitions: [{to: Still, after: 1s}]}
  Still: {final: true}
""",
}


def write_used_models(folder: Path) -> Path:
    """USED_MODELS written under ``folder``; the using model's path."""
    for name, text in USED_MODELS.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)
    return folder / "legs.yaml"

GREEN = r"\x1b\[(?:[0-9;]*;)?32m(?:\x1b\[[0-9;]*m)*"  # green foreground, then maybe other SGRs


def build_blinker(out: Path) -> Path:
    """The real blinker component, built with `hfsmc build`; its main file."""
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", BLINKER, "-o", str(out)],
                   cwd=ROOT, check=True, capture_output=True, timeout=120, stdin=subprocess.DEVNULL)
    return out / "blinker.py"


# -- the monitor's protocol -----------------------------------------------------------------------
def _monitor_validator() -> Any:
    schemas = {name: json.loads((ROOT / "schemas" / name).read_text())
               for name in ("monitor.schema.json", "trace.schema.json")}
    registry: Registry[Any] = Registry().with_resources(
        (s["$id"], Resource.from_contents(s)) for s in schemas.values())
    cls = jsonschema.validators.validator_for(schemas["monitor.schema.json"])
    cls.check_schema(schemas["monitor.schema.json"])
    return cls(schemas["monitor.schema.json"], registry=registry)


# Checks a monitor message (schemas/monitor.schema.json, which refers to the trace's schema).
MONITOR_VALIDATOR = _monitor_validator()


class Client:
    """A raw monitor client: JSON lines, each checked against the schema."""

    def __init__(self, port: int, rcvbuf: int | None = None, timeout: float = 20,
                 source: str | None = None) -> None:
        """Connected to 127.0.0.1:``port``, from the address ``source`` when given (another
        address of 127.0.0.0/8 is another address to the server)."""
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf is not None:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        if source is not None:
            self.sock.bind((source, 0))
        self.sock.settimeout(timeout)
        self.sock.connect(("127.0.0.1", port))
        self.stream = self.sock.makefile("rb")
        self.lines: list[bytes] = []
        self._reader: threading.Thread | None = None
        self._data = b""

    def message(self) -> dict[str, Any] | None:
        line = self.stream.readline()
        if not line:
            return None
        return self._parse(line)

    def _parse(self, line: bytes, validate: bool = True) -> dict[str, Any]:
        self.lines.append(line)
        msg = json.loads(line)
        if validate:
            MONITOR_VALIDATOR.validate(msg)
        assert isinstance(msg, dict)
        return msg

    def until(self, last: Callable[[dict[str, Any]], bool]) -> list[dict[str, Any]]:
        """The messages up to the first for which ``last`` is true."""
        out: list[dict[str, Any]] = []
        while True:
            msg = self.message()
            assert msg is not None, f"connection closed after {out[-3:]}"
            out.append(msg)
            if last(msg):
                return out

    def until_bye(self) -> list[dict[str, Any]]:
        """The messages until ``bye``, after which the connection must close."""
        out: list[dict[str, Any]] = []
        while (msg := self.message()) is not None:
            out.append(msg)
            if msg["type"] == "bye":
                assert self.stream.readline() == b"", "the connection closes after bye"
                return out
        raise AssertionError(f"connection closed without bye after {self.lines[-2:]}")

    def gone(self) -> bool:
        """The server closed (or reset) the connection; data still queued is read first."""
        try:
            while self.stream.readline():
                pass
        except OSError:
            pass
        return True

    def read_fast(self) -> None:
        """Read everything as fast as it comes, on a thread (checked by ``collected``)."""
        self._data = b""

        def pump() -> None:
            with contextlib.suppress(OSError):
                while chunk := self.stream.read1(1 << 20):
                    self._data += chunk

        self._reader = threading.Thread(target=pump, daemon=True)
        self._reader.start()

    def received(self, timeout: float = 30) -> bytes:
        """What ``read_fast`` read until the connection ended (or ``timeout``)."""
        assert self._reader is not None
        self._reader.join(timeout)
        return self._data

    def collected(self) -> list[dict[str, Any]]:
        self.received()
        assert self._data.endswith(b'{"type":"bye","reason":"error"}\n'), self._data[-200:]
        # Checking all of a burst against the schema would take long: one in a hundred will do.
        return [self._parse(line, validate=k % 100 == 0 or b"burst " not in line)
                for k, line in enumerate(self._data.splitlines(keepends=True))]

    def close(self) -> None:
        self.stream.close()
        self.sock.close()


def read_messages(sock: socket.socket, seconds: float) -> list[dict[str, Any]]:
    """The JSON lines read from a raw monitor connection for ``seconds`` (or until it closes)."""
    got: list[dict[str, Any]] = []
    buf = b""
    deadline = time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            data = sock.recv(1 << 16)
        except TimeoutError:
            break
        if not data:
            break
        buf += data
        *lines, buf = buf.split(b"\n")
        got.extend(json.loads(line) for line in lines)
    return got


# -- as a person sees it: tmux ------------------------------------------------------------------
_sessions = count()


class Tmux:
    """A private tmux server (its own socket) running one command in a 120x40 pane."""

    def __init__(self, command: str, cwd: Path, after: str = "") -> None:
        self.socket = f"test-{os.getpid()}-{next(_sessions)}"
        env = {k: v for k, v in os.environ.items() if k not in ("NO_COLOR", "TMUX")}
        env["TERM"] = "xterm-256color"
        self._run("-f", "/dev/null", "new-session", "-d", "-x", "120", "-y", "40",
                  f"cd {shlex.quote(str(cwd))} && {command}; echo EXIT=$?; {after or ':'}; sleep 60",
                  env=env)
        self.path = self._run("display-message", "-p", "#{socket_path}").strip()

    def _run(self, *args: str, env: dict[str, str] | None = None) -> str:
        r = subprocess.run(["tmux", "-u", "-L", self.socket, *args], capture_output=True, text=True,
                           timeout=10, env=env, stdin=subprocess.DEVNULL, check=True)
        return r.stdout

    def screen(self, colors: bool = False) -> str:
        return self._run("capture-pane", "-p", *(["-e"] if colors else []))

    def keys(self, *keys: str) -> None:
        self._run("send-keys", *keys)

    def wait(self, found: Callable[[str], bool], timeout: float = 15, colors: bool = False) -> str:
        deadline = time.monotonic() + timeout
        while True:
            text = self.screen(colors)
            if found(text):
                return text
            if time.monotonic() > deadline:
                raise AssertionError(f"not on the screen after {timeout}s:\n{text}")
            time.sleep(0.1)

    def kill(self) -> None:
        subprocess.run(["tmux", "-L", self.socket, "kill-server"], capture_output=True, timeout=10,
                       stdin=subprocess.DEVNULL, check=False)
        with contextlib.suppress(OSError):  # the server leaves its socket file behind
            os.unlink(self.path)


# -- a large structure (the web view's 500-state model) ------------------------------------------
def many_states(groups: int = 20, per: int = 24) -> dict[str, Any]:
    """``groups`` composite states of ``per`` leaves each, in a ring: 500 states by default
    (tests/test_web.py and bench/web.py)."""
    states: list[dict[str, Any]] = []
    automata = [{"owner": "", "region": None, "use": None, "period_ms": 100, "initial": "G0", "history": False}]
    transitions: list[dict[str, Any]] = []
    for g in range(groups):
        states.append({"path": f"G{g}", "final": False, "composite": True})
        automata.append({"owner": f"G{g}", "region": None, "use": None, "period_ms": 10, "initial": "S0", "history": False})
        for i in range(per):
            states.append({"path": f"G{g}/S{i}", "final": False, "composite": False})
            transitions.append({"from": f"G{g}/S{i}", "to": f"G{g}/S{(i + 1) % per}",
                                "index": 0, "name": None})
        transitions.append({"from": f"G{g}", "to": f"G{(g + 1) % groups}", "index": 0,
                            "name": None})
    return {"name": "many", "automata": automata, "states": states, "transitions": transitions,
            "variables": [], "parameters": {}}


# -- tests/cpp/observers_main.cpp: the C++ observers played a fixed run of the blinker --------
OBSERVERS_FLAGS = ["-std=c++17", "-Wall", "-Wextra", "-Werror", "-Wpedantic", "-pthread"]
SANITIZERS = ["-fsanitize=address,undefined", "-fno-omit-frame-pointer", "-fno-sanitize-recover=all",
              "-g"]


def compile_observers(out: Path, extra: list[str]) -> Path:
    """tests/cpp/observers_main.cpp compiled with the component's headers into ``out``."""
    gxx = shutil.which("g++")
    assert gxx is not None, "g++ is needed to test the C++ observers"
    cmd = [gxx, *OBSERVERS_FLAGS, *extra, "-I", str(ROOT / "templates" / "cpp"),
           str(ROOT / "tests" / "cpp" / "observers_main.cpp"),
           str(ROOT / "templates" / "cpp" / "hfsmc_json.cpp"), "-o", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=240, check=False)
    assert done.returncode == 0, done.stderr
    return out


class Live:
    """A driver (a vehicle, a camera) as a snippet sees it when every call is an instant
    of its own: a snapshot before each public call (docs/recording.md)."""

    def __init__(self, driver: Any) -> None:
        object.__setattr__(self, "_driver", driver)

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._driver, name)
        if name.startswith("_") or name in ("snapshot", "close") or not callable(attr):
            return attr

        def call(*args: Any, **kwargs: Any) -> Any:
            self._driver.snapshot()
            return getattr(self._driver, name)(*args, **kwargs)
        return call

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self._driver, name, value)


# -- drone flights: the component and `hfsmc sim` (tests/test_missions.py, test_lockstep.py) ----
HFSMC = [sys.executable, "-m", "hfsmc"]
FOLLOW = ROOT / "examples/follow_colors"
FOLLOW_CPP = ROOT / "examples/follow_colors_cpp"


@dataclass
class Flight:
    folder: Path
    component: subprocess.Popen[bytes]
    sim: subprocess.Popen[bytes]
    started: float  # monotonic time the simulator was started
    component_started: float

    @property
    def trace(self) -> list[dict[str, object]]:
        path = self.folder / "trace.jsonl"
        lines = path.read_text().splitlines() if path.exists() else []
        return [json.loads(line) for line in lines if line.endswith("}")]

    def truth(self) -> dict[str, object]:
        data: dict[str, object] = json.loads((self.folder / "truth.json").read_text())
        return data

    def wait_for(self, ev: str, key: str, value: str, timeout: float,
                 **also: str) -> dict[str, object]:
        """The first trace record with ev, key == value (and the other keys given)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for rec in self.trace:
                if rec.get("ev") == ev and rec.get(key) == value and \
                        all(rec.get(k) == v for k, v in also.items()):
                    return rec
            if self.component.poll() is not None:
                break
            time.sleep(0.2)
        raise AssertionError(f"no {ev} {key}={value} within {timeout} s: "
                             f"{(self.folder / 'component.log').read_text()[-2000:]}")

    def stop_sim(self) -> None:
        if self.sim.poll() is None:
            self.sim.send_signal(signal.SIGINT)
            self.sim.wait(timeout=20)


@contextmanager
def flight(tmp_path: Path, *sim_args: str, model: Path = FOLLOW / "follow_colors.yaml",
           world: Path = FOLLOW / "world.yaml",
           command: list[str] | None = None,
           component_args: tuple[str, ...] = (), lockstep: bool = False) -> Iterator[Flight]:
    """Start the simulator and the component on free ports: `command` (a built component's
    command line), or else the Python component of `model`, built here. ``lockstep``: the
    simulator is the component's clock (`--lockstep PORT`, `--clock sim:PORT`)."""
    folder = tmp_path / "flight"
    if command is None:
        r = subprocess.run([*HFSMC, "build", str(model), "-o", str(folder / "component")],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        command = [sys.executable, str(folder / "component" / f"{model.stem}.py")]
    folder.mkdir(parents=True, exist_ok=True)
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    clock: tuple[str, ...] = ()
    if lockstep:
        port = free_port(socket.SOCK_STREAM)
        sim_args = ("--lockstep", str(port), *sim_args)
        clock = ("--clock", f"sim:{port}")
    config = {"parameters": {"report": str(folder / "report.json")},
              "interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
                             "camera": {"type": "camera",
                                        "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}
    (folder / "config.yaml").write_text(json.dumps(config))
    sim_log = (folder / "sim.log").open("wb")
    comp_log = (folder / "component.log").open("wb")
    sim = subprocess.Popen([*HFSMC, "sim", "--world", str(world), "--mavlink",
                            f"udpout:127.0.0.1:{udp}", "--camera-port", str(http),
                            "--truth", str(folder / "truth.json"), *sim_args],
                           stdout=sim_log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    started = time.monotonic()
    component = subprocess.Popen(
        [*command, "--config", str(folder / "config.yaml"), "--trace", str(folder / "trace.jsonl"),
         "--until", "240s", *clock, *component_args],
        stdout=comp_log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    f = Flight(folder, component, sim, started, time.monotonic())
    try:
        yield f
    finally:
        for p in (component, sim):
            if p.poll() is None:
                p.kill()
            p.wait(timeout=20)
        sim_log.close()
        comp_log.close()


def fired_into(trace: list[dict[str, object]]) -> list[str]:
    return [str(r["to"]) for r in trace if r["ev"] == "fire"]


# -- the edit engine -----------------------------------------------------------------------
def library_and_users(tmp_path: Path) -> tuple[Path, Path, Path]:
    """lib/takeoff.yaml and two models that use it, one YAML and one XML."""
    (tmp_path / "lib").mkdir()
    lib = tmp_path / "lib" / "takeoff.yaml"
    lib.write_text((ROOT / "examples" / "lib" / "takeoff.yaml").read_text())
    (tmp_path / "lib" / "land.yaml").write_text((ROOT / "examples" / "lib" / "land.yaml").read_text())
    (tmp_path / "app").mkdir()
    user = tmp_path / "app" / "m.yaml"
    user.write_text((ROOT / "examples" / "follow_colors" / "follow_colors.yaml").read_text())
    xml = tmp_path / "app" / "m.xml"
    xml.write_text((ROOT / "examples" / "traffic_light" / "traffic_light.xml").read_text().replace(
        '  <parameter name="cycles"',
        '  <interface name="drone" type="mavlink" url="udpin:127.0.0.1:14550"/>\n  <parameter name="cycles"'
    ).replace(
        '<state name="Night" final="true"/>',
        '<state name="Up" use="../lib/takeoff.yaml">\n'
        '      <transition to="Night"><when>active("Up/Airborne") or active(&quot;Up/Climb&quot;)</when>'
        '</transition>\n    </state>\n    <state name="Night" final="true"/>'))
    return lib, user, xml
