"""The web view (`hfsmc view --web`): the bridge and the picture at unit level, then the
page in a real browser (Debian's chromium, driven by selenium through its chromedriver)
against the blinker running on the real clock."""

from __future__ import annotations

import asyncio
import base64
import contextlib
import importlib
import io
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hfsmc.commands.view import view
from hfsmc.emit.structure import structure_of
from hfsmc.pipeline import compile_file
from hfsmc.web.bridge import Bridge, Page, Picture
from hfsmc.web.picture import model_from_structure, svg_of
from hfsmc.web.replay import Replay, active_at, view_at
from hfsmc.web.server import listen, make_app, painter
from hfsmc.web.trust import Trust
from tests.conftest import ROOT
from tests.cppbuild import need_toolchain
from tests.support import (
    BLINKER,
    MONITOR_VALIDATOR,
    PARALLEL_RECORDS,
    PARALLEL_STRUCTURE,
    RECORDS,
    STRUCTURE,
    WEB_URL,
    Process,
    build_blinker,
    free_port,
    many_states,
    needs_browser,
    read_messages,
    screenshot,
    wait_until,
    write_used_models,
)

monitor = importlib.import_module("hfsmc.templates.python.hfsmc_monitor")
viewstate = importlib.import_module("hfsmc.templates.python.hfsmc_viewstate")

GREEN = "rgb(76, 175, 80)"  # --active in app.css
WHITE = "rgb(255, 255, 255)"
LEAVES = ("Blinking/Lit", "Blinking/Dark")


# -- the picture ------------------------------------------------------------------------------
def ids(svg: str, kind: str) -> set[str]:
    return set(re.findall(rf'<g id="([^"]+)" class="{kind}"', svg))


def test_the_structure_alone_draws_the_same_states_and_arrows_as_the_model() -> None:
    result = compile_file(BLINKER)
    assert result.model is not None
    from_model = svg_of(result.model)
    from_structure = svg_of(model_from_structure(structure_of(result.model)))
    assert from_structure.startswith("<svg")
    for kind in ("node", "cluster"):
        states = {i for i in ids(from_model, kind) if "#" not in i}
        assert states == {i for i in ids(from_structure, kind) if "#" not in i}
    assert {"Blinking/Lit", "Blinking/Dark", "Paused", "Done"} <= ids(from_structure, "node")
    assert ids(from_structure, "cluster") == {"Blinking"}
    edges = {i for i in ids(from_model, "edge") if ":" not in i and not i.startswith("#")}
    assert edges == {"Blinking#0", "Blinking#1", "Blinking/Lit#0", "Blinking/Dark#0", "Paused#0"}
    assert edges == {i for i in ids(from_structure, "edge") if ":" not in i}
    assert "[count &gt;= blinks" in from_model and "blinks" not in from_structure  # no conditions


def test_a_structure_that_does_not_hold_together_is_refused() -> None:
    with pytest.raises(ValueError, match="bad state path"):
        model_from_structure({**STRUCTURE, "states": [{"path": "a b", "final": False,
                                                       "composite": False}]})
    with pytest.raises(ValueError, match="no states under the root"):
        model_from_structure({**STRUCTURE, "states": []})


def test_the_model_is_drawn_while_the_component_is_that_model() -> None:
    result = compile_file(BLINKER)
    assert result.model is not None
    drawn = Picture("<svg>model</svg>", "model")
    paint = painter(drawn, structure_of(result.model))
    other_params = {**structure_of(result.model), "parameters": {"blinks": "1000"}}
    assert asyncio.run(paint(other_params)) is drawn  # --param changes no drawing
    other = {**STRUCTURE, "transitions": STRUCTURE["transitions"][:-1]}
    fallback = asyncio.run(paint(other))
    assert fallback.drawn_from == "structure" and fallback.svg is not None
    assert 'id="Paused"' in fallback.svg and 'id="Paused#0"' not in fallback.svg
    assert fallback.problem is not None and "not the model given with --model" in fallback.problem
    broken = asyncio.run(paint({**STRUCTURE, "states": []}))
    assert broken == Picture(None, "", "no picture: the structure has no states under the root")


def test_a_sub_automaton_is_drawn_alone_from_the_picture_s_model() -> None:
    async def story() -> None:
        async def paint(structure: dict[str, Any]) -> Picture:
            return Picture("<svg/>", "structure")

        bridge = Bridge("127.0.0.1", 9, paint, log=io.StringIO())
        assert await bridge.sub_svg("Blinking") is None  # no picture yet
        bridge.picture = await painter(None, None)(STRUCTURE)
        sub = await bridge.sub_svg("Blinking")
        assert sub is not None and sub.startswith("<svg")
        assert ids(sub, "node") >= {"Blinking/Lit", "Blinking/Dark"}
        assert "Paused" not in ids(sub, "node") | ids(sub, "cluster")
        assert await bridge.sub_svg("Blinking") is sub  # drawn once
        for wrong in ("Paused", "Nope", "", "Blinking/Lit"):
            assert await bridge.sub_svg(wrong) is None, wrong
        for n in range(2000):  # junk paths draw nothing and are not kept
            assert await bridge.sub_svg(f"Nope{n}/" + "x" * 500) is None
        assert set(bridge._subs) == {"Blinking"}

    asyncio.run(asyncio.wait_for(story(), 20))


def test_regions_are_drawn_from_the_structure_as_from_the_model(tmp_path: Path) -> None:
    """A structure's automata that name a region give the state its regions: the same
    clusters (the state's, one per region) and state nodes as the model's drawing, and each
    region alone can be drawn."""
    yaml = tmp_path / "par.yaml"
    yaml.write_text(PAR_YAML)
    result = compile_file(str(yaml))
    assert result.model is not None, result.diagnostics
    assert structure_of(result.model) == PARALLEL_STRUCTURE
    rebuilt = model_from_structure(PARALLEL_STRUCTURE)
    mission = rebuilt.find("Mission")
    assert mission is not None and mission.parallel
    assert [(a.region, a.period_ms, a.history, a.path) for a in mission.automata] == [
        ("Nav", 100, False, "Mission/Nav"), ("Watch", 300, True, "Mission/Watch")]
    from_model, from_structure = svg_of(result.model), svg_of(rebuilt)
    for kind in ("node", "cluster"):
        assert {i for i in ids(from_model, kind) if "#" not in i} == \
            {i for i in ids(from_structure, kind) if "#" not in i}
    assert ids(from_structure, "cluster") == {"Mission", "Mission/Nav", "Mission/Watch"}
    assert ids(svg_of(rebuilt, "Mission/Watch"), "node") >= {"Mission/Watch/Ok", "Mission/Watch/Seen"}
    with pytest.raises(ValueError, match="bad region"):
        model_from_structure({**PARALLEL_STRUCTURE, "automata": [
            *PARALLEL_STRUCTURE["automata"], {"owner": "", "region": "X", "period_ms": 1,
                                              "initial": "A", "history": False}]})


PAR_YAML = """\
hfsm: 1
name: par
period: 100ms
variables: {n: 0}
initial: Mission
states:
  Mission:
    regions:
      Nav:
        initial: A
        states:
          A: {transitions: [{to: B, after: 200ms}]}
          B: {final: true}
      Watch:
        period: 300ms
        initial: Ok
        history: true
        states:
          Ok: {transitions: [{to: Seen, when: n >= 3, name: seen}]}
          Seen: {final: true}
    transitions: [{to: Done, when: done(), name: all done}]
  Done: {final: true}
"""


def cluster_titles(svg: str) -> list[str]:
    """The first line of every cluster's label, in the drawing's order."""
    return re.findall(r'<g id="[^"]+" class="cluster">\s*<title>[^<]*</title>\s*(?:<[^t][^>]*>\s*)*'
                      r'<text[^>]*>([^<]*)</text>', svg)


def test_a_used_file_is_drawn_from_the_structure_as_from_the_model(tmp_path: Path) -> None:
    """A structure's ``use`` makes the automaton an instance of that file: its cluster is
    named after it as in the model's drawing (a nested use too), alone as well."""
    result = compile_file(str(write_used_models(tmp_path)))
    assert result.model is not None, result.diagnostics
    rebuilt = model_from_structure(structure_of(result.model))
    for path, written in (("First", "lib/climb.yaml"), ("Second/Hold", "hold.yaml")):
        state, real = rebuilt.find(path), result.model.find(path)
        assert state is not None and state.automaton is not None and state.automaton.instance is not None
        assert real is not None and real.automaton is not None and real.automaton.instance is not None
        instance = state.automaton.instance
        assert (instance.written, instance.file) == (written, written)
        # Its model has the used file's states with their paths there, as the real one's.
        assert [s.path for s in instance.model.states()] == \
            [s.path for s in real.automaton.instance.model.states()]
    assert [s.path for s in rebuilt.find("First").automaton.instance.model.states()] == [  # type: ignore[union-attr]
        "Climb", "Hold", "Hold/Wait", "Hold/Still", "Up"]
    from_model, from_structure = svg_of(result.model), svg_of(rebuilt)
    for kind in ("node", "cluster"):
        assert {i for i in ids(from_model, kind) if "#" not in i} == \
            {i for i in ids(from_structure, kind) if "#" not in i}
    titles = cluster_titles(from_structure)
    assert titles == cluster_titles(from_model)
    assert titles == ["First · lib/climb.yaml", "Hold · hold.yaml", "Second · lib/climb.yaml",
                      "Hold · hold.yaml"], titles
    for alone in ("First", "First/Hold"):  # the title of a sub-automaton drawn alone
        files = [re.findall(r"<text[^>]*>([^<]*\.yaml[^<]*)</text>", svg_of(m, alone)) for m in (rebuilt, result.model)]
        assert files[0] == files[1] and files[0][0].startswith(f"legs: {alone} · "), files
    assert model_from_structure(STRUCTURE).find("Blinking").automaton.instance is None  # type: ignore[union-attr]


# -- the bridge against a real monitor server --------------------------------------------------
async def next_message(page: Page, timeout: float = 3.0) -> dict[str, Any]:
    text = await asyncio.wait_for(page.queue.get(), timeout)
    assert text is not None
    msg: dict[str, Any] = json.loads(text)
    return msg


async def _bridge_story() -> None:
    srv = monitor.MonitorServer(port=0, announce=io.StringIO())
    srv.start(STRUCTURE)
    painted: list[dict[str, Any]] = []

    async def paint(structure: dict[str, Any]) -> Picture:
        painted.append(structure)
        return Picture("<svg/>", "structure")

    log = io.StringIO()
    bridge = Bridge("127.0.0.1", srv.port, paint, log=log)
    task = asyncio.create_task(bridge.run())
    try:
        for rec in ({"t": 0, "ev": "start", "name": "blinker"},
                    {"t": 0, "ev": "enter", "state": "Blinking"},
                    {"t": 0, "ev": "enter", "state": "Blinking/Lit"}):
            srv.record(rec)
        first = bridge.attach()
        assert (await next_message(first))["type"] == "state"  # not connected yet: no model
        while bridge.status != "connected" or "Blinking/Lit" not in bridge.view.active:
            await asyncio.sleep(0.01)
        late = bridge.attach()
        model, state = await next_message(late), await next_message(late)
        assert model["type"] == "model" and model["svg"] == "<svg/>"
        assert model["structure"] == STRUCTURE and painted == [STRUCTURE]
        assert state["status"] == "connected"
        assert state["active"] == [{"state": "Blinking", "since": 0},
                                   {"state": "Blinking/Lit", "since": 0}]
        # A transition: one delta says what the pages draw, whoever attached when.
        for rec in ({"t": 500, "ev": "fire", "from": "Blinking/Lit", "to": "Blinking/Dark",
                     "index": 0},
                    {"t": 500, "ev": "exit", "state": "Blinking/Lit"},
                    {"t": 500, "ev": "enter", "state": "Blinking/Dark"}):
            srv.record(rec)
        srv.sample(520, {"x": "0.30000000000000004"}, 2)
        delta = await next_message(late)
        while "variables" not in delta:
            more = await next_message(late)
            for key in ("enter", "exit", "fired"):
                delta[key] = delta.get(key, []) + more.get(key, [])
            delta.update({k: v for k, v in more.items() if k not in ("enter", "exit", "fired")})
        assert delta["enter"] == [{"state": "Blinking/Dark", "since": 500}]
        assert delta["exit"] == ["Blinking/Lit"]
        assert delta["fired"] == [{"t": 500, "from": "Blinking/Lit", "to": "Blinking/Dark",
                                   "index": 0, "name": None}]
        assert delta["variables"] == {"x": "0.3"}  # readable precision
        assert delta["overruns"] == 2
        # The component goes: the pages are told, and the bridge keeps trying.
        srv.close()
        while bridge.status == "connected":
            await asyncio.sleep(0.01)
        status = await next_message(late)
        while status["type"] != "status":
            status = await next_message(late)
        assert status["status"] == "stopped"
        assert status["note"] == "component closed the monitor; waiting for it to come back"
        assert "hfsmc view: connected to 127.0.0.1:" in log.getvalue()
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        srv.close()


def test_the_bridge_gives_a_state_then_deltas() -> None:
    asyncio.run(asyncio.wait_for(_bridge_story(), 20))


def test_a_page_that_falls_behind_is_dropped() -> None:
    async def story() -> None:
        page = Page(limit=3)
        assert all(page.offer(str(n)) for n in range(3))
        assert not page.offer("3") and page.dropped
        assert page.queue.get_nowait() is None  # what waited is thrown away; then the end
        assert not page.offer("4")

    asyncio.run(story())


async def _slow_and_fast_pages() -> None:
    import aiohttp
    from aiohttp import web

    async def no_picture(structure: dict[str, Any]) -> Picture:
        return Picture(None, "")

    bridge = Bridge("127.0.0.1", 9, no_picture, log=io.StringIO(), queue_limit=8)
    sock = listen("127.0.0.1", 0)
    port = sock.getsockname()[1]
    trust = Trust.new(sock)
    runner = web.AppRunner(make_app(bridge, trust, io.StringIO()))
    await runner.setup()
    await web.SockSite(runner, sock).start()
    # A browser that never reads: a WebSocket handshake by hand on a socket left alone.
    slow = socket.socket()
    slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    slow.connect(("127.0.0.1", port))
    slow.sendall(f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nCookie: {trust.cookie}={trust.token}"
                 "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                 "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
                 .encode())
    try:
        async with aiohttp.ClientSession() as session, \
                session.ws_connect(f"http://127.0.0.1:{port}/ws?token={trust.token}") as fast:
            assert json.loads((await fast.receive(timeout=5)).data)["type"] == "state"
            while len(bridge.pages) < 2:
                await asyncio.sleep(0.01)
            pad = "x" * 100_000
            for n in range(300):  # 30 MB: far more than the slow page's socket holds
                bridge._broadcast({"type": "delta", "n": n, "pad": pad})
                got = json.loads((await fast.receive(timeout=5)).data)
                assert got["n"] == n  # the fast page gets every message, in order
            assert len(bridge.pages) == 1, "the slow page was not dropped"
    finally:
        slow.close()
        await runner.cleanup()


def test_a_browser_that_does_not_read_is_dropped_and_the_others_go_on() -> None:
    asyncio.run(asyncio.wait_for(_slow_and_fast_pages(), 60))


# -- the command line ---------------------------------------------------------------------------
# -- replay ------------------------------------------------------------------------------------
def trace_active(records: list[dict[str, Any]], t: int) -> set[str]:
    """The states active at ``t`` by the trace's own enter and exit records (the test's fold)."""
    active: set[str] = set()
    for rec in records:
        if rec["t"] <= t and rec["ev"] == "enter":
            active.add(rec["state"])
        elif rec["t"] <= t and rec["ev"] == "exit":
            active.discard(rec["state"])
    return active


def test_the_states_active_at_an_instant_come_from_the_trace() -> None:
    assert active_at(STRUCTURE, RECORDS, 499) == ["Blinking", "Blinking/Lit"]
    assert active_at(STRUCTURE, RECORDS, 500) == ["Blinking", "Blinking/Dark"]
    assert active_at(STRUCTURE, RECORDS, 3100) == ["Paused"]
    assert active_at(STRUCTURE, RECORDS, 3200) == []
    for t in range(0, 3300, 50):
        assert set(active_at(STRUCTURE, RECORDS, t)) == trace_active(RECORDS, t), t


def test_a_trace_with_regions_replays_without_the_model() -> None:
    """The structure inferred from the trace gives the regions: drawn as region clusters,
    the states of both regions active at once."""
    inferred = viewstate.infer_structure(PARALLEL_RECORDS)
    picture = asyncio.run(painter(None, None)(inferred))
    assert picture.svg is not None and picture.problem is None
    assert ids(picture.svg, "cluster") == {"Mission", "Mission/Nav", "Mission/Watch"}
    assert active_at(inferred, PARALLEL_RECORDS, 500) == ["Mission", "Mission/Watch/Ok", "Mission/Nav/B"]
    for t in range(0, 1100, 100):
        assert set(active_at(inferred, PARALLEL_RECORDS, t)) == trace_active(PARALLEL_RECORDS, t), t


async def _replay_story() -> None:
    async def paint(structure: dict[str, Any]) -> Picture:
        return Picture("<svg/>", "structure")

    replay = Replay(RECORDS, STRUCTURE, "blinker.trace", paint, log=io.StringIO())
    task = asyncio.create_task(replay.run())
    try:
        while replay.structure is None:
            await asyncio.sleep(0.01)
        page = replay.attach()
        model, state = await next_message(page), await next_message(page)
        assert model["replay"] == {"trace": "blinker.trace", "end": 3200, "fires": [500, 3000],
                                   "variables": False}
        assert state["status"] == "replay" and "no variable records" in state["note"]
        assert state["replay"] == {"t": 0, "playing": False, "speed": 1.0, "end": 3200}

        async def after(command: dict[str, Any] | str) -> tuple[list[str], dict[str, Any]]:
            replay.command(command if isinstance(command, str) else json.dumps(command))
            msg = await next_message(page)
            assert msg["type"] == "state"
            where = await next_message(page)
            assert where["type"] == "replay"
            return [a["state"] for a in msg["active"]], where

        assert await after({"do": "seek", "t": 1200}) == (
            ["Blinking", "Blinking/Dark"], {"type": "replay", "t": 1200, "playing": False,
                                            "speed": 1.0, "end": 3200})
        assert (await after({"do": "next"}))[0] == ["Paused"] and replay.position == 3000
        assert (await after({"do": "next"}))[1]["t"] == 3200  # no transition after: the end
        assert (await after({"do": "previous"}))[1]["t"] == 3000
        assert (await after({"do": "previous"}))[1]["t"] == 500
        assert (await after({"do": "previous"}))[0] == ["Blinking", "Blinking/Lit"]
        for junk in ("nope", "[]", '{"do":"seek","t":"x"}', '{"do":"speed","speed":true}',
                     '{"do":"seek","t":1e999}', '{"do":"launch"}', '{"do":"seek","t":1}' + " " * 300):
            replay.command(junk)
        assert replay.position == 0 and page.queue.empty()
        # Played at 100 times real time: the deltas of a live component, then the end.
        replay.command(json.dumps({"do": "speed", "speed": 100}))
        replay.command(json.dumps({"do": "play"}))
        entered: list[str] = []
        while True:
            msg = await next_message(page)
            entered += [a["state"] for a in msg.get("enter", [])]
            if msg["type"] == "replay" and not msg["playing"] and msg["t"] == 3200:
                break
        assert entered == ["Blinking/Dark", "Paused"]
        assert replay.view.stop_reason == "sigint" and not replay.view.active
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


def test_a_replay_seeks_steps_and_plays_as_the_pages_say() -> None:
    asyncio.run(asyncio.wait_for(_replay_story(), 20))


# -- vehicles, camera frames and variables in replay (monitor minor version 1) ----------------
class FakeVehicle:
    """What a mavlink driver answers (hfsmc_mavlink.Vehicle's queries)."""

    def __init__(self) -> None:
        self.alt = 2.345678

    def connected(self) -> bool:
        return True

    def mode(self) -> str:
        return "GUIDED"

    def armed(self) -> bool:
        return True

    def altitude(self) -> float:
        return self.alt

    def position(self) -> tuple[float, float, float]:
        return (1.0, -2.5, -self.alt)

    def velocity(self) -> tuple[float, float, float]:
        return (float("nan"),) * 3

    def battery(self) -> int:
        return 87

    def heartbeat_age(self) -> float:
        return 0.25


class FakeCamera:
    """A camera driver whose snippet read a 640x480 frame (hfsmc_camera.Camera._last_seen)."""

    def __init__(self) -> None:
        import numpy as np

        self.image = np.zeros((480, 640, 3), np.uint8)
        self.image[:, 320:] = (0, 0, 255)  # right half red (BGR)

    def _last_seen(self) -> Any:
        return self.image


class Unusable:
    """An interface the component cannot drive: any use raises (runtime's Unavailable)."""

    def __getattr__(self, name: str) -> Any:
        raise RuntimeError("cannot be used")


def test_the_monitor_sends_vehicles_to_every_viewer_and_frames_only_to_those_that_ask() -> None:
    import cv2
    import numpy as np

    camera = FakeCamera()
    srv = monitor.MonitorServer(port=0, announce=io.StringIO())
    srv.watch({"drone": FakeVehicle(), "camera": camera, "ros": Unusable(), "none": None})
    srv.start(STRUCTURE)
    try:
        asks = socket.create_connection(("127.0.0.1", srv.port), timeout=5)
        quiet = socket.create_connection(("127.0.0.1", srv.port), timeout=5)
        asks.sendall(b'junk\n{"type":"subscribe","frames":"yes"}\n' + b"x" * 5000 + b"\n"
                     b'{"type":"subscribe",\n"frames":true}\n{"type": "subscribe", "frames": true}\n')
        got, other = read_messages(asks, 1.2), read_messages(quiet, 0.3)
        for msgs in (got, other):
            for m in msgs:
                MONITOR_VALIDATOR.validate(m)
            assert msgs[0]["minor"] == 4 and msgs[0]["feeds"] == {
                "vehicle": ["drone"], "camera": ["camera"], "ros2": [], "driver": []}
        vehicles = [m for m in got if m["type"] == "vehicle"]
        assert 3 <= len(vehicles) <= 6, len(vehicles)  # about 4 a second
        assert vehicles[0] == {"type": "vehicle", "t": 0, "name": "drone", "connected": True,
                               "mode": "GUIDED", "armed": True, "altitude": 2.346,
                               "position": [1.0, -2.5, -2.346], "velocity": None, "battery": 87,
                               "link_age": 0.25}
        frames = [m for m in got if m["type"] == "frame"]
        assert len(frames) == 1, frames  # the frame did not change: sent once
        assert (frames[0]["name"], frames[0]["width"], frames[0]["height"]) == ("camera", 320, 240)
        # The terminal viewer (and any viewer of minor version 0) ignores both.
        assert monitor.item(vehicles[0]) is None and monitor.item(frames[0]) is None
        assert monitor.item(got[0]) == ("structure", STRUCTURE)
        jpeg = base64.b64decode(frames[0]["jpeg"])
        image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
        assert image is not None and image.shape == (240, 320, 3)
        assert image[120, 300][2] > 200 and image[120, 20][2] < 50  # the red half is on the right
        assert [m["type"] for m in other].count("vehicle") >= 1 and "frame" not in {
            m["type"] for m in read_messages(quiet, 0.6)}
        camera.image = camera.image.copy()  # a snippet obtained a new frame
        assert [m["type"] for m in read_messages(asks, 0.6)].count("frame") == 1
        asks.sendall(b'{"type":"subscribe","frames":false}\n')
        time.sleep(0.1)
        camera.image = camera.image.copy()
        assert "frame" not in {m["type"] for m in read_messages(asks, 0.6)}
        asks.close()
        quiet.close()
    finally:
        srv.close()


class NoisyCamera:
    """A camera whose snippet reads a new frame of noise each time (large JPEGs, 4 a second)."""

    def __init__(self) -> None:
        import numpy as np

        self.image = np.random.default_rng(17).integers(0, 256, (480, 640, 3), dtype=np.uint8)
        self.frozen = False

    def _last_seen(self) -> Any:
        return self.image if self.frozen else self.image[:]  # a new object: a new frame


def test_a_viewer_that_does_not_read_its_frames_is_skipped_for_frames_and_not_dropped() -> None:
    # The frames' backlog (FRAME_BACKLOG, 256 KiB) is below the client's buffer, so the
    # stalled viewer's frames stop before the buffer overflows and the records still fit.
    srv = monitor.MonitorServer(port=0, announce=io.StringIO(), buffer_limit=300_000)
    camera = NoisyCamera()
    srv.watch({"drone": FakeVehicle(), "camera": camera})
    srv.start(STRUCTURE)
    stalled = socket.socket()
    try:
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # a small window
        stalled.connect(("127.0.0.1", srv.port))
        reader = socket.create_connection(("127.0.0.1", srv.port), timeout=5)
        # The kernel's buffers made small (it would otherwise hold megabytes), so that
        # the monitor's own limits are what this tests.
        deadline = time.monotonic() + 5
        while len(srv._clients) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        for c in list(srv._clients.values()):
            if c.sock.getpeername() == stalled.getsockname():
                c.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
        for s in (stalled, reader):
            s.sendall(b'{"type":"subscribe","frames":true}\n')
        read = [m["type"] for m in read_messages(reader, 3.0)]
        camera.frozen = True  # no new frame from now on
        read += [m["type"] for m in read_messages(reader, 0.5)]
        assert read.count("frame") >= 6, read.count("frame")  # about 4 a second, each new
        late = [m["type"] for m in read_messages(stalled, 1.0)]
        # It was sent the frames that fitted, then none: fewer than the reader, whole lines.
        assert late[0] == "hello" and 1 <= late.count("frame") < read.count("frame") - 2, late
        assert "vehicle" in late
        # Not dropped: reading again, it gets the records and the frames as they come.
        camera.frozen = False
        again = [m["type"] for m in read_messages(stalled, 1.0)]
        assert "vehicle" in again and "frame" in again, again
        assert "frame" in {m["type"] for m in read_messages(reader, 0.6)}
        reader.close()
    finally:
        stalled.close()
        srv.close()


async def _feeds_story() -> None:
    camera = FakeCamera()
    vehicle = FakeVehicle()
    srv = monitor.MonitorServer(port=0, announce=io.StringIO())
    srv.watch({"drone": vehicle, "camera": camera})
    srv.start(STRUCTURE)

    async def paint(structure: dict[str, Any]) -> Picture:
        return Picture("<svg/>", "structure")

    bridge = Bridge("127.0.0.1", srv.port, paint, log=io.StringIO())
    task = asyncio.create_task(bridge.run())
    try:
        while bridge.status != "connected" or "drone" not in bridge.vehicles:
            await asyncio.sleep(0.02)
        await asyncio.sleep(0.6)
        assert bridge.frames == {}  # no page: no frames asked for
        page = bridge.attach()
        kinds: dict[str, dict[str, Any]] = {}
        while "frame" not in kinds or "model" not in kinds:
            msg = await next_message(page)
            kinds[msg["type"]] = msg
        assert kinds["model"]["feeds"] == {"vehicle": ["drone"], "camera": ["camera"], "ros2": [],
                                           "driver": []}
        assert kinds["vehicle"]["altitude"] == 2.346 and kinds["vehicle"]["battery"] == 87
        assert kinds["frame"]["width"] == 320 and kinds["frame"]["jpeg"]
        vehicle.alt = 7.5
        late = bridge.attach()  # gets the latest vehicle and frame at once
        first = [json.loads(t) for t in [late.queue.get_nowait() for _ in range(late.queue.qsize())]
                 if t is not None]
        assert [m["type"] for m in first] == ["model", "state", "vehicle", "frame"]
        while (await next_message(late)).get("altitude") != 7.5:
            pass
        bridge.detach(page)
        bridge.detach(late)
        assert bridge._subscribed == (False, False)  # neither frames nor scans
        while any(c.frames for c in srv._clients.values()):
            await asyncio.sleep(0.02)
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        srv.close()


def test_the_bridge_passes_vehicles_and_frames_on_and_asks_for_frames_only_while_a_page_is_open(
        ) -> None:
    asyncio.run(asyncio.wait_for(_feeds_story(), 20))


def test_trace_variables_adds_variable_records_and_nothing_else(blinker: Path, tmp_path: Path) -> None:
    def run(*flags: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, str(blinker), "--clock", "virtual", "--until", "4s",
                               *flags], capture_output=True, text=True, timeout=60,
                              stdin=subprocess.DEVNULL)

    assert run("--trace", str(tmp_path / "plain.trace")).returncode == 0
    assert run("--trace", str(tmp_path / "vars.trace"), "--trace-variables").returncode == 0
    plain = [json.loads(x) for x in (tmp_path / "plain.trace").read_text().splitlines()]
    both = [json.loads(x) for x in (tmp_path / "vars.trace").read_text().splitlines()]
    assert [r for r in both if r["ev"] != "variables"] == plain
    for rec in both:
        MONITOR_VALIDATOR.validate({"type": "record", "record": rec})  # the trace's schema
    values = [r for r in both if r["ev"] == "variables"]
    assert values[0] == {"t": 0, "ev": "variables",
                         "values": {"led": "True", "count": "1", "pauses": "0"}}
    assert {"t": 500, "ev": "variables", "values": {"led": "False"}} in values
    assert all(r["values"] for r in values)  # only records of a change
    # What the replay shows at an instant: the values the records up to it gave.
    for t, led, count in ((250, "True", "1"), (750, "False", "1"), (1000, "True", "2")):
        view = view_at(STRUCTURE, both, t)
        assert (view.values["led"], view.values["count"]) == (led, count), t
    assert view_at(STRUCTURE, plain, 750).values == {}
    # The terminal viewer replays such a trace too (its screen shows the variables).
    shown = subprocess.run([sys.executable, "-m", "hfsmc", "view", "--replay",
                            str(tmp_path / "vars.trace"), "--speed", "0"], capture_output=True,
                           text=True, timeout=60, stdin=subprocess.DEVNULL, cwd=ROOT)
    assert shown.returncode == 0 and shown.stderr.strip().endswith(
        f"replayed {len(both)} records of {tmp_path / 'vars.trace'}"), shown.stderr
    bad = run("--trace-variables")
    assert bad.returncode == 2 and bad.stderr == "blinker: --trace-variables needs --trace FILE\n"


def test_web_usage_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert view(None, str(tmp_path / "t.jsonl"), web="0") == 1
    assert capsys.readouterr().err == (f"hfsmc: error: cannot read {tmp_path / 't.jsonl'}: "
                                       "No such file or directory\n")
    assert view(None, str(tmp_path / "t.jsonl"), web="0", speed=0.0) == 2
    assert capsys.readouterr().err == ("hfsmc: error: bad --speed 0.0: the web view plays from "
                                       "more than 0 to 1000 times real time\n")
    assert view("8765", None, web="1.2.3:x") == 2
    assert capsys.readouterr().err == ("hfsmc: error: bad address '1.2.3:x': expected [HOST:]PORT "
                                       "with a port from 0 to 65535\n")
    assert view("0", None, web="0") == 2
    assert "port 0 is not a component's port" in capsys.readouterr().err
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        assert view("8765", None, web=str(port)) == 1
    assert capsys.readouterr().err == (f"hfsmc: error: cannot serve the web view on "
                                       f"127.0.0.1:{port}: Address already in use\n")


# -- in a real browser ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def blinker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_blinker(tmp_path_factory.mktemp("component") / "blinker")


def component(logged: Callable[..., Process], main: Path, port: int = 0,
              until: str = "60s") -> tuple[Process, int]:
    """The blinker on the real clock, blinking until ``until``; its monitor port."""
    p = logged([sys.executable, str(main), "--monitor", str(port), "--clock", "real",
                   "--until", until, "--param", "blinks=100000"], "component")
    return p, int(p.wait_for(r"monitor: listening on 127\.0\.0\.1:(\d+)").group(1))


def web_view(logged: Callable[..., Process], port: int) -> tuple[Process, str]:
    p = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0", f"127.0.0.1:{port}",
                   "--model", str(ROOT / BLINKER)], "web")
    url = p.wait_for(WEB_URL, where="out").group(1)
    return p, url


# What the page shows, read from its DOM: the SVG elements and tree rows marked active, and
# the computed fill of each state's circle.
PAGE_JS = """
const fill = (p) => {
  const g = [...document.querySelectorAll('#hv-diagram g.node')].find((e) => e.id === p);
  const e = g && g.querySelector('ellipse');
  return e ? getComputedStyle(e).fill : null;
};
return {
  status: document.body.dataset.status,
  rate: document.getElementById('hv-rate').hidden ? null : document.getElementById('hv-rate').textContent,
  simRate: document.body.dataset.simRate === undefined ? null : Number(document.body.dataset.simRate),
  clock: document.getElementById('hv-clock').textContent,
  banner: document.getElementById('hv-banner').hidden ? '' : document.getElementById('hv-banner').textContent,
  svg: [...document.querySelectorAll('#hv-diagram g.hv-active')].map((g) => g.id),
  tree: [...document.querySelectorAll('#hv-tree li.hv-active')].map((li) => li.dataset.path),
  fills: Object.fromEntries(arguments[0].map((p) => [p, fill(p)])),
  count: (document.querySelector('#hv-vars tr[data-name="count"] td:last-child') || {}).textContent,
};
"""


def page(driver: Any) -> dict[str, Any]:
    shown: dict[str, Any] = driver.execute_script(PAGE_JS, [*LEAVES, "Paused", "Done"])
    return shown


def wait_page(driver: Any, ok: Callable[[dict[str, Any]], bool], timeout: float = 10) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while not ok(shown := page(driver)):
        assert time.monotonic() < deadline, shown
        time.sleep(0.05)
    return shown


def green_leaf(shown: dict[str, Any]) -> str | None:
    """The leaf drawn green while the tree agrees with the picture (None otherwise)."""
    if shown["status"] != "connected" or sorted(shown["svg"]) != sorted(shown["tree"]):
        return None
    leaves = [p for p in LEAVES if p in shown["svg"]]
    if len(leaves) != 1 or "Blinking" not in shown["svg"]:
        return None
    other = LEAVES[1 - LEAVES.index(leaves[0])]
    ok = shown["fills"][leaves[0]] == GREEN and shown["fills"][other] == WHITE
    return leaves[0] if ok else None


# Whether the deepest active state is drawn inside the diagram's pane; its viewBox.
FOCUS_JS = """
const svg = document.querySelector('#hv-diagram svg');
const active = [...svg.querySelectorAll('g.hv-active')];
const deepest = active.sort((a, b) => b.id.split('/').length - a.id.split('/').length)[0];
const r = deepest.getBoundingClientRect(), s = svg.getBoundingClientRect();
return [r.left >= s.left && r.right <= s.right && r.top >= s.top && r.bottom <= s.bottom,
        svg.getAttribute('viewBox'), document.getElementById('hv-autofocus').checked];
"""
GESTURE_JS = """
const pane = document.getElementById('hv-diagram');
const at = {clientX: 200, clientY: 300, bubbles: true, cancelable: true};
pane.dispatchEvent(new WheelEvent('wheel', {...at, deltaY: -600}));
pane.dispatchEvent(new MouseEvent('mousedown', {...at, button: 0}));
window.dispatchEvent(new MouseEvent('mousemove', {...at, clientX: 3000, clientY: 2500}));
window.dispatchEvent(new MouseEvent('mouseup', at));
"""


def pan_zoom_and_autofocus(driver: Any) -> None:
    """Zooming and panning by hand turn autofocus off; turned on, it brings the deepest
    active state back into view."""
    inside, box, on = driver.execute_script(FOCUS_JS)
    assert on
    width = float(box.split()[2])
    driver.execute_script(GESTURE_JS)
    inside, box, on = driver.execute_script(FOCUS_JS)
    assert not on and float(box.split()[2]) < width / 2 and not inside, (inside, box)
    driver.find_element("id", "hv-autofocus").click()
    inside, box, on = driver.execute_script(FOCUS_JS)
    assert on and inside, box


def open_subautomaton(driver: Any, tmp_path: Path) -> None:
    """A click on the Blinking cluster opens its sub-automaton alone in a tab, live; the tree
    folds and unfolds it."""
    driver.find_element("id", "hv-fit").click()
    driver.find_element("css selector", '#hv-diagram g.cluster[id="Blinking"] text').click()
    tabs = driver.find_element("id", "hv-tabs")
    deadline = time.monotonic() + 5
    while not tabs.is_displayed() or len(tabs.find_elements("css selector", ".hv-tab")) != 2:
        assert time.monotonic() < deadline, "no tab opened"
        time.sleep(0.05)
    current = tabs.find_element("css selector", ".hv-tab.hv-current")
    assert current.get_attribute("data-path") == "Blinking" and current.text.startswith("Blinking")
    nodes = {g.get_attribute("id") for g in
             driver.find_elements("css selector", "#hv-diagram g.node[id]")}
    assert {"Blinking/Lit", "Blinking/Dark"} <= nodes and not {"Paused", "Done"} & nodes, nodes

    def leaf(s: dict[str, Any]) -> str | None:  # the one green leaf, the other white
        on = [p for p in LEAVES if p in s["svg"]]
        if len(on) != 1 or s["fills"][on[0]] != GREEN:
            return None
        return on[0] if s["fills"][LEAVES[1 - LEAVES.index(on[0])]] == WHITE else None

    first = leaf(wait_page(driver, lambda s: leaf(s) is not None, timeout=5))
    wait_page(driver, lambda s: leaf(s) not in (None, first), timeout=5)  # live
    screenshot(driver, "web-subautomaton", tmp_path)
    rows = {p: driver.find_element("css selector", f'#hv-tree li[data-path="{p}"]') for p in LEAVES}
    fold = driver.find_element("css selector", '#hv-tree li[data-path="Blinking"] .hv-fold')
    fold.click()
    assert not any(r.is_displayed() for r in rows.values()) and fold.text == "▸"
    fold.click()
    assert all(r.is_displayed() for r in rows.values()) and fold.text == "▾"
    tabs.find_element("css selector", '.hv-tab[data-path="Blinking"] .hv-close').click()
    assert not tabs.is_displayed()
    assert driver.find_elements("css selector", '#hv-diagram g.node[id="Paused"]')


def moved_on(driver: Any) -> None:
    """Wait until another leaf than the one drawn now is drawn green."""
    seen = green_leaf(page(driver))
    wait_page(driver, lambda s: green_leaf(s) not in (None, seen), timeout=5)


async def _garbage(url: str) -> None:
    """Things no page sends, on the page's WebSocket and on the web view's port."""
    import aiohttp

    base, token = url.split("?token=")
    ws_url = f"{base.replace('http://', 'ws://')}ws?token={token}"  # a script: the token, no Origin
    async with aiohttp.ClientSession() as session:
        async with session.ws_connect(ws_url) as ws:
            for junk in ("not json", '{"type":"state","active":[]}', "{" * 10_000, "\0\1\2"):
                await ws.send_str(junk)
            await ws.send_bytes(os.urandom(5000))
            first = await ws.receive(timeout=5)
            assert json.loads(first.data)["type"] in ("model", "state")
        async with session.ws_connect(ws_url) as ws:
            await ws.send_bytes(b"x" * 200_000)  # over the page's message limit: closed
            while (await ws.receive(timeout=5)).type not in (aiohttp.WSMsgType.CLOSE,
                                                              aiohttp.WSMsgType.CLOSED):
                pass
    host, port = base[len("http://"):].rstrip("/").split(":")
    with socket.create_connection((host, int(port)), timeout=5) as raw:
        raw.sendall(os.urandom(3000) + b"\r\n\r\n")
        with contextlib.suppress(OSError):
            raw.recv(1000)


@needs_browser
def test_the_page_draws_the_running_component(blinker: Path, logged: Callable[..., Process],
                                               browsers: Callable[..., Any], tmp_path: Path) -> None:
    _, port = component(logged, blinker)
    web, url = web_view(logged, port)
    first = browsers()
    first.get(url)
    shown = wait_page(first, lambda s: green_leaf(s) is not None)
    leaf = green_leaf(shown)
    assert shown["fills"]["Paused"] == WHITE and shown["fills"]["Done"] != GREEN
    # On the real clock the time is the wall clock's: no rate is shown.
    assert shown["rate"] is None and shown["simRate"] is None, shown
    assert re.fullmatch(r"t \d+\.\d{3} s", shown["clock"]), shown
    # The component takes its next transition (every 500 ms): the green moves.
    wait_page(first, lambda s: green_leaf(s) not in (None, leaf), timeout=5)
    screenshot(first, "web-blinker", tmp_path)
    # Garbage on the WebSocket and the port changes nothing for anyone.
    asyncio.run(asyncio.wait_for(_garbage(url), 20))
    assert web.proc.poll() is None
    # A late browser sees the current state at once, and both follow the component.
    time.sleep(0.3)
    late = browsers()
    t0 = time.monotonic()
    late.get(url)
    now = wait_page(late, lambda s: green_leaf(s) is not None, timeout=5)
    assert time.monotonic() - t0 < 5
    assert re.fullmatch(r"\d+", now["count"] or ""), now
    for driver in (first, late):
        moved_on(driver)
    deadline = time.monotonic() + 5
    while {green_leaf(page(first)), green_leaf(page(late))} != {"Blinking/Lit"} and \
            {green_leaf(page(first)), green_leaf(page(late))} != {"Blinking/Dark"}:
        assert time.monotonic() < deadline, "the two pages do not agree"
        time.sleep(0.02)
    pan_zoom_and_autofocus(first)
    screenshot(first, "web-autofocus", tmp_path)
    open_subautomaton(first, tmp_path)
    assert web.kill(signal.SIGTERM) == 0
    assert "Traceback" not in web.err_path.read_text()


@needs_browser
def test_the_page_says_when_the_component_goes_and_comes_back(
        blinker: Path, logged: Callable[..., Process], browsers: Callable[..., Any],
        tmp_path: Path) -> None:
    port = free_port()
    first, _ = component(logged, blinker, port)
    web, url = web_view(logged, port)
    driver = browsers()
    driver.get(url)
    wait_page(driver, lambda s: green_leaf(s) is not None)
    first.kill()
    gone = wait_page(driver, lambda s: s["status"] == "disconnected", timeout=5)
    assert gone["banner"] == f"disconnected from 127.0.0.1:{port}; trying again"
    screenshot(driver, "web-disconnected", tmp_path)
    second, _ = component(logged, blinker, port)
    back = wait_page(driver, lambda s: green_leaf(s) is not None, timeout=10)
    assert back["banner"] == ""
    assert second.kill(signal.SIGINT) == 130  # on_interrupt: Done, then the stop
    stopped = wait_page(driver, lambda s: s["status"] == "stopped", timeout=10)
    assert stopped["banner"] == "component stopped (sigint); waiting for it to come back"
    assert web.kill(signal.SIGTERM) == 0
    err = web.err_path.read_text()
    assert "Traceback" not in err
    assert err.count(f"hfsmc view: connected to 127.0.0.1:{port}") == 2, err


SEEK_JS = """
const line = document.getElementById('hv-timeline');
line.value = String(arguments[0]);
line.dispatchEvent(new Event('input', {bubbles: true}));
"""


VARS_JS = """
return Object.fromEntries([...document.querySelectorAll('#hv-vars tr[data-name]')]
  .map((tr) => [tr.dataset.name, tr.cells[1].textContent]));
"""


@needs_browser
def test_the_page_replays_a_trace(blinker: Path, logged: Callable[..., Process],
                                  browsers: Callable[..., Any], tmp_path: Path) -> None:
    trace = tmp_path / "blinker.trace"
    subprocess.run([sys.executable, str(blinker), "--clock", "virtual", "--until", "12s",
                    "--trace", str(trace)], check=True, capture_output=True, timeout=60,
                   stdin=subprocess.DEVNULL)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    fires = sorted({r["t"] for r in records if r["ev"] == "fire"})
    web = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0", "--replay", str(trace),
                     "--model", str(ROOT / BLINKER)], "web")
    url = web.wait_for(WEB_URL + r"\(replay of ", where="out").group(1)
    driver = browsers()
    driver.get(url)

    def shown_at(t: int) -> dict[str, Any]:
        # At the position and drawn so: the page may be read between two of its messages.
        return wait_page(driver, lambda s: driver.execute_script(
            "return document.body.dataset.position") == str(t) and s["status"] == "replay"
            and set(s["svg"]) == trace_active(records, t))

    shown = shown_at(0)
    assert shown["banner"] == "" and set(shown["svg"]) == trace_active(records, 0)
    hint = driver.find_element("css selector", "#hv-vars tr.hv-hint").text
    assert hint == "the trace has no variable records: no variables in replay"
    # Seek to instants inside states, at a transition and after the stop: the green
    # states and the tree are the ones the trace's enter/exit records say.
    for t in (1250, fires[3], fires[3] - 1, 3500, 7777, 12000):
        driver.execute_script(SEEK_JS, t)
        shown = shown_at(t)
        assert set(shown["svg"]) == set(shown["tree"]) == trace_active(records, t), (t, shown)
        for leaf in (*LEAVES, "Paused"):
            assert shown["fills"][leaf] == (GREEN if leaf in shown["svg"] else WHITE), (t, shown)
    # The buttons: previous and next go from one transition to the other.
    driver.execute_script(SEEK_JS, 2600)
    shown_at(2600)
    driver.find_element("id", "hv-next").click()
    nxt = min(f for f in fires if f > 2600)
    assert set(shown_at(nxt)["svg"]) == trace_active(records, nxt)
    driver.find_element("id", "hv-previous").click()
    before = max(f for f in fires if f < nxt)
    assert set(shown_at(before)["svg"]) == trace_active(records, before)
    assert web.kill(signal.SIGTERM) == 0
    assert "Traceback" not in web.err_path.read_text()
    # A trace with variable records (--trace-variables): the variables at the sought instant.
    subprocess.run([sys.executable, str(blinker), "--clock", "virtual", "--until", "12s",
                    "--trace", str(trace), "--trace-variables"], check=True, capture_output=True,
                   timeout=60, stdin=subprocess.DEVNULL)
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    web = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0", "--replay", str(trace),
                     "--model", str(ROOT / BLINKER)], "web")
    url = web.wait_for(WEB_URL + r"\(replay of ", where="out").group(1)
    driver.get(url)
    shown_at(0)
    assert not driver.find_elements("css selector", "#hv-vars tr.hv-hint")
    for t in (3500, 1250, fires[3], fires[3] - 1, 12000):
        driver.execute_script(SEEK_JS, t)
        shown_at(t)
        values = {k: v for r in records if r["ev"] == "variables" and r["t"] <= t
                  for k, v in r["values"].items()}

        def shows(v: dict[str, Any] = values) -> bool:
            return bool(driver.execute_script(VARS_JS) == v)

        assert values and wait_until(shows, 5), \
            (t, values, driver.execute_script(VARS_JS))
        if t == 3500:
            screenshot(driver, "web-replay", tmp_path)
    assert web.kill(signal.SIGTERM) == 0


BIG_JS = r"""
const g = [...document.querySelectorAll('#hv-diagram g.node')];
const fill = (p) => { const e = g.find((x) => x.id === p); const s = e && e.querySelector('ellipse');
                      return s ? getComputedStyle(s).fill : null; };
return {status: document.body.dataset.status,
        nodes: g.filter((x) => /^G\d+\/S\d+$/.test(x.id)).length,
        svg: [...document.querySelectorAll('#hv-diagram g.hv-active')].map((x) => x.id),
        tree: [...document.querySelectorAll('#hv-tree li.hv-active')].map((li) => li.dataset.path),
        fills: [fill(arguments[0]), fill(arguments[1])]};
"""


@needs_browser
def test_a_500_state_model_opens_and_colours_its_active_state(
        logged: Callable[..., Process], browsers: Callable[..., Any], tmp_path: Path) -> None:
    structure = many_states()
    assert len(structure["states"]) == 500
    srv = monitor.MonitorServer(port=0, announce=io.StringIO())
    srv.start(structure)
    try:
        for rec in ({"t": 0, "ev": "start", "name": "many"},
                    {"t": 0, "ev": "enter", "state": "G7"},
                    {"t": 0, "ev": "enter", "state": "G7/S13"}):
            srv.record(rec)
        web = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0",
                         f"127.0.0.1:{srv.port}"], "web")
        url = web.wait_for(WEB_URL, where="out").group(1)
        driver = browsers()
        driver.get(url)

        def state(leaf: str) -> dict[str, Any]:
            s = driver.execute_script(BIG_JS, leaf, "G0/S0")
            assert isinstance(s, dict)
            return s

        def shown(ok: Callable[[dict[str, Any]], bool], leaf: str) -> dict[str, Any]:
            deadline = time.monotonic() + 30
            while not ok(s := state(leaf)):
                assert time.monotonic() < deadline, s
                time.sleep(0.1)
            return s

        s = shown(lambda s: s["status"] == "connected" and s["nodes"] == 480 and
                  s["fills"][0] == GREEN, "G7/S13")
        assert sorted(s["svg"]) == sorted(s["tree"]) == ["G7", "G7/S13"] and s["fills"][1] == WHITE
        for rec in ({"t": 10, "ev": "fire", "from": "G7", "to": "G8", "index": 0},
                    {"t": 10, "ev": "exit", "state": "G7/S13"}, {"t": 10, "ev": "exit", "state": "G7"},
                    {"t": 10, "ev": "enter", "state": "G8"}, {"t": 10, "ev": "enter", "state": "G8/S0"}):
            srv.record(rec)
        s = shown(lambda s: sorted(s["svg"]) == ["G8", "G8/S0"] and s["fills"][0] == GREEN, "G8/S0")
        assert sorted(s["tree"]) == ["G8", "G8/S0"]
        screenshot(driver, "web-500-states", tmp_path)
    finally:
        srv.close()


REGIONS_JS = r"""
const fill = (p) => { const g = [...document.querySelectorAll('#hv-diagram g.node')].find((x) => x.id === p);
                      const e = g && g.querySelector('ellipse'); return e ? getComputedStyle(e).fill : null; };
const svg = document.querySelector('#hv-diagram svg');
const inside = (p) => { const g = [...svg.querySelectorAll('g.node')].find((x) => x.id === p);
  const r = g.getBoundingClientRect(), s = svg.getBoundingClientRect();
  return r.left >= s.left && r.right <= s.right && r.top >= s.top && r.bottom <= s.bottom; };
return {status: document.body.dataset.status,
        svg: [...document.querySelectorAll('#hv-diagram g.hv-active')].map((x) => x.id).sort(),
        tree: [...document.querySelectorAll('#hv-tree li.hv-active')].map((li) => li.dataset.path),
        rows: [...document.querySelectorAll('#hv-tree li')].map((li) => li.textContent.replace(/[0-9.]+ s$/, '')),
        fills: Object.fromEntries(arguments[0].map((p) => [p, fill(p)])),
        inside: arguments[1].map(inside)};
"""


@needs_browser
def test_the_page_lights_every_region_of_a_parallel_state(
        logged: Callable[..., Process], browsers: Callable[..., Any], tmp_path: Path) -> None:
    """Drawn from the structure alone: each region a group in the tree and a cluster in the
    picture, the active state of every region green at once, autofocus keeping them all."""
    srv = monitor.MonitorServer(port=0, announce=io.StringIO())
    srv.start(PARALLEL_STRUCTURE)
    leaves = ["Mission/Nav/A", "Mission/Nav/B", "Mission/Watch/Ok", "Mission/Watch/Seen"]
    try:
        for rec in PARALLEL_RECORDS[:7]:  # at 200 ms: Nav in B, Watch in Ok
            srv.record(rec)
        web = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0",
                         f"127.0.0.1:{srv.port}"], "web")
        url = web.wait_for(WEB_URL, where="out").group(1)
        driver = browsers()
        driver.get(url)

        def shown(ok: Callable[[dict[str, Any]], bool], focus: list[str]) -> dict[str, Any]:
            deadline = time.monotonic() + 30
            while not ok(s := driver.execute_script(REGIONS_JS, leaves, focus)):
                assert time.monotonic() < deadline, s
                time.sleep(0.1)
            assert isinstance(s, dict)
            return s

        lit = ["Mission", "Mission/Nav", "Mission/Nav/B", "Mission/Watch", "Mission/Watch/Ok"]
        s = shown(lambda s: s["status"] == "connected" and s["svg"] == lit, [])
        assert sorted(s["tree"]) == lit
        assert s["fills"] == {"Mission/Nav/A": WHITE, "Mission/Nav/B": GREEN,  # final states are grey
                              "Mission/Watch/Ok": GREEN, "Mission/Watch/Seen": "rgb(200, 200, 200)"}, s
        assert [r.split("open")[0].strip() for r in s["rows"]] == [
            "▾Mission‖ 2 regions", "▾[Nav]100 ms", "A", "B", "▾[Watch]300 ms history", "Ok", "Seen",
            "Done"], s["rows"]
        screenshot(driver, "web-regions", tmp_path)
        # A region folds its states away, as a composite state does.
        rows = [driver.find_element("css selector", f'#hv-tree li[data-path="Mission/Watch/{n}"]')
                for n in ("Ok", "Seen")]
        fold = driver.find_element("css selector", '#hv-tree li[data-path="Mission/Watch"] .hv-fold')
        fold.click()
        assert not any(r.is_displayed() for r in rows) and fold.text == "▸"
        fold.click()
        assert all(r.is_displayed() for r in rows)
        for rec in PARALLEL_RECORDS[7:10]:  # Watch: Ok -> Seen
            srv.record(rec)
        s = shown(lambda s: s["fills"]["Mission/Watch/Seen"] == GREEN, [])
        assert s["fills"]["Mission/Nav/B"] == GREEN and s["fills"]["Mission/Watch/Ok"] == WHITE
        # Zoomed in by hand, then autofocus on: both regions' active states in view again.
        driver.execute_script(GESTURE_JS)
        driver.find_element("id", "hv-autofocus").click()
        s = shown(lambda s: all(s["inside"]), ["Mission/Nav/B", "Mission/Watch/Seen"])
    finally:
        srv.close()


USE_JS = r"""
return {status: document.body.dataset.status,
        tree: [...document.querySelectorAll('#hv-tree li.hv-active')].map((li) => li.dataset.path),
        rows: [...document.querySelectorAll('#hv-tree li')].map((li) => li.textContent.replace(/[0-9.]+ s$/, '')),
        uses: [...document.querySelectorAll('#hv-tree .hv-use')].map((u) => [u.closest('li').dataset.path, u.title]),
        clusters: [...document.querySelectorAll('#hv-diagram g.cluster text')].map((t) => t.textContent)
          .filter((t) => t.includes('.yaml'))};
"""


@needs_browser
def test_the_page_names_the_files_sub_automata_are_used_from(
        logged: Callable[..., Process], browsers: Callable[..., Any], tmp_path: Path) -> None:
    """Drawn from the structure alone: the tree row of a using state and its cluster in the
    picture name the file, a nested use too; the instance's states light as any others."""
    result = compile_file(str(write_used_models(tmp_path)))
    assert result.model is not None, result.diagnostics
    srv = monitor.MonitorServer(port=0, announce=io.StringIO())
    srv.start(structure_of(result.model))
    try:
        for rec in [{"t": 0, "ev": "start", "name": "legs"}, {"t": 0, "ev": "enter", "state": "First"},
                    {"t": 0, "ev": "enter", "state": "First/Climb"},
                    {"t": 200, "ev": "fire", "from": "First/Climb", "to": "First/Hold", "index": 0},
                    {"t": 200, "ev": "exit", "state": "First/Climb"},
                    {"t": 200, "ev": "enter", "state": "First/Hold"},
                    {"t": 200, "ev": "enter", "state": "First/Hold/Wait"}]:
            srv.record(rec)
        web = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0",
                         f"127.0.0.1:{srv.port}"], "web")
        url = web.wait_for(WEB_URL, where="out").group(1)
        driver = browsers()
        driver.get(url)
        deadline = time.monotonic() + 30
        while (s := driver.execute_script(USE_JS))["tree"] != ["First", "First/Hold", "First/Hold/Wait"]:
            assert time.monotonic() < deadline, s
            time.sleep(0.1)
        assert s["status"] == "connected"
        assert [r.split("open")[0].strip() for r in s["rows"]] == [
            "▾First· lib/climb.yaml100 ms", "Climb", "▾Hold· hold.yaml100 ms", "Wait", "Still", "Up",
            "▾Second· lib/climb.yaml100 ms", "Climb", "▾Hold· hold.yaml100 ms", "Wait", "Still", "Up",
            "Done"], s["rows"]
        assert s["uses"][:2] == [["First", "its sub-automaton is used from lib/climb.yaml"],
                                 ["First/Hold", "its sub-automaton is used from hold.yaml"]]
        assert s["clusters"] == ["First · lib/climb.yaml", "Hold · hold.yaml", "Second · lib/climb.yaml",
                                 "Hold · hold.yaml"], s["clusters"]
        screenshot(driver, "web-use", tmp_path)
    finally:
        srv.close()


# -- a C++ component in flight: the picture, the vehicle panel and the camera's frame ----------
FOLLOW_CPP = ROOT / "examples" / "follow_colors_cpp" / "follow_colors_cpp.yaml"
CPP_BUILD_TIMEOUT = 900  # s: CMake and g++ on a loaded 2-core machine take 1-2 min, at times more


@pytest.fixture(scope="module")
def follow_colors_cpp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """examples/follow_colors_cpp compiled once for the module (`hfsmc build -t cpp --compile`)."""
    need_toolchain()
    out = tmp_path_factory.mktemp("follow_colors_cpp") / "component"
    r = subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp", str(FOLLOW_CPP),
                        "-o", str(out), "--compile"], capture_output=True, text=True,
                       timeout=CPP_BUILD_TIMEOUT, stdin=subprocess.DEVNULL, cwd=ROOT)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return out / "build" / "follow_colors_cpp"


FLIGHT_JS = """
const cell = (k) => { const e = document.querySelector('#hv-vehicles tr[data-key="' + k + '"] td');
                      return e ? e.textContent : null; };
const alt = document.querySelector('#hv-vehicles tr[data-key="altitude"] td');
const img = document.querySelector('#hv-cameras figure img');
const filled = (g) => [...g.querySelectorAll('ellipse, polygon')].find((s) => s.getAttribute('fill') !== 'none');
return {
  status: document.body.dataset.status,
  rate: document.getElementById('hv-rate').hidden ? null : document.getElementById('hv-rate').textContent,
  simRate: document.body.dataset.simRate === undefined ? null : Number(document.body.dataset.simRate),
  clock: document.getElementById('hv-clock').textContent,
  panels: [!document.getElementById('hv-vehicles').hidden, !document.getElementById('hv-cameras').hidden],
  altitude: alt && alt.dataset.value ? Number(alt.dataset.value) : null,
  shown: alt ? alt.textContent : null, mode: cell('mode'), armed: cell('armed'),
  frame: img ? [img.naturalWidth, img.naturalHeight] : null,
  svg: [...document.querySelectorAll('#hv-diagram g.hv-active')].map((g) => g.id),
  tree: [...document.querySelectorAll('#hv-tree li.hv-active')].map((li) => li.dataset.path),
  green: [...document.querySelectorAll('#hv-diagram g.node.hv-active')]
    .filter((g) => filled(g) && getComputedStyle(filled(g)).fill === arguments[0]).map((g) => g.id),
};
"""


@needs_browser
@pytest.mark.timeout(CPP_BUILD_TIMEOUT + 240)
def test_the_page_follows_a_cpp_component_in_flight_with_its_vehicle_and_camera(
        follow_colors_cpp: Path, logged: Callable[..., Process], browsers: Callable[..., Any],
        tmp_path: Path) -> None:
    udp, http = free_port(socket.SOCK_DGRAM), free_port()
    config = {"parameters": {"report": str(tmp_path / "report.json")},
              "interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
                             "camera": {"type": "camera",
                                        "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}
    (tmp_path / "config.yaml").write_text(json.dumps(config))
    truth = tmp_path / "truth.json"
    # In lockstep at twice real time (docs/worlds.md#simulated-time): the page says its time is
    # simulated and how fast it runs.
    lockstep = free_port()
    logged([sys.executable, "-m", "hfsmc", "sim", "--world",
               str(ROOT / "examples" / "follow_colors" / "world.yaml"), "--mavlink",
               f"udpout:127.0.0.1:{udp}", "--camera-port", str(http), "--truth", str(truth),
               "--lockstep", str(lockstep), "--speedup", "2"], "sim")
    bad = subprocess.run([str(follow_colors_cpp), "--trace-variables"], capture_output=True,
                         text=True, timeout=30, stdin=subprocess.DEVNULL)
    assert (bad.returncode, bad.stderr) == (
        2, "follow_colors_cpp: --trace-variables needs --trace FILE\n")
    trace = tmp_path / "trace.jsonl"
    comp = logged([str(follow_colors_cpp), "--config", str(tmp_path / "config.yaml"),
                      "--monitor", "0", "--until", "90s", "--trace", str(trace),
                      "--trace-variables", "--clock", f"sim:{lockstep}"], "component")
    port = int(comp.wait_for(r"monitor: listening on 127\.0\.0\.1:(\d+)").group(1))
    web = logged([sys.executable, "-m", "hfsmc", "view", "--web", "0", f"127.0.0.1:{port}",
                     "--model", str(FOLLOW_CPP)], "web")
    url = web.wait_for(WEB_URL, where="out").group(1)
    driver = browsers()
    driver.set_window_size(1280, 900)
    driver.get(url)
    greens: list[str] = []  # the innermost green state, each time it changed
    deadline = time.monotonic() + 60
    while True:
        s = driver.execute_script(FLIGHT_JS, GREEN)
        if s["status"] == "connected" and s["svg"] and sorted(s["svg"]) == sorted(s["tree"]):
            leaf = max(s["green"], key=lambda p: p.count("/"), default=None)
            assert leaf is not None and set(s["green"]) <= set(s["svg"]), s
            if not greens or greens[-1] != leaf:
                greens.append(leaf)
        # Hovering at the mission's 4 m, the camera's frame shown: the mission has begun.
        if s["altitude"] is not None and s["altitude"] > 3.7 and s["frame"] == [320, 240] \
                and any(p.startswith("Mission/") for p in s["svg"]):
            break
        assert time.monotonic() < deadline, (s, greens, comp.err_path.read_text()[-2000:])
        time.sleep(0.1)
    assert s["panels"] == [True, True] and s["mode"] == "GUIDED" and s["armed"] == "ARMED", s
    assert re.fullmatch(r"\d+\.\d\d m", s["shown"] or ""), s  # readable: centimetres
    # The simulator's time, and its rate: never above the speedup but for the measuring.
    assert s["simRate"] is not None and 0 < s["simRate"] <= 2.5, s
    assert s["rate"] == f"simulated, {s['simRate']:.1f}× real time", s
    assert re.fullmatch(r"t \d+\.\d{3} s", s["clock"]), s
    # The green moved with the component's transitions (the page opened before the mission).
    assert len(greens) >= 2 and greens[-1].startswith("Mission/"), greens
    # The panel shows the simulator's altitude (its truth, written every second).
    true_alt = json.loads(truth.read_text())["altitude"]
    assert abs(s["altitude"] - true_alt) < 0.5, (s["altitude"], true_alt)
    screenshot(driver, "web-follow_colors_cpp", tmp_path)
    # The C++ component's variables records (--trace-variables), by the trace's schema.
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    for rec in records:
        MONITOR_VALIDATOR.validate({"type": "record", "record": rec})
    values = [r for r in records if r["ev"] == "variables"]
    assert values[0] == {"t": 0, "ev": "variables",
                         "values": {"seen": "[]", "stages": "[]", "frames": "0"}}, values[:2]
    assert any(r["values"].get("stages") == "['green']" for r in values), values[-3:]
    assert web.kill(signal.SIGTERM) == 0
    assert "Traceback" not in web.err_path.read_text()
