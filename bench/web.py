#!/usr/bin/env python3
"""Speed of the web view (``hfsmc view --web``): docs/web.md, figures in bench/README.md.

Four parts, each with the issue's targets:

* **Latency** from a transition in a component to the colour change in the
  browser, at 50 transitions a second: the component's own monitor server
  (``hfsmc_monitor.MonitorServer``, in this process) is given each
  transition's ``fire``, ``exit`` and ``enter`` records, the wall time noted
  at the ``enter``; ``hfsmc view --web`` runs as a child process, and headless
  Chromium (selenium) opens its page with a ``MutationObserver`` that notes the
  wall time at which the entered state's SVG element gets its green class.
  p50 and p99 (target p99 <= 100 ms), on a two-state model and on a
  generated 500-state one.
* **Page update cost** for those models: Chromium's own counters
  (``Performance.getMetrics``: script, style, layout and task time of the
  page) over the run, divided by the number of transitions.
* **CPU of a component** with a web viewer attached against none: a generated
  component toggling between two states every 20 ms (50 transitions a second),
  run as ``NAME.py --clock real --monitor PORT`` in a child process, user +
  system time from ``wait4``; alone, then with ``hfsmc view --web`` and a
  browser page watching it (target <= 2 % of a core more).
* **CPU with a vehicle and a camera** (``--only feeds``): the same toggler
  with a ``mavlink`` and a ``camera`` interface, each tick reading the
  camera's frame, against ``hfsmc sim`` on free ports; with its monitor and
  no viewer, then with the web view's page open, which gets the vehicle
  records (4 a second) and subscribes to the frames (JPEG-encoded by the
  component, at most 4 a second).

Usage::

    python bench/web.py                       # about 3 minutes
    python bench/web.py --quick               # about 1 minute
    python bench/web.py --json bench/results.json
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from report import hfsmc_revision, loadavg, machine, merge_json, table  # bench/report.py

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tests.support import interrupt, many_states  # many_states: tests/test_web.py opens it too

KEY = "web"
ROOT = Path(__file__).resolve().parent.parent
WORK = ROOT / "bench" / "_work" / "web"
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
monitor = importlib.import_module("hfsmc.templates.python.hfsmc_monitor")

TOGGLER = """\
hfsm: 1
name: toggler
language: python
description: Two states, 50 transitions a second, for the web view's CPU figure.
period: 10ms
initial: A
states:
  A:
    transitions:
      - {to: B, after: 20ms}
  B:
    transitions:
      - {to: A, after: 20ms}
"""

# The same toggler with a vehicle and a camera: each tick reads the camera's frame, so the
# monitor has a frame to send (minor version 1) and vehicle records from the simulator.
FEEDER = """\
hfsm: 1
name: feeder
language: python
description: The toggler with a mavlink and a camera interface, for the CPU of the feeds.
interfaces:
  drone: {type: mavlink, url: "udpin:127.0.0.1:14550"}
  camera: {type: camera, url: "http://127.0.0.1:8554/bottom.mjpg"}
variables:
  frames: 0
period: 10ms
initial: A
states:
  A:
    during: |
      if camera.frame() is not None:
          frames += 1
    transitions:
      - {to: B, after: 20ms}
  B:
    during: |
      if camera.frame() is not None:
          frames += 1
    transitions:
      - {to: A, after: 20ms}
"""

# Notes the wall time (ms since the epoch) at which a state's element turns green.
OBSERVE_JS = """
window.__seen = [];
const svg = document.querySelector('#hv-diagram svg');
new MutationObserver((changes) => {
  const t = performance.timeOrigin + performance.now();
  for (const m of changes) {
    const g = m.target;
    if (g.classList.contains('hv-active') && !(m.oldValue || '').includes('hv-active')) {
      window.__seen.push([g.id, t]);
    }
  }
}).observe(svg, {subtree: true, attributes: true, attributeFilter: ['class'], attributeOldValue: true});
return svg.querySelectorAll('g.node').length;
"""


# -- models -------------------------------------------------------------------------------------
def two_states() -> dict[str, Any]:
    return {"name": "two", "automata": [{"owner": "", "period_ms": 10, "initial": "A",
                                         "history": False}],
            "states": [{"path": p, "final": False, "composite": False} for p in ("A", "B")],
            "transitions": [{"from": "A", "to": "B", "index": 0, "name": None},
                            {"from": "B", "to": "A", "index": 0, "name": None}],
            "variables": [], "parameters": {}}


def leaf_cycle(structure: dict[str, Any]) -> list[str]:
    """The leaves a run goes through, in order (then again)."""
    return [s["path"] for s in structure["states"] if not s["composite"]]


# -- processes and the browser ------------------------------------------------------------------
def free_port() -> int:
    with socket.create_server(("127.0.0.1", 0)) as s:
        port: int = s.getsockname()[1]
        return port


@contextlib.contextmanager
def web_view(port: int, tmp: Path) -> Iterator[str]:
    """``hfsmc view --web`` of the component at ``port``; its URL."""
    out = tmp / f"web{port}.out"
    with open(out, "w") as o, open(tmp / f"web{port}.err", "w") as e:
        proc = subprocess.Popen([sys.executable, "-m", "hfsmc", "view", "--web", "0",
                                 f"127.0.0.1:{port}"], stdout=o, stderr=e,
                                stdin=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 30
        while not (m := re.search(r"web view on (\S+) ", out.read_text())):
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError(f"hfsmc view --web did not start: {(tmp / f'web{port}.err').read_text()}")
            time.sleep(0.05)
        yield m.group(1)
    finally:
        interrupt(proc, signum=signal.SIGTERM)


@contextlib.contextmanager
def browser(tmp: Path) -> Iterator[Any]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    os.environ["SE_OFFLINE"] = "true"  # never let Selenium Manager fetch a driver
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--window-size=1280,800", f"--user-data-dir={tmp / 'profile'}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        driver.set_page_load_timeout(30)
        driver.set_script_timeout(30)
        yield driver
    finally:
        with contextlib.suppress(Exception):
            driver.quit()


def open_page(driver: Any, url: str, nodes: int, timeout: float = 60) -> None:
    """Open the page and wait until its picture has ``nodes`` states and is connected."""
    driver.get(url)
    deadline = time.monotonic() + timeout
    while True:
        n = driver.execute_script(
            "const s = document.querySelector('#hv-diagram svg');"
            "return document.body.dataset.status === 'connected' && s ?"
            " s.querySelectorAll('g.node').length : -1")
        if n >= nodes:
            return
        if time.monotonic() > deadline:
            raise RuntimeError(f"the page did not show {nodes} states (it shows {n})")
        time.sleep(0.1)


def page_metrics(driver: Any) -> dict[str, float]:
    got = driver.execute_cdp_cmd("Performance.getMetrics", {})
    return {m["name"]: float(m["value"]) for m in got["metrics"]}


# -- latency and page cost ------------------------------------------------------------------------
def latency(name: str, structure: dict[str, Any], rate: float, count: int, tmp: Path) -> dict[str, Any]:
    """Transitions at ``rate`` per second through a monitor server to a page."""
    srv = monitor.MonitorServer(port=0, announce=open(os.devnull, "w"))  # noqa: SIM115
    srv.start(structure)
    leaves = leaf_cycle(structure)
    t0 = time.monotonic()

    def ms() -> int:
        return int((time.monotonic() - t0) * 1000)

    srv.record({"t": 0, "ev": "start", "name": structure["name"]})
    for p in _ancestors(leaves[0]):
        srv.record({"t": 0, "ev": "enter", "state": p})
    sent: list[tuple[str, float]] = []
    try:
        with web_view(srv.port, tmp) as url, browser(tmp) as driver:
            nodes = len(structure["states"]) - sum(1 for s in structure["states"] if s["composite"])
            t_open = time.monotonic()
            open_page(driver, url, nodes)
            opened_s = time.monotonic() - t_open
            driver.execute_script("document.getElementById('hv-autofocus').checked = true;")
            driver.execute_script(OBSERVE_JS)
            driver.execute_cdp_cmd("Performance.enable", {})
            before = page_metrics(driver)

            def emit() -> None:
                here = leaves[0]
                start = last = time.monotonic()
                for i in range(1, count + 1):
                    # On time, but never two closer than half a period after a late one:
                    # the bridge would rightly draw a state that short as not entered.
                    due = max(start + i / rate, last + 0.5 / rate)
                    while (now := time.monotonic()) < due:
                        time.sleep(min(due - now, 0.005))
                    last = time.monotonic()
                    there = leaves[i % len(leaves)]
                    t = ms()
                    srv.record({"t": t, "ev": "fire", "from": _source(here, there), "to": _target(here, there), "index": 0})
                    for p in reversed(_ancestors(here)):
                        if p not in _ancestors(there):
                            srv.record({"t": t, "ev": "exit", "state": p})
                    entered = [p for p in _ancestors(there) if p not in _ancestors(here)]
                    wall = time.time() * 1000
                    for p in entered:
                        srv.record({"t": t, "ev": "enter", "state": p})
                    sent.append((there, wall))
                    here = there

            emitter = threading.Thread(target=emit)
            emitter.start()
            emitter.join()
            time.sleep(1.0)  # the last ones reach the page
            after = page_metrics(driver)
            seen: list[list[Any]] = driver.execute_script("return window.__seen")
    finally:
        srv.close()
    delays, missed = _pair(sent, seen)
    cost = {k: (after.get(k, 0) - before.get(k, 0)) * 1000 / count
            for k in ("ScriptDuration", "RecalcStyleDuration", "LayoutDuration", "TaskDuration")}
    return {"model": name, "states": len(structure["states"]), "rate_per_s": rate,
            "transitions": count, "drawn": len(delays), "missed": missed,
            "p50_ms": round(_pct(delays, 50), 1), "p99_ms": round(_pct(delays, 99), 1),
            "max_ms": round(max(delays), 1) if delays else None,
            "page_ms_per_update": {k: round(v, 3) for k, v in cost.items()},
            "page_open_s": round(opened_s, 2)}


def _ancestors(path: str) -> list[str]:
    parts = path.split("/")
    return ["/".join(parts[:i]) for i in range(1, len(parts) + 1)]


def _source(here: str, there: str) -> str:
    a, b = _ancestors(here), _ancestors(there)
    return next(x for x, y in zip(a, b + [""] * len(a), strict=False) if x != y)


def _target(here: str, there: str) -> str:
    a, b = _ancestors(here), _ancestors(there)
    return next(y for x, y in zip(a + [""] * len(b), b, strict=False) if x != y)


def _pair(sent: list[tuple[str, float]], seen: list[list[Any]]) -> tuple[list[float], int]:
    """Each transition's delay: the first time its state turned green after it was sent
    (and before it was sent again)."""
    by_state: dict[str, list[float]] = {}
    for sid, t in seen:
        by_state.setdefault(sid, []).append(float(t))
    delays: list[float] = []
    missed = 0
    next_send: dict[int, float] = {}
    last: dict[str, int] = {}
    for i, (state, _) in enumerate(sent):
        if state in last:
            next_send[last[state]] = sent[i][1]
        last[state] = i
    for i, (state, wall) in enumerate(sent):
        until = next_send.get(i, float("inf"))
        hit = next((t for t in by_state.get(state, ()) if wall - 1 <= t < until), None)
        if hit is None:
            missed += 1
        else:
            delays.append(max(hit - wall, 0.0))
    return delays, missed


def _pct(values: list[float], p: float) -> float:
    if not values:
        return float("nan")
    s = sorted(values)
    return s[min(len(s) - 1, int(len(s) * p / 100))]


# -- CPU of the component -----------------------------------------------------------------------
def build_toggler(tmp: Path) -> Path:
    model = tmp / "toggler.yaml"
    model.write_text(TOGGLER)
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(model), "-o",
                    str(tmp / "toggler")], check=True, capture_output=True, timeout=120)
    return tmp / "toggler" / "toggler.py"


def component_cpu(main: Path, seconds: float, port: int, *extra: str) -> float:
    """CPU seconds (user + system) of the component over its run."""
    proc = subprocess.Popen([sys.executable, str(main), "--clock", "real", "--monitor", str(port),
                             "--until", f"{seconds}s", *extra], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"the toggler exited with {proc.returncode}")
    return float(usage.ru_utime + usage.ru_stime)


def cpu(seconds: float, repeat: int, tmp: Path) -> dict[str, Any]:
    main = build_toggler(tmp)
    alone: list[float] = []
    watched: list[float] = []
    for _ in range(repeat):
        alone.append(component_cpu(main, seconds, free_port()))
        port = free_port()
        with web_view(port, tmp) as url, browser(tmp) as driver:
            result: dict[str, float] = {}

            def run(result: dict[str, float] = result, port: int = port) -> None:
                result["cpu"] = component_cpu(main, seconds, port)

            runner = threading.Thread(target=run)
            runner.start()
            with contextlib.suppress(RuntimeError):
                open_page(driver, url, 2, timeout=min(30, seconds))
            runner.join()
            watched.append(result["cpu"])
    a, w = statistics.median(alone), statistics.median(watched)
    return {"seconds": seconds, "runs": repeat, "alone_cpu_s": [round(x, 3) for x in alone],
            "web_cpu_s": [round(x, 3) for x in watched],
            "alone_pct": round(100 * a / seconds, 2), "web_pct": round(100 * w / seconds, 2),
            "more_pct_of_a_core": round(100 * (w - a) / seconds, 2)}


def feeds_cpu(seconds: float, repeat: int, tmp: Path) -> dict[str, Any]:
    """The CPU of a component with a vehicle and a camera (``hfsmc sim`` on free ports):
    with its monitor and no viewer, then with the web view's page open, which gets the
    vehicle records and asks for the camera's frames."""
    model = tmp / "feeder.yaml"
    model.write_text(FEEDER)
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(model), "-o",
                    str(tmp / "feeder")], check=True, capture_output=True, timeout=120)
    main = tmp / "feeder" / "feeder.py"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        udp = s.getsockname()[1]
    http = free_port()
    config = tmp / "feeder-config.yaml"
    config.write_text(json.dumps({"interfaces": {
        "drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
        "camera": {"type": "camera", "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}))
    with open(tmp / "sim.log", "w") as log:
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--mavlink",
                                f"udpout:127.0.0.1:{udp}", "--camera-port", str(http),
                                "--world", str(ROOT / "examples" / "follow_colors" / "world.yaml")],
                               stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    alone: list[float] = []
    watched: list[float] = []
    frames = 0
    try:
        time.sleep(2.0)  # the simulator's camera serving
        for _ in range(repeat):
            alone.append(component_cpu(main, seconds, free_port(), "--config", str(config)))
            port = free_port()
            with web_view(port, tmp) as url, browser(tmp) as driver:
                result: dict[str, float] = {}

                def run(result: dict[str, float] = result, port: int = port) -> None:
                    result["cpu"] = component_cpu(main, seconds, port, "--config", str(config))

                runner = threading.Thread(target=run)
                runner.start()
                with contextlib.suppress(RuntimeError):
                    open_page(driver, url, 2, timeout=min(30, seconds))
                driver.execute_script(
                    "window.__frames = 0; const img = document.querySelector('#hv-cameras img');"
                    "if (img) new MutationObserver(() => { window.__frames += 1; })"
                    ".observe(img, {attributes: true, attributeFilter: ['src']});")
                runner.join()
                frames += int(driver.execute_script("return window.__frames || 0"))
                watched.append(result["cpu"])
    finally:
        interrupt(sim, signum=signal.SIGTERM)
    a, w = statistics.median(alone), statistics.median(watched)
    return {"seconds": seconds, "runs": repeat, "alone_cpu_s": [round(x, 3) for x in alone],
            "web_cpu_s": [round(x, 3) for x in watched],
            "alone_pct": round(100 * a / seconds, 2), "web_pct": round(100 * w / seconds, 2),
            "more_pct_of_a_core": round(100 * (w - a) / seconds, 2),
            "frames_shown_per_s": round(frames / (seconds * repeat), 2)}


# -- main ---------------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--only", choices=("latency", "cpu", "feeds"), help="one part only")
    ap.add_argument("--json", type=Path, help=f'merge the figures into this file under "{KEY}"')
    ns = ap.parse_args(argv)
    if not (os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER)):
        print("bench/web.py: chromium and chromium-driver are not installed (`make deps`)",
              file=sys.stderr)
        return 1
    count = 250 if ns.quick else 1000
    seconds, repeat = (10.0, 1) if ns.quick else (20.0, 2)
    WORK.mkdir(parents=True, exist_ok=True)
    result: dict[str, Any] = {"machine": machine(), "hfsmc": hfsmc_revision(),
                              "load_before": loadavg()}
    with tempfile.TemporaryDirectory(dir=WORK) as d:
        tmp = Path(d)
        if ns.only in (None, "latency"):
            result["latency"] = [latency("two states", two_states(), 50, count, tmp),
                                 latency("500 states", many_states(), 50, count, tmp)]
        if ns.only in (None, "cpu"):
            result["cpu"] = cpu(seconds, repeat, tmp)
        if ns.only in (None, "feeds"):
            result["feeds_cpu"] = feeds_cpu(seconds, repeat, tmp)
    result["load_after"] = loadavg()
    result.setdefault("latency", [])
    rows = [[r["model"], str(r["transitions"]), str(r["missed"]), f"{r['p50_ms']}",
             f"{r['p99_ms']}", f"{r['max_ms']}",
             f"{r['page_ms_per_update']['ScriptDuration']:.2f}",
             f"{r['page_ms_per_update']['RecalcStyleDuration']:.2f}",
             f"{r['page_ms_per_update']['LayoutDuration']:.2f}",
             f"{r['page_ms_per_update']['TaskDuration']:.2f}", f"{r['page_open_s']}"]
            for r in result["latency"]]
    print("latency at 50 transitions/s (target p99 <= 100 ms); page cost per update")
    for line in table(rows, ["model", "transitions", "missed", "p50 ms", "p99 ms", "max ms",
                             "script ms", "style ms", "layout ms", "task ms", "open s"]):
        print(line)
    c = result.get("cpu")
    if c is not None:
        print(f"component CPU: alone {c['alone_pct']} %, with the web view {c['web_pct']} % of a "
              f"core: {c['more_pct_of_a_core']} % more (target <= 2 %)")
    f = result.get("feeds_cpu")
    if f is not None:
        print(f"component with a vehicle and a camera: alone {f['alone_pct']} %, with the web view "
              f"(vehicle records, frames) {f['web_pct']} % of a core: {f['more_pct_of_a_core']} % "
              f"more; {f['frames_shown_per_s']} frames shown a second")
    print(f"load {result['load_before']} -> {result['load_after']}")
    ok = all(r["p99_ms"] <= 100 for r in result["latency"]) and (
        c is None or c["more_pct_of_a_core"] <= 2) and (f is None or f["more_pct_of_a_core"] <= 2)
    result["targets_met"] = ok
    if ns.json:
        merge_json(ns.json, KEY, result)
        print(f"wrote {ns.json} (key {KEY!r})")
    print(json.dumps({"targets_met": ok}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
