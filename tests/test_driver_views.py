"""A user driver in the live views (docs/drivers.md "In the live views", schemas/monitor.md
minor version 4): the monitor's driver messages, the terminal view's table and the web
view's, against examples/udp_gadget running with its device simulator on loopback."""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hfsmc.templates.python.hfsmc_driverview import (  # type: ignore[import-not-found]
    cleaned,
    driver_rows,
    shown,
)

from tests.support import ROOT, WEB_URL, Client, Process, Tmux, free_port, needs_browser, screenshot

GADGET = ROOT / "examples/udp_gadget"


# -- pure parts ------------------------------------------------------------------------------
def test_values_are_sent_as_numbers_booleans_or_short_text() -> None:
    assert [shown(v) for v in (1.23456789, float("inf"), float("-inf"), float("nan"), 7, True,
                               None, "ok", (0.5, 1.0))] == \
        [1.23457, "inf", "-inf", "nan", 7, True, None, "ok", "[0.5, 1.0]"]
    assert shown("x" * 200) == "x" * 79 + "…" and shown(1 << 60) == str(1 << 60)
    msg = {"type": "driver", "t": 50, "name": "gadget", "kind": "gadget", "live": False,
           "fields": [{"name": "distance", "value": 0.3}, {"name": "led", "value": True},
                      {"name": "age", "value": "inf"}, {"name": "note", "value": None}]}
    assert driver_rows(msg) == [("gadget gadget (playback)", ""), ("distance", "0.3"),
                                ("led", "true"), ("age", "inf"), ("note", "–")]
    # What the web view passes on is rebuilt: text cut, odd values dropped, junk refused.
    odd = {**msg, "t": True, "extra": 1, "fields": [{"name": "a" * 100, "value": {"x": 1}}]}
    assert cleaned(odd) == {"type": "driver", "t": 0, "name": "gadget", "kind": "gadget",
                            "live": False, "fields": [{"name": "a" * 79 + "…",
                                                      "value": "{'x': 1}"}]}
    assert cleaned({**msg, "fields": "no"}) is None and cleaned({**msg, "name": 3}) is None


# -- a running gadget ------------------------------------------------------------------------
class Run:
    """gadget_sim.py and udp_gadget (Python) or udp_gadget_cpp with --monitor, on loopback."""

    def __init__(self, tmp: Path, language: str) -> None:
        self.tmp = tmp
        self.procs: list[subprocess.Popen[bytes]] = []
        self.model = GADGET / ("udp_gadget.yaml" if language == "python" else "udp_gadget_cpp.yaml")
        build = ["-t", "cpp", "--compile"] if language == "cpp" else []
        out = subprocess.run([sys.executable, "-m", "hfsmc", "build", *build, str(self.model),
                              "-o", str(tmp / "g")],
                             capture_output=True, text=True, timeout=280, cwd=ROOT)
        assert out.returncode == 0, out.stderr
        component = [sys.executable, str(tmp / "g/udp_gadget.py")] if language == "python" \
            else [str(tmp / "g/build/udp_gadget_cpp")]
        udp = free_port(socket.SOCK_DGRAM)
        self.start("sim", [sys.executable, str(GADGET / "gadget_sim.py"), "--port", str(udp),
                           "--period", "2", "--for", "300"])
        (tmp / "wire.yaml").write_text(json.dumps(
            {"interfaces": {"gadget": {"url": f"udp:127.0.0.1:{udp}"}}}))
        self.start("component", [*component, "--config",
                                 str(tmp / "wire.yaml"), "--monitor", "0", "--until", "300s"])
        deadline = time.monotonic() + 20
        while not (m := re.search(r"monitor: listening on 127\.0\.0\.1:(\d+)",
                                  (tmp / "component.err").read_text())):
            assert time.monotonic() < deadline, (tmp / "component.err").read_text()
            time.sleep(0.05)
        self.port = int(m.group(1))

    def start(self, name: str, args: list[str]) -> None:
        with open(self.tmp / f"{name}.err", "w") as err:
            self.procs.append(subprocess.Popen(args, stdin=subprocess.DEVNULL,
                                               stdout=subprocess.DEVNULL, stderr=err, cwd=self.tmp))

    def stop(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)


@pytest.fixture(scope="module", params=["python", "cpp"])
def run(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Run]:
    if request.param == "cpp":
        from tests.cppbuild import CppBuildError, need_toolchain

        try:
            need_toolchain()
        except CppBuildError as e:
            pytest.fail(str(e))
    r = Run(tmp_path_factory.mktemp("driverviews"), request.param)
    try:
        yield r
    finally:
        r.stop()


def test_the_monitor_sends_the_drivers_snapshot_to_every_viewer(run: Run) -> None:
    c = Client(run.port)  # every message checked against schemas/monitor.schema.json
    try:
        hello = c.message()
        assert hello is not None and hello["minor"] == 4
        assert hello["feeds"] == {"vehicle": [], "camera": [], "ros2": [], "driver": ["gadget"]}
        deadline = time.monotonic() + 30
        while True:
            msg = c.message()
            assert msg is not None and time.monotonic() < deadline, msg
            if msg["type"] == "driver" and msg["fields"][2]["value"] > 5:
                break
        assert (msg["name"], msg["kind"], msg["live"]) == ("gadget", "gadget", True)
        fields = {f["name"]: f["value"] for f in msg["fields"]}
        assert list(fields) == ["distance", "age", "count", "led"]  # the declaration's order
        # The simulator's obstacle sweeps between 0.2 and 2 m; readings 20 a second.
        assert 0.0 < fields["distance"] < 3.0 and 0 <= fields["age"] < 1.0, fields
        assert isinstance(fields["led"], bool)
    finally:
        c.close()


def test_the_terminal_view_shows_the_drivers_table(run: Run, tmux: Callable[..., Tmux],
                                                    tmp_path: Path) -> None:
    t = tmux(f"{sys.executable} -m hfsmc view {run.port}", ROOT)
    rows = (r"│ gadget gadget\s+│", r"distance\s+\d+\.\d+", r"age\s+\d", r"count\s+\d+",
            r"led\s+(true|false)")
    screen = t.wait(lambda s: all(re.search(r, s) for r in rows), timeout=30)
    assert re.search(r"● (Clear|Near)", screen), screen
    (tmp_path / f"view-{run.model.stem}.txt").write_text(screen)


DRIVER_JS = """
const box = document.getElementById('hv-drivers');
return {
  status: document.body.dataset.status,
  shown: !box.hidden,
  caption: (box.querySelector('caption') || {}).textContent,
  rows: [...box.querySelectorAll('tr')].map((t) => [t.dataset.key, t.querySelector('td').textContent]),
};
"""


@needs_browser
def test_the_web_view_shows_the_drivers_table(run: Run, browsers: Callable[..., Any],
                                               tmp_path: Path) -> None:
    web = Process([sys.executable, "-m", "hfsmc", "view", "--web", "0", f"127.0.0.1:{run.port}",
                   "--model", str(run.model)], tmp_path, "web")
    try:
        url = web.wait_for(WEB_URL, where="out").group(1)
        driver = browsers()
        driver.set_window_size(1280, 800)
        driver.get(url)
        deadline = time.monotonic() + 30
        while True:
            s = driver.execute_script(DRIVER_JS)
            if s["shown"] and len(s["rows"]) == 4 and s["rows"][2][1] not in ("", "0"):
                break
            assert time.monotonic() < deadline, (s, web.err_path.read_text())
            time.sleep(0.2)
        assert s["status"] == "connected" and s["caption"] == "gadget gadget", s
        rows = dict(s["rows"])
        assert list(rows) == ["distance", "age", "count", "led"], s
        assert 0.0 < float(rows["distance"]) < 3.0 and rows["led"] in ("true", "false"), s
        screenshot(driver, f"web-{run.model.stem}", tmp_path)
    finally:
        web.kill(signal.SIGINT)
