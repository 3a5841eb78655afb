"""The C++ component's observers (templates/cpp/hfsmc/monitor.hpp, view.hpp): the monitor
speaks the Python monitor's protocol, so `hfsmc view` watches a C++ component, and the
display prints what the Python display prints.

tests/cpp/observers_main.cpp plays a fixed run of the blinker of tests/support.py
through the observers, as the runtime calls them; it is compiled once per session
(plain and with ASan/UBSan). Everything on 127.0.0.1 with port 0, bounded in time."""

from __future__ import annotations

import contextlib
import fcntl
import importlib
import io
import json
import os
import pty
import re
import select
import shutil
import signal
import socket
import struct
import subprocess
import termios
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from tests.conftest import ROOT
from tests.support import (
    MONITOR_VALIDATOR,
    PARALLEL_STRUCTURE,
    STRUCTURE,
    USED_STRUCTURE,
    Client,
    read_messages,
)

hfsmc_monitor = importlib.import_module("hfsmc.templates.python.hfsmc_monitor")
hfsmc_view = importlib.import_module("hfsmc.templates.python.hfsmc_view")

pytestmark = pytest.mark.timeout(180)

SANITIZER_ENV = {"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0:exitcode=99",
                 "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1:exitcode=99"}
SANITIZER_ERRORS = re.compile(r"AddressSanitizer|ThreadSanitizer|LeakSanitizer|runtime error:|UndefinedBehaviorSanitizer")


@pytest.fixture(params=["plain", "asan"])
def build(request: pytest.FixtureRequest) -> tuple[Path, dict[str, str]]:
    """The program and its environment, in both builds."""
    if request.param == "plain":
        return request.getfixturevalue("observers_program"), {}
    return request.getfixturevalue("observers_asan_program"), SANITIZER_ENV


class Run:
    """observers_main running with a gate: the first calls of the run are made at once,
    the others once ``release`` is called."""

    def __init__(self, exe: Path, tmp: Path, *args: str, env: dict[str, str] | None = None,
                 prefix: tuple[str, ...] = (), **popen: Any) -> None:
        tmp.mkdir(parents=True, exist_ok=True)
        self.gate, self.calls = tmp / "gate", tmp / "calls.jsonl"
        cmd = [*prefix, str(exe), "--gate", str(self.gate), "--calls", str(self.calls), *args]
        popen.setdefault("stdout", subprocess.PIPE)
        popen.setdefault("stderr", subprocess.PIPE)
        self.proc = subprocess.Popen(cmd, env={**os.environ, **(env or {})}, **popen)
        self.port = 0
        if "--monitor" in args and self.proc.stderr is not None:
            line = self.proc.stderr.readline().decode()
            m = re.fullmatch(r"monitor: listening on 127\.0\.0\.1:(\d+)\n", line)
            assert m, f"no announcement: {line!r}"
            self.port = int(m[1])

    def at_gate(self) -> None:
        """Wait until the program has made its first calls (and the monitor taken them)."""
        assert self.proc.stderr is not None
        while (line := self.proc.stderr.readline()) != b"component: at the gate\n":
            assert line, "the program ended before the gate"
        time.sleep(0.3)

    def release(self, gate: int = 0) -> None:
        (self.gate.with_suffix(f".{gate}") if gate else self.gate).touch()

    def finish(self, timeout: float = 60) -> tuple[bytes, str]:
        """(stdout, stderr) once the program has exited 0 and said nothing of sanitizers."""
        for gate in range(4):
            self.release(gate)
        out, err = self.proc.communicate(timeout=timeout)
        text = (err or b"").decode(errors="replace")
        assert not SANITIZER_ERRORS.search(text), text
        assert self.proc.returncode == 0, text
        return out or b"", text

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.communicate()


@pytest.fixture
def run(tmp_path: Path) -> Iterator[Callable[..., Run]]:
    made: list[Run] = []

    def start(exe: Path, *args: str, **kw: Any) -> Run:
        made.append(Run(exe, tmp_path / str(len(made)), *args, **kw))
        return made[-1]

    yield start
    for r in made:
        r.kill()


def calls_of(r: Run) -> list[tuple[str, Any]]:
    """The observer calls the program made, as (kind, payload) items of the Python view."""
    out: list[tuple[str, Any]] = []
    for line in r.calls.read_text().splitlines():
        call = json.loads(line)
        if "record" in call:
            out.append(("record", call["record"]))
        else:
            s = call["sample"]
            out.append(("sample", (s["t"], s["variables"], s["overruns"])))
    return out


def record_lines(r: Run, first: int = 0) -> list[bytes]:
    """The records from call ``first`` on, exactly as the trace writes them."""
    return [line[len('{"record":'):-1].encode() for line in r.calls.read_text().splitlines()[first:]
            if line.startswith('{"record":')]


def test_an_address_in_use_is_a_clear_error(observers_program: Path) -> None:
    with socket.create_server(("127.0.0.1", 0)) as busy:
        port = busy.getsockname()[1]
        done = subprocess.run([str(observers_program), "--monitor", str(port)], capture_output=True, text=True,
                              timeout=10, check=False)
    assert done.returncode == 2
    assert done.stderr == "error: [Errno 98] Address already in use\n"


# -- the monitor -------------------------------------------------------------------------
def test_python_viewer_attaches_late_and_sees_the_current_state(observers_program: Path, run: Any) -> None:
    r = run(observers_program, "--monitor", "0", "--pause-ms", "20")
    viewer = subprocess.Popen([str(ROOT / ".venv" / "bin" / "python"), "-m", "hfsmc", "view",
                               f"127.0.0.1:{r.port}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    try:
        assert viewer.stdout is not None
        first = viewer.stdout.readline()  # the snapshot: the viewer is attached
        r.release()
        rest, err = viewer.communicate(timeout=30)
    finally:
        if viewer.poll() is None:
            viewer.kill()
            viewer.communicate()
    r.finish()
    assert (first + rest).splitlines() == [
        "  0.600  in Blinking/Dark",
        "  1.000  Blinking/Dark -> Blinking/Lit",
        "  3.000  Blinking -> Paused  (pause)",
        "  3.100  interrupt (error) -> Done",
        "  3.100  stop (error)",
    ]
    assert viewer.returncode == 0
    assert err.splitlines()[-1] == "hfsmc view: component stopped (error)"


def _message_of(item: tuple[str, Any]) -> dict[str, Any]:
    kind, payload = item
    msg = hfsmc_monitor.message(kind, payload)
    assert isinstance(msg, dict)
    return msg


# The run is gated in Blinking/Dark (9 calls), in Paused (19) and after the stop (26).
@pytest.mark.parametrize("gate_at", [9, 19, 26])
def test_raw_client_gets_the_protocol_of_the_python_monitor(build: tuple[Path, dict[str, str]],
                                                            run: Callable[..., Run], clients: Callable[..., Client],
                                                            gate_at: int) -> None:
    exe, env = build
    r = run(exe, "--monitor", "0", "--gate-at", str(gate_at), env=env)
    r.at_gate()
    c = clients(r.port)
    hello, snapshot = c.message(), c.message()
    r.release()
    rest = c.until_bye()
    r.finish()
    assert hello == {"type": "hello", "protocol": 1, "minor": 4, "structure": STRUCTURE,
                     "feeds": {"vehicle": [], "camera": [], "ros2": [], "driver": []}}
    assert snapshot is not None and snapshot["type"] == "snapshot"
    assert rest[-1] == {"type": "bye", "reason": "error"}
    # What followed the snapshot is the tail of the run, and the snapshot is the Python
    # view of everything before it: together, the whole run, nothing missed or repeated.
    calls = calls_of(r)
    k = len(calls) - len(rest) + 1
    assert [_message_of(it) for it in calls[k:]] == rest[:-1]
    assert k == gate_at
    view = hfsmc_view.ViewState(STRUCTURE)
    for it in calls[:k]:
        view.apply(*it)
    assert snapshot == json.loads(json.dumps(view.snapshot()))
    # Records are the trace's lines, byte for byte; every line is ASCII.
    sent = [line for line in c.lines if line.startswith(b'{"type":"record"')]
    assert sent == [b'{"type":"record","record":' + rec + b"}\n" for rec in record_lines(r, k)]
    assert all(line.isascii() for line in c.lines)


def test_strings_are_escaped_as_json_dumps_does(observers_program: Path, run: Callable[..., Run],
                                                clients: Callable[..., Client]) -> None:
    r = run(observers_program, "--monitor", "0", "--gate-at", "26")
    r.at_gate()
    c = clients(r.port)
    snapshot = c.message() and c.message()
    r.release()
    c.until_bye()
    r.finish()
    msg = "dark \"now\" \\ caf\u00e9 \u2713 \U0001f681 \x1b[2J\ttab"
    assert json.dumps(msg).encode() in c.lines[1]
    assert snapshot is not None
    assert {"t": 500, "state": "Blinking/Dark", "msg": msg} in snapshot["logs"]
    assert {"t": 3100, "state": "Paused", "error": "during"} in snapshot["logs"]
    assert snapshot["stop"]["states"] == [{"state": "Done", "since": 3100}]


def _drain(c: Client) -> bytes:
    c.sock.settimeout(10)
    data = b""
    with contextlib.suppress(OSError):
        while chunk := c.sock.recv(1 << 20):
            data += chunk
    return data


def test_misbehaving_clients_change_nothing(build: tuple[Path, dict[str, str]], run: Callable[..., Run],
                                            clients: Callable[..., Client]) -> None:
    exe, env = build
    burst = 30000  # log records of about 130 bytes: 4 MB at once
    r = run(exe, "--monitor", "0", "--burst", str(burst), "--gate-at", "9", "--gate-at", str(9 + burst),
            env=env)
    r.at_gate()
    good, halfclosed, chatty = clients(r.port), clients(r.port), clients(r.port)
    halfclosed.sock.shutdown(socket.SHUT_WR)  # as nc does at the end of its input
    chatty.sock.sendall(b"\x00\xff{not json\n[1,2" * 1000)  # read and thrown away
    stuck = clients(r.port, rcvbuf=4096)  # does not read during the burst
    killed = clients(r.port)
    killed.message()
    killed.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    killed.close()  # reset mid-stream
    flood = clients(r.port)
    flood.read_fast()
    with contextlib.suppress(OSError):
        for _ in range(64):  # 2 MiB: more than a client may send
            flood.sock.sendall(os.urandom(1 << 15))
    for c in (good, halfclosed, chatty):
        c.read_fast()
    t0 = time.monotonic()
    r.release()
    r.at_gate()  # the burst is made; the component still runs
    stuck.read_fast()
    # The flooder and the stuck client were dropped: their streams have ended, without a bye.
    for c in (flood, stuck):
        data = c.received(10)
        assert c._reader is not None and not c._reader.is_alive(), "still connected"
        assert b'"type":"bye"' not in data
    r.finish()
    assert time.monotonic() - t0 < 30
    for c in (good, halfclosed, chatty):
        msgs = c.collected()
        logs = [m for m in msgs if m["type"] == "record" and m["record"].get("msg", "").startswith("burst ")]
        assert len(logs) == burst


def test_too_many_clients_are_turned_away(observers_program: Path, run: Callable[..., Run],
                                          clients: Callable[..., Client]) -> None:
    """16 served (8 an address), the 17th told busy and closed, the 16 see the run's end."""
    r = run(observers_program, "--monitor", "0")
    served = [clients(r.port, source=f"127.0.0.{1 + i % 2}") for i in range(16)]
    for c in served:
        assert c.message() is not None
    extra = clients(r.port, source="127.0.0.3")
    assert _drain(extra) == (b'{"type":"busy","reason":"all 16 viewer slots are taken; '
                             b'try again later"}\n'), "the 17th connection is told why and closed"
    r.release()
    for c in served:
        assert c.until_bye()[-1]["type"] == "bye"
    r.finish()


def test_close_is_quick_with_a_stuck_client(observers_program: Path, run: Callable[..., Run],
                                            clients: Callable[..., Client]) -> None:
    r = run(observers_program, "--monitor", "0", "--burst", "3000")
    clients(r.port, rcvbuf=4096)
    _, err = r.finish()
    ms = int(re.findall(r"closed in (\d+) ms", err)[0])
    assert ms < 900


def test_threads_block_sigint_and_sigterm(observers_program: Path, run: Callable[..., Run]) -> None:
    r = run(observers_program, "--monitor", "0", "--display", "--masks")
    out, _ = r.finish()
    text = out.decode()
    main = int(re.findall(r"^main (\d+)$", text, re.M)[0])
    masks = {int(tid): int(mask, 16)
             for tid, mask in re.findall(r"^task (\d+) SigBlk:\s*([0-9a-f]+)$", text, re.M)}
    assert len(masks) == 3, masks  # the automaton's, the monitor's, the display's
    bits = 1 << (signal.SIGINT - 1) | 1 << (signal.SIGTERM - 1)
    for tid, mask in masks.items():
        assert (mask & bits) == (0 if tid == main else bits), (tid, hex(mask))


# -- the display -------------------------------------------------------------------------
@pytest.mark.parametrize("focus", [None, "Blinking", "/Blinking/"])
def test_display_plain_lines_are_the_python_ones(build: tuple[Path, dict[str, str]], run: Callable[..., Run],
                                                 focus: str | None) -> None:
    exe, env = build
    r = run(exe, "--display", *(["--focus", focus] if focus else []), env=env)
    out, _ = r.finish()
    expected = io.StringIO()
    d = hfsmc_view.Display(focus=focus, stream=expected)
    d.start(STRUCTURE)
    for kind, payload in calls_of(r):
        if kind == "record":
            d.record(payload)
        else:
            d.sample(*payload)
    d.close()
    assert out.decode() == expected.getvalue()
    assert out.decode().startswith("  0.000  start blinker in Blinking/Lit\n")


def test_display_plain_lines_reach_a_closed_pipe_without_harm(observers_program: Path, run: Callable[..., Run]) -> None:
    r = run(observers_program, "--display", "--burst", "3000")
    assert r.proc.stdout is not None
    r.proc.stdout.close()
    r.finish()


class Terminal:
    """A pseudo-terminal that the program gets as its controlling terminal (setsid --ctty)."""

    def __init__(self, rows: int = 40, cols: int = 120) -> None:
        self.master, self.slave = pty.openpty()
        fcntl.ioctl(self.slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
        self.out = b""

    def read_until(self, pattern: bytes, timeout: float = 15) -> None:
        deadline = time.monotonic() + timeout
        while pattern not in self.out and time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], 0.1)
            if ready:
                with contextlib.suppress(OSError):
                    self.out += os.read(self.master, 65536)
        assert pattern in self.out, self.out[-3000:]

    def frame(self, *parts: bytes, timeout: float = 15) -> bytes:
        """The latest frame (what follows the last clear) once it holds every one of
        ``parts``: a frame can be read while the view is still writing it."""
        deadline = time.monotonic() + timeout
        while True:
            last = self.out.rpartition(b"\x1b[J")[2]
            if all(p in last for p in parts) or time.monotonic() > deadline:
                return last
            ready, _, _ = select.select([self.master], [], [], 0.1)
            if ready:
                with contextlib.suppress(OSError):
                    self.out += os.read(self.master, 65536)

    def close(self) -> None:
        os.close(self.master)
        os.close(self.slave)


def test_display_on_a_terminal(build: tuple[Path, dict[str, str]], run: Callable[..., Run]) -> None:
    exe, env = build
    setsid = shutil.which("setsid")
    assert setsid is not None, "setsid (util-linux) is needed to give the program a terminal"
    tty = Terminal()
    try:
        before = termios.tcgetattr(tty.slave)
        r = run(exe, "--display", "--pause-ms", "150", prefix=(setsid, "--ctty"), env=env,
                stdin=tty.slave, stdout=tty.slave, stderr=tty.slave)
        tty.read_until(b"\x1b[1;32m\xe2\x97\x8f Dark")  # active states are green
        assert termios.tcgetattr(tty.slave)[3] & termios.ECHO == 0, "keys are read one by one"
        os.write(tty.master, b"a")
        tty.read_until(b"off (a: on)")
        r.release()
        tty.read_until(b"closed in")
        assert r.proc.wait(timeout=15) == 0
        after = termios.tcgetattr(tty.slave)
        assert after[3] & (termios.ECHO | termios.ICANON) == before[3] & (termios.ECHO | termios.ICANON)
        last = tty.out.rpartition(b"\x1b[J")[2]
        assert b"stopped (error)" in last
        assert b"\x1b[1;33m\xe2\x96\xa0 Done" in last, "the states the stop left are yellow"
        assert b"\xe2\x96\xb8 2 states" not in last, "autofocus is off: Blinking is expanded"
        assert tty.out.count(b"component: past the gate") == 1
        # printed above the frame: right after it is erased, before it is drawn again
        assert re.search(rb"\x1b\[J(component: [a-z ]+\r\n)*component: past the gate\r\n", tty.out)
    finally:
        tty.close()


def test_display_fits_80x24_and_says_when_keys_are_not_read(observers_program: Path,
                                                             run: Callable[..., Run]) -> None:
    """30 log lines and 8 transitions on an 80x24 terminal: every frame is at most 23
    lines of at most 80 columns; stdin is not the terminal, and the panel says so."""
    tty = Terminal(24, 80)
    try:
        r = run(observers_program, "--display", "--burst", "30", stdin=subprocess.DEVNULL,
                stdout=tty.slave, stderr=tty.slave)
        tty.read_until(b"no keys: stdin is not a terminal")
        r.release()
        tty.read_until(b"closed in")
        assert r.proc.wait(timeout=15) == 0
        frames = [f for f in tty.out.split(b"\x1b[J")[1:] if b"autofocus" in f]
        assert frames
        for frame in frames:
            text = re.sub(rb"\x1b\[[0-9;]*[A-Za-z]", b"", frame).decode()
            lines = [ln for ln in text.split("\r\n") if not ln.startswith(("component:", "[", "observers"))]
            assert len([ln for ln in lines if ln]) <= 23, text
            assert all(len(ln) <= 80 for ln in lines), text
        # Sections are cut, not the frame: the newest log line and the variables show.
        final = re.sub(rb"\x1b\[[0-9;]*[A-Za-z]", b"", frames[-1]).decode()
        assert "on_shutdown stopped after 2 blinks" in final and "pauses 1" in final, final
        assert "\u2026" not in final, final
    finally:
        tty.close()


READABLE = ["0.30000000000000004", "[1.2345678, 'x1.2345678', -2.0000000000000004]",
            "np.float64(0.1234567891)", "1.23456789e-07", "12345678.9", "123456789", "x1.23456789",
            "{'a': 3.14159265358979, \"b\": \"it's 2.718281828\"}", "(0.1+0.2j)", "3.0", "1e+20",
            "100000000000000000000.0", "-0.000123456789", "v_2.5555555", "é1.23456789", "1.5e300",
            "[nan, inf, -inf]", "0.1234565", "2.5000005", "'unterminated 1.23456789"]


def test_readable_values_and_panel_fit_are_the_python_ones(observers_program: Path) -> None:
    r = subprocess.run([str(observers_program), "--readable"], input="\n".join(READABLE) + "\n",
                       capture_output=True, text=True, timeout=30, check=False)
    assert r.returncode == 0, r.stderr
    hfsmc_viewstate = importlib.import_module("hfsmc.templates.python.hfsmc_viewstate")
    assert r.stdout.splitlines() == [hfsmc_viewstate.readable(v) for v in READABLE]
    assert hfsmc_viewstate.readable("0.30000000000000004") == "0.3"
    cases = [(free, t, lg, v) for free in (-3, 0, 3, 7, 12, 40) for t in (0, 1, 8)
             for lg in (0, 2, 8) for v in (0, 1, 5)]
    r = subprocess.run([str(observers_program), "--fit"], input="".join(f"{c[0]} {c[1]} {c[2]} {c[3]}\n"
                                                             for c in cases),
                       capture_output=True, text=True, timeout=30, check=False)
    want = [hfsmc_view.fit(free, {"transitions": t, "logs": lg, "variables": v})
            for free, t, lg, v in cases]
    assert r.stdout.splitlines() == [f"{w['transitions']} {w['logs']} {w['variables']}"
                                     for w in want]


def test_feeds_go_to_every_client_and_frames_only_to_those_that_subscribe(
        observers_program: Path, run: Callable[..., Run]) -> None:
    """Minor version 1 in C++: the registered feeds (stand-ins for mavlink.hpp and camera.hpp)."""
    r = run(observers_program, "--monitor", "0", "--feeds", "--gate-at", "9")
    r.at_gate()
    asks = socket.create_connection(("127.0.0.1", r.port), timeout=5)
    quiet = socket.create_connection(("127.0.0.1", r.port), timeout=5)
    try:
        asks.sendall(b'junk\n{"type":"subscribe","frames":1}\n' + b"y" * 3000 + b"\n"
                     b'{"type": "subscribe", "frames": true}\n')
        got, other = read_messages(asks, 1.2), read_messages(quiet, 1.2)
        for msgs in (got, other):
            for m in msgs:
                MONITOR_VALIDATOR.validate(m)
            assert msgs[0] == {"type": "hello", "protocol": 1, "minor": 4, "structure": STRUCTURE,
                               "feeds": {"vehicle": ["drone"], "camera": ["camera"], "ros2": [],
                                         "driver": []}}
        # About 4 a second (a subscription sends at once): 1.2 s for one, 2.4 s for the other.
        assert 3 <= [m["type"] for m in got].count("vehicle") <= 8, got
        assert 6 <= [m["type"] for m in other].count("vehicle") <= 13, other
        frames = [m for m in got if m["type"] == "frame"]
        assert 3 <= len(frames) <= 8 and "frame" not in {m["type"] for m in other}, got
        asks.sendall(b'{"type":"subscribe","frames":false}\n')
        read_messages(asks, 0.3)
        assert "frame" not in {m["type"] for m in read_messages(asks, 0.6)}
    finally:
        asks.close()
        quiet.close()
    r.finish()


# -- a state with regions (observers_main --regions) ------------------------------------------
def test_regions_reach_the_monitor_as_the_python_one_sends_them(observers_program: Path, run: Callable[..., Run],
                                                                clients: Callable[..., Client]) -> None:
    """The hello names each automaton's region; the snapshot of a run with two regions
    active is the Python view's."""
    r = run(observers_program, "--regions", "--monitor", "0", "--gate-at", "9")
    r.at_gate()
    c = clients(r.port)
    hello, snapshot = c.message(), c.message()
    r.release()
    rest = c.until_bye()
    r.finish()
    for m in (hello, snapshot, *rest):
        MONITOR_VALIDATOR.validate(m)
    assert hello is not None and hello["structure"] == PARALLEL_STRUCTURE
    view = hfsmc_view.ViewState(PARALLEL_STRUCTURE)
    for it in calls_of(r)[:9]:
        view.apply(*it)
    assert snapshot is not None and snapshot == json.loads(json.dumps(view.snapshot()))
    assert [a["state"] for a in snapshot["active"]] == ["Mission", "Mission/Watch/Ok", "Mission/Nav/B"]


@pytest.mark.parametrize("focus", [None, "Mission/Watch"])
def test_display_of_regions_prints_the_python_lines(build: tuple[Path, dict[str, str]], run: Callable[..., Run],
                                                    focus: str | None) -> None:
    exe, env = build
    r = run(exe, "--regions", "--display", *(["--focus", focus] if focus else []), env=env)
    out, _ = r.finish()
    expected = io.StringIO()
    d = hfsmc_view.Display(focus=focus, stream=expected)
    d.start(PARALLEL_STRUCTURE)
    for kind, payload in calls_of(r):
        if kind == "record":
            d.record(payload)
        else:
            d.sample(*payload)
    d.close()
    assert out.decode() == expected.getvalue()
    assert out.decode().startswith("  0.000  start par in Mission/Nav/A, Mission/Watch/Ok\n")


def test_display_of_regions_on_a_terminal(observers_program: Path, run: Callable[..., Run]) -> None:
    """Regions as named groups under their state, every region's active state green."""
    tty = Terminal(30, 120)
    try:
        r = run(observers_program, "--regions", "--display", "--gate-at", "9", stdin=subprocess.DEVNULL,
                stdout=tty.slave, stderr=tty.slave)
        tty.read_until(b"component: at the gate")
        tty.read_until(b"\x1b[35mn\x1b[0m 2")
        frame = tty.out.rpartition(b"\x1b[J")[2]
        r.release()
        tty.read_until(b"closed")
        assert r.proc.wait(timeout=15) == 0
        plain = re.sub(rb"\x1b\[[0-9;]*[A-Za-z]", b"", frame).decode()
        lines = [ln for ln in plain.split("\r\n") if not ln.startswith("component:")]
        tree = [ln[:33].rstrip() for ln in lines[:9]]
        assert tree == ["par  100 ms",
                        "├── ● Mission ‖  0.6s",
                        "│   ├── [Nav 100 ms]",
                        "│   │   ├── ○ A",
                        "│   │   └── ● B  0.4s  final",
                        "│   └── [Watch 300 ms history]",
                        "│       ├── ● Ok  0.6s",
                        "│       └── ○ Seen  final",
                        "└── ○ Done  final"], plain
        for state in (b"B", b"Ok"):  # both regions' states at once
            assert re.search(rb"\x1b\[1;32m\xe2\x97\x8f " + state + rb"\x1b", frame), frame
        assert b"\x1b[32m[Nav 100 ms]" in frame
    finally:
        tty.close()


# -- a sub-automaton used from another file (observers_main --use) --------------------------
def test_a_used_file_reaches_the_monitor_as_the_python_one_sends_it(
        observers_program: Path, run: Callable[..., Run], clients: Callable[..., Client]) -> None:
    r = run(observers_program, "--use", "--monitor", "0", "--gate-at", "9")
    r.at_gate()
    hello = clients(r.port).message()
    r.finish()
    assert hello is not None
    MONITOR_VALIDATOR.validate(hello)
    assert hello["structure"] == USED_STRUCTURE


def test_display_of_a_used_file_on_a_terminal(build: tuple[Path, dict[str, str]], run: Callable[..., Run]) -> None:
    """The state's line names the file, as the Python view's tree writes it."""
    exe, env = build
    tty = Terminal(30, 120)
    try:
        r = run(exe, "--use", "--display", "--gate-at", "9", stdin=subprocess.DEVNULL,
                stdout=tty.slave, stderr=tty.slave, env=env)
        tty.read_until(b"component: at the gate")
        tty.read_until(b"\x1b[35mpauses\x1b[0m 0")
        frame = tty.frame(b"\x1b[35mpauses\x1b[0m 0", b"final")  # the whole tree
        r.release()
        tty.read_until(b"closed")
        assert r.proc.wait(timeout=15) == 0
        view = hfsmc_view.ViewState(USED_STRUCTURE)
        for it in calls_of(r)[:9]:
            view.apply(*it)
        shown = io.StringIO()
        Console(file=shown, width=120, color_system=None).print(hfsmc_view.render(view, width=120))
        first = shown.getvalue().splitlines()
        py_tree = [ln[:first[0].index("╭")].rstrip() for ln in first[:6]]
        assert py_tree[1] == "├── ● Blinking · lib/blink.yaml  0.6s  50 ms history", py_tree
        plain = re.sub(rb"\x1b\[[0-9;]*[A-Za-z]", b"", frame).decode()
        lines = [ln for ln in plain.split("\r\n") if not ln.startswith("component:")]
        assert [ln[:len(want) + 2] for ln, want in zip(lines, py_tree, strict=False)] == \
            [want + "  " for want in py_tree], plain
        assert b"\x1b[1;32m\xe2\x97\x8f Blinking\x1b[0m\x1b[2m \xc2\xb7 lib/blink.yaml\x1b[0m" in frame
    finally:
        tty.close()


def test_busy_is_said_and_one_address_cannot_take_every_slot(
        observers_program: Path, run: Callable[..., Run], clients: Callable[..., Client]) -> None:
    """As the Python monitor: 16 slots, at most 8 for one address, `busy` and why to the others."""
    r = run(observers_program, "--monitor", "0", "--gate-at", "9")
    r.at_gate()
    mine = [clients(r.port) for _ in range(8)]
    for c in mine:
        assert c.message() is not None
    ninth = clients(r.port)
    assert ninth.message() == {"type": "busy", "reason": "the viewers from 127.0.0.1 hold 8 of "
                               "the 16 slots, the most one address may; close one"}
    assert ninth.message() is None
    others = [clients(r.port, source="127.0.0.2") for _ in range(8)]
    for c in others:
        assert c.message() is not None
    last = clients(r.port, source="127.0.0.3")
    assert last.message() == {"type": "busy",
                              "reason": "all 16 viewer slots are taken; try again later"}
    assert last.message() is None
    shown = subprocess.run([str(ROOT / ".venv" / "bin" / "python"), "-m", "hfsmc", "view",
                            f"127.0.0.1:{r.port}"], capture_output=True, text=True, timeout=60,
                           stdin=subprocess.DEVNULL)
    assert shown.returncode == 1 and shown.stderr.splitlines()[-1] == (
        "hfsmc view: error: the component's monitor is busy: all 16 viewer slots are taken; "
        "try again later")
    for c in (*mine, *others):
        c.close()
    r.finish()


def test_subscribing_again_and_again_makes_no_more_frames(
        observers_program: Path, run: Callable[..., Run]) -> None:
    """The stand-in camera has a new frame each time the monitor asks, numbered: however often
    a client subscribes, frames are made at most 4 times a second."""
    r = run(observers_program, "--monitor", "0", "--feeds", "--gate-at", "9")
    r.at_gate()
    quiet = socket.create_connection(("127.0.0.1", r.port), timeout=5)
    flood = socket.create_connection(("127.0.0.1", r.port), timeout=5)
    try:
        quiet.sendall(b'{"type":"subscribe","frames":true}\n')
        flood.setblocking(False)
        start, lines = time.monotonic(), 0
        while lines < 6000:
            flood.sendall(b'{"type":"subscribe","frames":true}\n{"type":"subscribe","frames":false}\n'
                          * 50 + b'{"type":"subscribe","frames":true}\n')
            lines += 101
            time.sleep(0.03)
            with contextlib.suppress(BlockingIOError):
                flood.recv(1 << 20)  # what it is sent, unread
        seen = [m for m in read_messages(quiet, 0.3) if m["type"] == "frame"]
        seconds = time.monotonic() - start
        made = int(seen[-1]["jpeg"])  # the stand-in's count of the frames it was asked to make
        assert 2 <= len(seen) <= made <= 4 * seconds + 2, (len(seen), made, seconds)
    finally:
        quiet.close()
        flood.close()
    r.finish()
