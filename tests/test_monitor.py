"""The monitor: the component's TCP server, the viewer's client, and `hfsmc view` attaching
late to a real component. Everything on 127.0.0.1 with port 0, bounded in time."""

from __future__ import annotations

import contextlib
import importlib
import io
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from hfsmc.commands.view import view
from hfsmc.emit.structure import structure_of
from hfsmc.pipeline import compile_file
from tests.conftest import ROOT
from tests.support import (
    GREEN,
    MONITOR_VALIDATOR,
    PARALLEL_RECORDS,
    PARALLEL_STRUCTURE,
    RECORDS,
    STRUCTURE,
    Client,
    Tmux,
    py,
    read_messages,
)

hfsmc_monitor = importlib.import_module("hfsmc.templates.python.hfsmc_monitor")
hfsmc_view = importlib.import_module("hfsmc.templates.python.hfsmc_view")
MonitorServer = hfsmc_monitor.MonitorServer

pytestmark = pytest.mark.timeout(60)


# -- addresses ---------------------------------------------------------------------------
PORT_WORDS = "expected [HOST:]PORT with a port from 0 to 65535"
# What `--monitor TEXT` means: (host, port), or the message of the error it is.
ADDRESSES: list[tuple[str, tuple[str, int] | str]] = [
    ("8765", ("127.0.0.1", 8765)),
    ("0", ("127.0.0.1", 0)),
    (":8765", ("127.0.0.1", 8765)),
    ("0.0.0.0:8765", ("0.0.0.0", 8765)),
    ("localhost:1", ("localhost", 1)),
    ("[::1]:65535", ("::1", 65535)),
    (" 80 ", ("127.0.0.1", 80)),
    *((text, f"bad address {text!r}: {PORT_WORDS}")
      for text in ("", "abc", "65536", "-1", "host:", "\uff18\uff17", "a'b", "x\ty")),
    ("1:2:3", "bad address '1:2:3': write an IPv6 address in brackets, [::1]:PORT"),
    ("[::1]8765", "bad address '[::1]8765': expected [HOST]:PORT"),
    ("[::1", "bad address '[::1': expected [HOST]:PORT"),
]


@pytest.mark.parametrize("backend", ["python", "cpp"])
@pytest.mark.parametrize(("text", "meaning"), ADDRESSES, ids=[repr(t) for t, _ in ADDRESSES])
def test_addresses(backend: str, text: str, meaning: tuple[str, int] | str,
                   request: pytest.FixtureRequest) -> None:
    """The Python monitor and the C++ one (tests/cpp/observers_main.cpp --parse) read an
    address alike."""
    if backend == "python":
        if isinstance(meaning, str):
            with pytest.raises(ValueError) as e:
                hfsmc_monitor.parse_address(text)
            assert str(e.value) == meaning
        else:
            assert hfsmc_monitor.parse_address(text) == meaning
        return
    program = request.getfixturevalue("observers_program")
    done = subprocess.run([str(program), "--parse", text], capture_output=True, text=True,
                          timeout=10, check=False)
    if isinstance(meaning, str):
        assert (done.returncode, done.stderr) == (2, f"error: {meaning}\n")
    else:
        assert (done.returncode, done.stdout) == (0, f"{meaning[0]} {meaning[1]}\n")


def test_ipv6_addresses_are_written_in_brackets() -> None:
    assert hfsmc_monitor.format_address("::1", 80) == "[::1]:80"
    assert hfsmc_monitor.format_address("127.0.0.1", 80) == "127.0.0.1:80"


# -- the server, driven like the runtime drives it -----------------------------------------
@pytest.fixture
def server() -> Iterator[Callable[..., Any]]:
    made: list[Any] = []

    def make(**kw: Any) -> Any:
        made.append(MonitorServer("127.0.0.1", 0, announce=io.StringIO(), **kw))
        return made[-1]

    yield make
    for s in made:
        s.close()


def is_record(ev: str) -> Callable[[dict[str, Any]], bool]:
    return lambda m: m["type"] == "record" and m["record"]["ev"] == ev


def attached(c: Client) -> Client:
    """``c`` once the server has taken it in (what comes next is not in its snapshot)."""
    c.until(lambda m: m["type"] == "snapshot")
    return c


def settle(srv: Any) -> None:
    """Wait until the server thread has taken everything queued so far."""
    deadline = time.monotonic() + 5
    while not srv._q.empty() and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.05)


def test_announces_its_address() -> None:
    out = io.StringIO()
    srv = MonitorServer("127.0.0.1", 0, announce=out)
    try:
        assert out.getvalue() == f"monitor: listening on 127.0.0.1:{srv.port}\n"
        assert srv.port > 0
        with pytest.raises(OSError):
            MonitorServer("127.0.0.1", srv.port, announce=io.StringIO())
    finally:
        srv.close()
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", srv.port), timeout=5).close()


def test_hello_then_snapshot_then_everything_in_order(server: Any, clients: Any) -> None:
    srv = server()
    srv.start(STRUCTURE)
    a = clients(srv.port)
    assert a.message() == {"type": "hello", "protocol": 1, "minor": 4, "structure": STRUCTURE,
                           "feeds": {"vehicle": [], "camera": [], "ros2": [], "driver": []}}
    snap = a.message()
    assert snap is not None and snap["type"] == "snapshot" and snap["active"] == []
    srv.sample(0, {"led": "False", "count": "0", "pauses": "0"}, 0)
    for rec in RECORDS:
        srv.record(rec)
    srv.close()
    got = a.until(lambda m: m["type"] == "bye")
    assert got[0] == {"type": "sample", "t": 0, "variables": {"led": "False", "count": "0",
                                                              "pauses": "0"}, "overruns": 0}
    assert [m["record"] for m in got[1:-1]] == RECORDS
    assert got[-1] == {"type": "bye", "reason": "sigint"}
    assert a.gone()


def test_a_late_viewer_gets_the_current_state_at_once(server: Any, clients: Any) -> None:
    srv = server()
    srv.start(STRUCTURE)
    for rec in RECORDS[:6]:
        srv.record(rec)
    srv.sample(740, {"led": "False", "count": "1", "pauses": "0"}, 2)
    settle(srv)
    late = clients(srv.port)
    assert late.message() is not None
    snap = late.message()
    assert snap is not None
    assert snap["active"] == [{"state": "Blinking", "since": 0}, {"state": "Blinking/Dark", "since": 500}]
    assert (snap["t"], snap["overruns"], snap["variables"]["count"]) == (740, 2, "1")
    assert [t["to"] for t in snap["transitions"]] == ["Blinking/Dark"]
    assert snap["stop"] is None and snap["started"] is True


def test_snapshot_and_what_follows_add_up_whenever_one_attaches(server: Any, clients: Any) -> None:
    """Attaching while records flow: snapshot + the messages after it = the full view."""
    srv = server()
    srv.start(STRUCTURE)
    whole = hfsmc_view.ViewState(STRUCTURE)
    for rec in RECORDS:
        whole.apply_record(rec)
    attached: list[Client] = []

    def attach() -> None:
        for _ in range(5):
            attached.append(Client(srv.port))
            time.sleep(0.002)

    th = threading.Thread(target=attach)
    th.start()
    for rec in RECORDS:
        srv.record(rec)
        time.sleep(0.001)
    th.join(10)
    srv.close()
    try:
        for c in attached:
            v = hfsmc_view.ViewState()
            for msg in c.until(lambda m: m["type"] == "bye"):
                kind, payload = hfsmc_monitor.item(msg)
                v.apply(kind, payload)
            assert (v.active, v.stop_reason, v.stopped_in, list(v.transitions)) == (
                whole.active, whole.stop_reason, whole.stopped_in, list(whole.transitions))
    finally:
        for c in attached:
            c.close()


def test_several_viewers_and_garbage_sent_to_the_port(server: Any, clients: Any) -> None:
    srv = server()
    srv.start(STRUCTURE)
    viewers = [attached(clients(srv.port)) for _ in range(3)]
    noisy = attached(clients(srv.port))
    noisy.sock.sendall(b"GET / HTTP/1.1\r\n\r\n\xff\xfe\x00{\"type\":\"record\"}\n" + os.urandom(4096))
    half = attached(clients(srv.port))
    half.sock.shutdown(socket.SHUT_WR)  # as `nc` does at the end of its input: still served
    for rec in RECORDS:
        srv.record(rec)
    for c in [*viewers, noisy, half]:
        got = c.until(is_record("stop"))
        assert [m["record"] for m in got if m["type"] == "record"] == RECORDS


def test_a_flooding_client_is_dropped_and_the_others_go_on(server: Any, clients: Any) -> None:
    srv = server()
    srv.start(STRUCTURE)
    good = attached(clients(srv.port))
    flood = attached(clients(srv.port))
    chunk = os.urandom(1 << 16)
    t0 = time.monotonic()
    try:
        for _ in range(64):  # 4 MiB, more than a client may send
            flood.sock.sendall(chunk)
            srv.record(RECORDS[0])
    except OSError:
        pass  # dropped while it was still sending
    for rec in RECORDS[1:]:
        srv.record(rec)
    assert flood.gone()
    got = good.until(is_record("stop"))
    assert [m["record"] for m in got if m["type"] == "record"][-len(RECORDS) + 1:] == RECORDS[1:]
    assert time.monotonic() - t0 < 20


def test_a_slow_client_is_dropped_without_holding_anything_up(server: Any, clients: Any) -> None:
    # The writer waits for the fast reader to come within LAG records of it, so the fast reader
    # is never more than about half a MiB behind however loaded the machine is (a reader thread
    # left to race 20 MB fell behind its 1 MiB, then 8 MiB, share in full runs). The slow client
    # never reads: it would have to hold 20 MB, and is dropped, while the other goes on.
    srv = server(buffer_limit=4 << 20)
    srv.start(STRUCTURE)
    slow = attached(clients(srv.port, rcvbuf=4096))  # then never reads
    fast = attached(clients(srv.port))
    data = bytearray()
    lines = [0]  # one message per line
    received = threading.Condition()

    def read_all() -> None:
        with contextlib.suppress(OSError):
            while chunk := fast.sock.recv(1 << 20):
                with received:
                    data.extend(chunk)
                    lines[0] += chunk.count(b"\n")
                    received.notify_all()
                if data.endswith(b'"reason":"sigint"}}\n'):
                    return

    def caught_up(n: int) -> bool:
        with received:
            return received.wait_for(lambda: lines[0] >= n, timeout=30)

    reader = threading.Thread(target=read_all)
    reader.start()
    big = {"t": 0, "ev": "log", "state": "Blinking", "msg": "x" * 1000}
    lag = 500  # records, about 0.5 MiB
    for i in range(20_000):  # 20 MB: far more than the socket buffers and a client's share
        if i % lag == 0:
            assert caught_up(i - lag), f"the fast reader stalled at record {i - lag}"
        srv.record(big)
    srv.record(RECORDS[-1])
    reader.join(30)
    assert not reader.is_alive()
    assert data.count(b'"type":"record"') == 20_001
    assert slow.gone()
    assert srv._thread.is_alive()


def test_a_client_killed_mid_stream_changes_nothing(server: Any, clients: Any) -> None:
    srv = server()
    srv.start(STRUCTURE)
    killed, other = attached(clients(srv.port)), attached(clients(srv.port))
    for rec in RECORDS[:5]:
        srv.record(rec)
    killed.until(is_record("fire"))
    # A reset, as when the viewer's process dies: SO_LINGER with a zero timeout.
    killed.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    killed.close()
    for rec in RECORDS[5:]:
        srv.record(rec)
    assert [m["record"] for m in other.until(is_record("stop")) if m["type"] == "record"] == RECORDS
    assert srv._thread.is_alive()


def test_too_many_clients_are_told_busy_and_one_address_cannot_take_every_slot(
        server: Any, clients: Any) -> None:
    srv = server(max_clients=4)
    srv.start(STRUCTURE)
    first, second = clients(srv.port), clients(srv.port)
    for c in (first, second):
        assert c.message() is not None
    # 127.0.0.1 has its half of the slots: a third viewer from it is told why, and closed.
    third = clients(srv.port)
    assert third.message() == {"type": "busy", "reason": "the viewers from 127.0.0.1 hold 2 of "
                               "the 4 slots, the most one address may; close one"}
    assert third.message() is None
    # Another address still finds a slot, until every slot is taken.
    others = [clients(srv.port, source="127.0.0.2") for _ in range(2)]
    for c in others:
        assert c.message() is not None and c.message()["type"] == "snapshot"
    fifth = clients(srv.port, source="127.0.0.3")
    assert fifth.message() == {"type": "busy",
                               "reason": "all 4 viewer slots are taken; try again later"}
    assert fifth.message() is None
    first.close()
    deadline = time.monotonic() + 10
    while len(srv._clients) > 3:  # a send to the closed client fails, freeing its place
        assert time.monotonic() < deadline
        srv.record(RECORDS[0])
        time.sleep(0.05)
    fourth = clients(srv.port)
    assert fourth.message() is not None and fourth.message() is not None


def test_a_viewer_turned_away_says_the_component_is_busy(server: Any, clients: Any) -> None:
    srv = server(max_clients=1)
    srv.start(STRUCTURE)
    assert clients(srv.port).message() is not None
    shown = subprocess.run([sys.executable, "-m", "hfsmc", "view", f"127.0.0.1:{srv.port}"],
                           capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert shown.returncode == 1
    assert shown.stderr.splitlines()[-1] == (
        "hfsmc view: error: the component's monitor is busy: all 1 viewer slots are taken; "
        "try again later")


def test_close_is_quick_even_with_a_stuck_client(server: Any, clients: Any) -> None:
    srv = server(buffer_limit=1 << 24)
    srv.start(STRUCTURE)
    stuck = attached(clients(srv.port, rcvbuf=4096))
    big = {"t": 0, "ev": "log", "state": "", "msg": "y" * 1000}
    for _ in range(3000):
        srv.record(big)
    settle(srv)
    t0 = time.monotonic()
    srv.close()
    assert time.monotonic() - t0 < 1.0
    assert not srv._thread.is_alive()
    assert stuck.gone()


def test_close_without_start_frees_the_port(server: Any) -> None:
    srv = server()
    srv.close()
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", srv.port), timeout=5).close()


def test_malformed_items_do_not_stop_the_server(server: Any, clients: Any) -> None:
    srv = server()
    srv.start(STRUCTURE)
    c = attached(clients(srv.port))
    srv.record({"t": "later", "ev": "enter"})
    srv.sample(1, {"led": object()}, 0)
    srv.record(RECORDS[0])
    got = c.until(is_record("start"))
    assert got[-1]["record"] == RECORDS[0]


# -- the viewer's side ---------------------------------------------------------------------
def items_from(lines: list[bytes], close: bool = True) -> list[tuple[str, Any]]:
    a, b = socket.socketpair()
    with a, b:
        a.sendall(b"".join(lines))
        if close:
            a.shutdown(socket.SHUT_WR)
        return list(hfsmc_monitor.client_items(b, "test:1"))


def line(msg: dict[str, Any]) -> bytes:
    data: bytes = hfsmc_monitor.encode(msg)
    return data


def test_the_client_keeps_what_it_understands() -> None:
    snapshot = hfsmc_view.ViewState(STRUCTURE).snapshot()
    got = items_from([
        b"garbage\n", b"[1, 2]\n",
        line({"type": "hello", "protocol": 1, "structure": STRUCTURE}),
        line(snapshot),
        line({"type": "record", "record": {"t": 0, "ev": "enter"}}),  # not a record: ignored
        line({"type": "record", "record": RECORDS[0]}),
        line({"type": "sample", "t": 5, "variables": {"led": "True"}, "overruns": 1}),
        line({"type": "sample", "t": 6, "variables": {}, "overruns": 1, "sim_rate": 24.8}),
        line({"type": "sample", "t": 7, "variables": {}, "overruns": 1, "sim_rate": "fast"}),
        line({"type": "sample", "t": 8, "variables": {}, "overruns": 1, "sim_rate": -2}),
        line({"type": "news", "text": "later versions may add types"}),
        line({"type": "bye", "reason": "final"}),
        line({"type": "record", "record": RECORDS[1]}),  # after bye: not read
    ])
    assert got == [("structure", STRUCTURE), ("snapshot", snapshot), ("record", RECORDS[0]),
                   ("sample", (5, {"led": "True"}, 1, None)), ("sample", (6, {}, 1, 24.8)),
                   ("sample", (7, {}, 1, None)), ("sample", (8, {}, 1, None)),
                   ("end", "component stopped (final)")]


def test_the_client_refuses_another_protocol() -> None:
    got = items_from([line({"type": "hello", "protocol": 2, "structure": {}})])
    assert got[0][0] == "error" and "protocol 2" in got[0][1]


def test_the_client_says_disconnected() -> None:
    assert items_from([line({"type": "record", "record": RECORDS[0]})])[-1] == (
        "end", "disconnected from test:1")


def test_the_client_skips_overlong_lines(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hfsmc_monitor, "LINE_LIMIT", 100)
    long = line({"type": "record", "record": {**RECORDS[0], "name": "x" * 200}})
    got = items_from([long, line({"type": "record", "record": RECORDS[0]})])
    assert got == [("record", RECORDS[0]), ("end", "disconnected from test:1")]


def test_view_attaches_to_a_monitor(server: Any, capsys: pytest.CaptureFixture[str]) -> None:
    srv = server()
    srv.start(STRUCTURE)
    for rec in RECORDS[:6]:
        srv.record(rec)
    settle(srv)
    status: list[int] = []
    th = threading.Thread(target=lambda: status.append(view(f"127.0.0.1:{srv.port}", None)))
    th.start()
    time.sleep(0.5)
    for rec in RECORDS[6:]:
        srv.record(rec)
    srv.close()
    th.join(10)
    assert status == [0]
    out, err = capsys.readouterr()
    assert out.splitlines() == ["  0.500  in Blinking/Dark", "  3.000  Blinking -> Paused  (pause)",
                                "  3.200  interrupt (sigint) -> Done", "  3.200  stop (sigint)"]
    assert err.splitlines() == [f"hfsmc view: connected to 127.0.0.1:{srv.port}",
                                "hfsmc view: component stopped (sigint)"]


def test_view_attaches_to_a_component_with_regions(server: Any, clients: Any,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The hello names the regions (and validates); a late viewer starts from the innermost
    state of each region, and follows the transitions inside regions."""
    srv = server()
    srv.start(PARALLEL_STRUCTURE)
    for rec in PARALLEL_RECORDS[:7]:  # at 200 ms: Nav in B, Watch in Ok
        srv.record(rec)
    settle(srv)
    raw = clients(srv.port)
    hello, snap = raw.message(), raw.message()
    for m in (hello, snap):
        MONITOR_VALIDATOR.validate(m)
    assert hello is not None and hello["structure"] == PARALLEL_STRUCTURE
    status: list[int] = []
    th = threading.Thread(target=lambda: status.append(view(f"127.0.0.1:{srv.port}", None)))
    th.start()
    time.sleep(0.5)
    for rec in PARALLEL_RECORDS[7:]:
        srv.record(rec)
    srv.close()
    th.join(10)
    assert status == [0]
    assert capsys.readouterr().out.splitlines() == [
        "  0.200  in Mission/Nav/B, Mission/Watch/Ok",
        "  0.900  Mission/Watch/Ok -> Mission/Watch/Seen  (seen)",
        "  1.000  Mission -> Done  (all done)",
        "  1.000  stop (final)"]


def test_view_reports_a_refused_connection(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.create_server(("127.0.0.1", 0)) as s:
        port = s.getsockname()[1]
    assert view(str(port), None) == 1
    err = capsys.readouterr().err
    assert err == f"hfsmc: error: cannot connect to 127.0.0.1:{port}: Connection refused\n"


# -- a real component ------------------------------------------------------------------------
class Component:
    """The blinker running with --monitor 0; its port read from its stderr."""

    def __init__(self, main: Path, tmp: Path, *args: str) -> None:
        self.err_path = tmp / "component.err"
        with open(self.err_path, "w") as err:
            self.proc = subprocess.Popen([sys.executable, str(main), "--monitor", "0", *args],
                                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                         stderr=err, cwd=tmp)
        deadline = time.monotonic() + 10
        while not (m := re.search(r"monitor: listening on 127\.0\.0\.1:(\d+)", self.err())):
            assert time.monotonic() < deadline and self.proc.poll() is None, self.err()
            time.sleep(0.02)
        self.port = int(m.group(1))
        self.started = time.monotonic()

    def err(self) -> str:
        return self.err_path.read_text()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(10)


@pytest.fixture
def component(blinker: Path, tmp_path: Path) -> Iterator[Callable[..., Component]]:
    made: list[Component] = []

    def start(*args: str) -> Component:
        made.append(Component(blinker, tmp_path, *args))
        return made[-1]

    yield start
    for c in made:
        c.kill()


def hfsmc_view_process(port: int) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "hfsmc", "view", f"127.0.0.1:{port}"],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT)


def test_late_viewers_of_a_real_component(component: Callable[..., Component],
                                          clients: Callable[..., Client]) -> None:
    comp = component("--clock", "real", "--until", "4s")
    raw = clients(comp.port)
    hello = raw.message()
    result = compile_file("examples/blinker/blinker.yaml")
    assert hello is not None and result.model is not None
    assert hello["structure"] == structure_of(result.model)
    time.sleep(max(1.2 - (time.monotonic() - comp.started), 0))
    garbage = clients(comp.port)
    garbage.sock.sendall(os.urandom(10_000) + b"\n{}\n" * 100)
    first, doomed = hfsmc_view_process(comp.port), hfsmc_view_process(comp.port)
    try:
        assert first.stdout is not None and doomed.stdout is not None
        t0 = time.monotonic()
        attach = first.stdout.readline()
        assert re.fullmatch(r" +(\d+\.\d{3})  in Blinking/(Lit|Dark)\n", attach), attach
        assert float(attach.split()[0]) >= 1.0, "the current state, not the start"
        assert time.monotonic() - t0 < 5
        assert re.fullmatch(r" +\d+\.\d{3}  in Blinking/(Lit|Dark)\n", doomed.stdout.readline())
        doomed.kill()  # a viewer killed mid-stream
        out, err = first.communicate(timeout=20)
        assert first.returncode == 0, err
    finally:
        for p in (first, doomed):
            if p.poll() is None:
                p.kill()
            p.communicate(timeout=10)
    assert "  3.000  Blinking -> Paused  (pause)" in out
    assert out.splitlines()[-1] == "  4.000  stop (until)"
    assert err.splitlines()[-1] == "hfsmc view: component stopped (until)"
    msgs = raw.until(lambda m: m["type"] == "bye")  # validated against the schema on the way
    assert msgs[-1] == {"type": "bye", "reason": "until"}
    assert comp.proc.wait(10) == 0
    assert "Traceback" not in comp.err()


LAST_INSTANT = """\
hfsm: 1
name: last
variables: {legs: 0}
initial: A
states:
  A: {transitions: [{to: Done, after: 2s, do: "legs += 2"}]}
  Done: {final: true}
"""


def test_the_last_sample_has_the_values_the_run_ended_with(tmp_path: Path,
                                                           clients: Callable[..., Client]) -> None:
    """A variable changed by the very transition that stops the run reaches the viewers
    (samples are taken every 100 ms; the stop takes one more)."""
    (tmp_path / "last.yaml").write_text(LAST_INSTANT, "utf-8")
    subprocess.run([sys.executable, "-m", "hfsmc", "build", str(tmp_path / "last.yaml"), "-o",
                    str(tmp_path / "last")], check=True, capture_output=True, timeout=60)
    comp = Component(tmp_path / "last" / "last.py", tmp_path, "--clock", "real")
    try:
        raw = clients(comp.port)
        msgs = raw.until(lambda m: m["type"] == "bye")
        assert comp.proc.wait(10) == 0, comp.err()
    finally:
        comp.kill()
    samples = [m["variables"] for m in msgs if m["type"] == "sample"]
    assert samples[0] == {"legs": "0"} and samples[-1] == {"legs": "2"}, samples


def test_viewer_in_a_terminal_attaches_late(component: Callable[..., Component],
                                            tmux: Callable[..., Tmux], tmp_path: Path) -> None:
    comp = component("--clock", "real", "--until", "5s")
    time.sleep(max(1.0 - (time.monotonic() - comp.started), 0))
    t = tmux(py("-m", "hfsmc", "view", f"127.0.0.1:{comp.port}"), ROOT)
    text = t.wait(lambda s: bool(re.search(GREEN + "● (Lit|Dark)", s)), timeout=5, colors=True)
    assert re.search(GREEN + "● Blinking", text)
    screen = t.screen()
    assert re.search(r"time\s+[1-4]\.\d{3} s", screen), screen
    assert "○ Done" in screen and "Blinking/" in screen  # tree and recent transitions
    text = t.wait(lambda s: "EXIT=" in s)
    assert "stopped (until)" in text and "EXIT=0" in text
    assert "hfsmc view: component stopped (until)" in text
    assert comp.proc.wait(10) == 0


def test_viewer_says_disconnected_when_the_component_dies(component: Callable[..., Component]) -> None:
    comp = component("--clock", "real", "--until", "30s")
    viewer = hfsmc_view_process(comp.port)
    try:
        assert viewer.stdout is not None
        assert " in Blinking/" in viewer.stdout.readline()
        comp.proc.send_signal(signal.SIGKILL)
        _, err = viewer.communicate(timeout=10)
    finally:
        if viewer.poll() is None:
            viewer.kill()
            viewer.communicate(timeout=10)
    assert viewer.returncode == 0
    assert err.splitlines()[-1] == f"hfsmc view: disconnected from 127.0.0.1:{comp.port}"


class ChangingCamera:
    """A camera whose snippets read a new picture every time the monitor looks."""

    def __init__(self) -> None:
        self.looks = 0

    def _last_seen(self) -> Any:
        import numpy as np

        self.looks += 1
        return np.full((48, 64, 3), self.looks % 256, np.uint8)


def test_subscribing_again_and_again_encodes_no_more_frames(server: Any) -> None:
    """A client that sends `subscribe` thousands of times a second is given the frame already
    made: the component encodes at most 4 frames a second (every client gets each one)."""
    srv = server()
    srv.watch({"camera": ChangingCamera()})
    srv.start(STRUCTURE)
    quiet = socket.create_connection(("127.0.0.1", srv.port), timeout=5)
    flood = socket.create_connection(("127.0.0.1", srv.port), timeout=5)
    try:
        quiet.sendall(b'{"type":"subscribe","frames":true}\n')
        flood.setblocking(False)
        start = time.monotonic()
        lines = 0
        while lines < 6000:
            flood.sendall(b'{"type":"subscribe","frames":true}\n{"type":"subscribe","frames":false}\n'
                          * 50 + b'{"type":"subscribe","frames":true}\n')
            lines += 101
            time.sleep(0.03)
            with contextlib.suppress(BlockingIOError):
                flood.recv(1 << 20)  # what it is sent, unread
        seen = read_messages(quiet, 0.3)
        seconds = time.monotonic() - start
        made = [m["jpeg"] for m in seen if m["type"] == "frame"]
        assert 2 <= len(made) <= 4 * seconds + 2, (len(made), seconds)
    finally:
        quiet.close()
        flood.close()
