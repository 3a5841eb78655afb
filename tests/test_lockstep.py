"""Lockstep: `hfsmc sim --lockstep PORT` is the clock of a component run with `--clock sim:PORT`
(docs/worlds.md#simulated-time, schemas/lockstep.md). Real processes on loopback; no test
asserts how long anything took."""

from __future__ import annotations

import json
import multiprocessing
import os
import re
import shlex
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests import test_missions
from tests.conftest import ROOT
from tests.cppbuild import need_toolchain
from tests.support import FOLLOW, HFSMC, Client, Tmux, flight, free_port, wait_for_line
from tests.test_missions import CPP_BUILD_TIMEOUT

SHORT = "40s"  # a take-off and the start of the first stage


def _burn(stop: object, nice: int) -> None:
    os.nice(nice)
    while not stop.is_set():  # type: ignore[attr-defined]
        sum(i * i for i in range(10_000))


@contextmanager
def cpu_burners(n: int = 2) -> Iterator[None]:
    """Every core busy (a parallel build's load) while the block runs."""
    ctx = multiprocessing.get_context("spawn")
    stop = ctx.Event()
    # Alone, the burners are the load. Under `make test` the other workers' tests already
    # load every core: the burners then only take what they leave (the lowest priority)
    # instead of two cores from the rest of the suite.
    nice = 19 if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")) > 1 else 0
    procs = [ctx.Process(target=_burn, args=(stop, nice), daemon=True) for _ in range(n)]
    for p in procs:
        p.start()
    try:
        yield
    finally:
        stop.set()
        for p in procs:
            p.join(5)
            if p.is_alive():
                p.kill()


def fly(tmp: Path, *, command: list[str] | None = None, until: str = "240s",
        sim_args: tuple[str, ...] = ()) -> tuple[int, Path]:
    """A whole lockstep flight: the component's exit status and the flight's folder."""
    with flight(tmp, *sim_args, command=command, lockstep=True,
                component_args=("--until", until, "--trace-variables")) as f:
        status = f.component.wait(timeout=240)
        f.sim.wait(timeout=30)  # it stops when the component has gone
        assert f.sim.returncode == 0, (f.folder / "sim.log").read_text()[-2000:]
        return status, f.folder


START_UP = ("stream not available", "stream back", "waiting for the simulator")


def outputs(folder: Path) -> dict[str, str]:
    """What must be the same every run: the trace, the truth, and the component's lines (the
    commands' outcomes, the stages), with the run's folder and ports taken out; the lines
    said before the simulator's time starts (the camera's stream not up yet) left out."""
    def clean(text: str) -> str:
        return re.sub(r"127\.0\.0\.1:\d+", "127.0.0.1:PORT", text.replace(str(folder), "DIR"))
    log = "".join(line for line in (folder / "component.log").read_text().splitlines(True)
                  if not any(s in line for s in START_UP))
    return {"trace": clean((folder / "trace.jsonl").read_text()),
            "truth": (folder / "truth.json").read_text(), "log": clean(log)}


@pytest.mark.slow
def test_ten_lockstep_runs_on_a_loaded_machine_are_byte_identical(tmp_path: Path) -> None:
    runs = []
    with cpu_burners():
        for i in range(10):
            status, folder = fly(tmp_path / str(i), until=SHORT)
            assert status == 0, (folder / "component.log").read_text()[-2000:]
            runs.append(outputs(folder))
    trace = [json.loads(line) for line in runs[0]["trace"].splitlines()]
    entered = [r["state"] for r in trace if r["ev"] == "enter"]
    assert "Mission/FollowGreen/Track" in entered, entered  # it flew and saw green
    assert trace[-1]["ev"] == "stop" and trace[-1]["t"] == 40_000
    for other in runs[1:]:
        assert other == runs[0]


cpp_follow_colors = test_missions.cpp_follow_colors  # the fixture: follow_colors_cpp compiled


@pytest.mark.slow
@pytest.mark.timeout(CPP_BUILD_TIMEOUT + 300)
def test_python_and_cpp_fly_the_same_trace_in_lockstep(tmp_path: Path,
                                                        cpp_follow_colors: list[str]) -> None:
    status, py = fly(tmp_path / "python")
    assert status == 0, (py / "component.log").read_text()[-2000:]
    status, cpp = fly(tmp_path / "cpp", command=cpp_follow_colors)
    assert status == 0, (cpp / "component.log").read_text()[-2000:]
    # The same but for the component's name and the run's folder (the report's path, logged).
    py_trace = (py / "trace.jsonl").read_text().replace(str(py), "DIR")
    cpp_trace = (cpp / "trace.jsonl").read_text().replace(str(cpp), "DIR") \
        .replace("follow_colors_cpp", "follow_colors")
    assert cpp_trace == py_trace
    assert (cpp / "truth.json").read_bytes() == (py / "truth.json").read_bytes()
    assert json.loads((py / "report.json").read_text())["stages"] == \
        ["green", "blue", "green", "red"]


@pytest.mark.parametrize("killed", ["sim", "component"])
def test_killing_either_side_mid_flight_ends_the_other(tmp_path: Path, killed: str) -> None:
    # --speedup 5: the flight lasts long enough (about 30 s) to be killed in the middle.
    with flight(tmp_path, "--speedup", "5", lockstep=True) as f:
        wait_for_line(f.folder / "component.log", r"stage 1: green", f.component, timeout=120)
        victim, other = (f.sim, f.component) if killed == "sim" else (f.component, f.sim)
        victim.send_signal(signal.SIGKILL)
        victim.wait(timeout=10)
        # The other side notices at once (its socket is closed): bounded, not timed.
        other.wait(timeout=5)
        if killed == "sim":
            log = (f.folder / "component.log").read_text()
            assert "the simulator has gone (its connection is closed); the component stops" \
                in log, log[-2000:]
            assert other.returncode == 1
            trace = f.trace
            assert trace[-1]["ev"] == "stop" and trace[-1]["reason"] == "error", trace[-3:]
        else:
            log = (f.folder / "sim.log").read_text()
            assert "lockstep: the component has gone; the simulator stops" in log, log[-2000:]
            assert other.returncode == 0


def test_the_component_goes_on_in_real_time_when_asked(tmp_path: Path) -> None:
    """--component-gone realtime: the simulator flies on alone after its component."""
    with flight(tmp_path, "--component-gone", "realtime", lockstep=True,
                component_args=("--until", "5s")) as f:
        assert f.component.wait(timeout=120) == 0
        wait_for_line(f.folder / "sim.log", r"the simulator goes on in real time", f.sim,
                      timeout=30)
        time.sleep(0.5)
        assert f.sim.poll() is None  # still flying
        f.stop_sim()
        assert f.sim.returncode == 0


CAMERA_MODEL = """\
hfsm: 1
name: frames
language: python
interfaces:
  camera: {type: camera}
period: 100ms
initial: Look
states:
  Look:
    during: |
      log(f"at {round(now() * 1000)} ms frame {camera.count()} age {camera.age():.3f}")
"""


def test_the_frame_read_at_t_was_rendered_for_t(tmp_path: Path) -> None:
    """A camera at 10 frames a second and a component at 10 instants a second: at each
    instant the frame the snippet reads is the one rendered for that very time (its number
    counts from 1 at 0 s, its age is 0), as the simulator's stamps and truth say."""
    world = tmp_path / "world.yaml"
    world.write_text((FOLLOW / "world.yaml").read_text().replace("fps: 15", "fps: 10"))
    model = tmp_path / "frames.yaml"
    model.write_text(CAMERA_MODEL)
    r = subprocess.run([*HFSMC, "build", str(model), "-o", str(tmp_path / "c")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    http, port = free_port(), free_port()
    config = tmp_path / "config.yaml"
    config.write_text(json.dumps({"interfaces": {"camera": {
        "type": "camera", "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}))
    with (tmp_path / "sim.log").open("wb") as log:
        sim = subprocess.Popen([*HFSMC, "sim", "--world", str(world), "--mavlink",
                                f"udpout:127.0.0.1:{free_port(socket.SOCK_DGRAM)}",
                                "--camera-port", str(http), "--lockstep", str(port),
                                "--truth", str(tmp_path / "truth.json")],
                               stdout=log, stderr=subprocess.STDOUT)
        try:
            r = subprocess.run([*HFSMC[:1], str(tmp_path / "c" / "frames.py"), "--config",
                                str(config), "--clock", f"sim:{port}", "--until", "3s"],
                               capture_output=True, text=True, timeout=120)
            assert sim.wait(timeout=30) == 0
        finally:
            if sim.poll() is None:
                sim.kill()
                sim.wait()
    assert r.returncode == 0, r.stderr
    seen = [line.split("Look: ", 1)[1] for line in r.stderr.splitlines() if "Look: " in line]
    assert seen == [f"at {t} ms frame {t // 100 + 1} age 0.000" for t in range(0, 3001, 100)]
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["camera"] == {"frame": 31, "time": 3.0}  # rendered for the last step, 3 s


RATE = re.compile(r"(\d+\.\d{3}) s simulated, (\d+\.\d)× real time")


def blinker(tmp: Path, lang: str) -> list[str]:
    """examples/blinker (Python) or blinker_cpp (compiled): its command."""
    if lang == "python":
        model, out = ROOT / "examples/blinker/blinker.yaml", tmp / "blinker"
        r = subprocess.run([*HFSMC, "build", str(model), "-o", str(out)], capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        return [HFSMC[0], str(out / "blinker.py")]
    need_toolchain()
    model, out = ROOT / "examples/blinker_cpp/blinker_cpp.yaml", tmp / "blinker_cpp"
    r = subprocess.run([*HFSMC, "build", "-t", "cpp", str(model), "-o", str(out), "--compile"],
                       capture_output=True, text=True, timeout=CPP_BUILD_TIMEOUT)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return [str(out / "build" / "blinker_cpp")]


@pytest.mark.parametrize("lang", ["python", pytest.param(
    "cpp", marks=pytest.mark.timeout(CPP_BUILD_TIMEOUT + 120))])
def test_the_live_views_show_simulated_time_and_its_rate(
        tmp_path: Path, lang: str, tmux: Callable[..., Tmux],
        clients: Callable[..., Client]) -> None:
    """--clock sim at --speedup 5: the terminal view (--display) says its time is simulated
    and how fast it runs; the monitor's samples carry sim_rate (schemas/monitor.md, minor 2),
    never above the speedup but for the measuring's jitter."""
    command = blinker(tmp_path, lang)
    port, monitor = free_port(), free_port()
    with (tmp_path / "sim.log").open("wb") as log:
        sim = subprocess.Popen([*HFSMC, "sim", "--no-camera", "--mavlink",
                                f"udpout:127.0.0.1:{free_port(socket.SOCK_DGRAM)}",
                                "--lockstep", str(port), "--speedup", "5"],
                               stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        t = tmux(shlex.join([*command, "--clock", f"sim:{port}", "--param", "blinks=1000",
                             "--until", "300s", "--display", "--monitor", str(monitor)]),
                 tmp_path)
        screen = t.wait(lambda s: any(float(m[2]) > 0 for m in RATE.finditer(s)), timeout=60)
        shown = RATE.search(screen)
        assert shown is not None and 0 < float(shown[2]) <= 6.0, screen
        c = clients(monitor)
        msgs = c.until(lambda m: m["type"] == "sample" and m["t"] > 3000)
        samples = [m for m in msgs if m["type"] == "sample"][-5:]
        assert samples and all(0 <= m["sim_rate"] <= 6.0 for m in samples), samples
        assert msgs[0]["minor"] >= 2  # sim_rate came with minor 2
    finally:
        sim.kill()
        sim.wait(timeout=20)
