"""`hfsmc edit`'s live side (docs/editor.md) in Debian's chromium: the --monitor overlay
against a running blinker, Build and run of a copy of blinker with its log and Stop, a
condition's typo in the code editor's gutter at its line, a C++ snippet's missing `;` at
save; the new page files behind the token, Host and Origin rules; the live operations
refused or taken in-process."""

from __future__ import annotations

import asyncio
import io
import os
import shutil
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hfsmc.edit.text import EditError
from hfsmc.editor.build import Run
from hfsmc.editor.server import Editor
from tests.support import ROOT, Process, build_blinker, free_port, hfsmc, needs_browser, wait_until
from tests.test_editor import EDIT_URL, Page, Server

BLINKER = ROOT / "examples/blinker/blinker.yaml"


def copy_of(tmp_path: Path, src: Path) -> Path:
    folder = tmp_path / "m"
    folder.mkdir(exist_ok=True)
    shutil.copy(src, folder / src.name)
    return folder / src.name


def editor(logged: Callable[..., Process], path: Path, *more: str) -> Server:
    server = Server.__new__(Server)
    server.p = logged([sys.executable, "-m", "hfsmc", "edit", str(path), "--web", "0", *more],
                      "edit")
    m = server.p.wait_for(EDIT_URL, where="out", timeout=30)
    server.url, server.port, server.token = m[1], int(m[2]), m[3]
    return server


def lit(page: Page) -> list[str]:
    return list(page.d.execute_script(
        "return [...document.querySelectorAll('g.state.active')].map(g => g.dataset.path)"))


def tree_lit(page: Page) -> list[str]:
    return list(page.d.execute_script(
        "return [...document.querySelectorAll('#tree span.active')].map(s => s.dataset.path)"))


def live_text(page: Page) -> str:
    return str(page.d.execute_script("return document.getElementById('live-text').textContent"))


def log_text(page: Page) -> str:
    return str(page.d.execute_script("return document.getElementById('runlog').textContent"))


def stop_editor(server: Server) -> None:
    """Ctrl+C: the editor ends what it started."""
    server.p.proc.send_signal(signal.SIGINT)
    assert server.p.proc.wait(20) == 0


@needs_browser
def test_overlay_lights_the_running_blinker(logged: Callable[..., Process],
                                            browsers: Callable[..., Any], tmp_path: Path) -> None:
    main = build_blinker(tmp_path / "component")
    port = free_port()
    component = logged([sys.executable, str(main), "--monitor", str(port), "--param",
                        "blinks=1000"], "blinker")
    component.wait_for(r"monitor: listening on 127\.0\.0\.1:\d+")
    model = copy_of(tmp_path, BLINKER)
    server = editor(logged, model, "--monitor", str(port))
    page = Page(browsers(), server.url, tmp_path)
    page.d.find_element("css selector", 'g.state[data-path="Blinking"] rect.body')
    # the root canvas: Blinking lit while it blinks (or Paused, every 3 s)
    page.until(lambda: lit(page) in (["Blinking"], ["Paused"]))
    assert "Editing is paused" in live_text(page)
    page.shot("live-root")
    page.d.execute_script("open('Blinking')")
    seen: set[str] = set()

    def both() -> bool:
        seen.update(lit(page))
        return {"Blinking/Lit", "Blinking/Dark"} <= seen
    page.until(both, timeout=20)  # Lit and Dark in turn
    assert set(tree_lit(page)) & {"Blinking/Lit", "Blinking/Dark"}
    page.shot("live-blinking")
    # editing is paused: an edit is refused with the reason, the file untouched
    before = model.read_bytes()
    page.d.execute_script("send('add_state', {parent: 'Blinking', name: 'Spare'})")
    page.until(lambda: "editing is paused" in page.css("#message")[0].text)
    assert "Blinking/Spare" not in page.d.execute_script("return Object.keys(model.states)")
    # the component gone is said plainly, nothing lit
    component.kill(signal.SIGKILL)
    page.until(lambda: "is gone" in live_text(page) and not lit(page))
    page.shot("live-gone")
    # Resume editing drops the overlay; an edit is taken again
    page.css("#live-resume")[0].click()
    page.until(lambda: page.d.execute_script("return !document.body.classList.contains('paused')"))
    page.d.execute_script("send('add_state', {parent: 'Blinking', name: 'Spare'})")
    page.until(lambda: "Blinking/Spare" in page.d.execute_script(
        "return Object.keys(model.states)"))
    assert model.read_bytes() == before  # not saved: only the page's text changed
    page.shot("live-resumed")
    stop_editor(server)


@needs_browser
def test_build_and_run_from_the_page(logged: Callable[..., Process],
                                     browsers: Callable[..., Any], tmp_path: Path) -> None:
    model = copy_of(tmp_path, BLINKER)
    model.write_text(model.read_text().replace("blinks: {type: int, default: 10}",
                                               "blinks: {type: int, default: 1000}"))
    server = editor(logged, model)
    page = Page(browsers(), server.url, tmp_path)
    # unsaved edits: not run
    page.d.execute_script("send('add_state', {parent: '', name: 'Spare'})")
    page.until(lambda: page.status() == "unsaved")
    page.css("#run")[0].click()
    page.until(lambda: "save first" in page.css("#message")[0].text)
    page.d.execute_script("send('undo')")
    page.until(lambda: page.status() == "saved")
    page.css("#run")[0].click()
    page.until(lambda: "monitor: listening on 127.0.0.1:" in log_text(page), timeout=60)
    page.until(lambda: lit(page) in (["Blinking"], ["Paused"]), timeout=30)
    assert page.css("#run")[0].get_attribute("disabled")  # one run at a time
    page.d.execute_script("send('run_start')")
    page.until(lambda: "a run is on already" in page.css("#message")[0].text)
    page.until(lambda: "paused with the LED" in log_text(page), timeout=20)  # its log() lines
    page.shot("run-running")
    page.css("#stop")[0].click()
    page.until(lambda: "the run ended" in log_text(page), timeout=20)
    assert "stopped after" in log_text(page)  # on_shutdown ran: stopped as on Ctrl+C
    assert not page.css("#stop")[0].is_enabled()
    page.shot("run-stopped")
    # a second run, ended by the editor's own end
    page.css("#run")[0].click()
    page.until(lambda: "monitor: listening" in log_text(page), timeout=60)
    pid = int(page.d.execute_script(
        "return /\\(pid (\\d+)\\)/.exec(document.getElementById('runlog').textContent)[1]"))
    stop_editor(server)
    assert wait_until(lambda: not Path(f"/proc/{pid}").exists() or
                      "zombie" in Path(f"/proc/{pid}/status").read_text().lower(), 10)


@needs_browser
def test_a_typo_in_the_gutter_at_its_line(logged: Callable[..., Process],
                                          browsers: Callable[..., Any], tmp_path: Path) -> None:
    model = copy_of(tmp_path, BLINKER)
    server = editor(logged, model)
    page = Page(browsers(), server.url, tmp_path)
    page.d.execute_script("open('Blinking'); select({kind: 'state', path: 'Blinking/Lit'})")
    page.until(lambda: page.has('.field[data-field="entry"] .cm-content'))
    entry = page.css('.field[data-field="entry"] .cm-content')[0]
    entry.click()
    from selenium.webdriver.common.keys import Keys
    page.chord(Keys.END)
    page.keys("x = countt + 1")  # line 3 of the snippet
    marker = '.field[data-field="entry"] .cm-lint-marker-error'
    page.until(lambda: page.has(marker))
    where = page.d.execute_script(f"""
        const lines = [...document.querySelectorAll('.field[data-field="entry"] .cm-line')];
        const range = document.querySelector('.field[data-field="entry"] .cm-lintRange-error');
        const g = document.querySelector('{marker}').closest('.cm-gutterElement').getBoundingClientRect();
        const mid = g.top + g.height / 2;
        return [lines.indexOf(range.closest('.cm-line')) + 1, range.textContent,
                lines.findIndex(l => {{ const q = l.getBoundingClientRect();
                                       return q.top <= mid && mid <= q.bottom; }}) + 1,
                lines.map(l => l.textContent)];""")
    assert where[:3] == [3, "countt + 1", 3], where
    assert page.has('.field[data-field="entry"] .cm-lintRange-error')
    page.shot("gutter-typo")
    page.keys(Keys.BACKSPACE * 10, "count + 1")
    page.until(lambda: not page.has(marker))
    page.shot("gutter-fixed")
    stop_editor(server)


@needs_browser
def test_a_cpp_missing_semicolon_shown_at_save(logged: Callable[..., Process],
                                               browsers: Callable[..., Any],
                                               tmp_path: Path) -> None:
    model = copy_of(tmp_path, ROOT / "examples/blinker_cpp/blinker_cpp.yaml")
    server = editor(logged, model)
    page = Page(browsers(), server.url, tmp_path)
    page.d.execute_script("open('Blinking'); select({kind: 'state', path: 'Blinking/Dark'})")
    page.until(lambda: page.has('.field[data-field="entry"] .cm-content'))
    page.css('.field[data-field="entry"] .cm-content')[0].click()
    from selenium.webdriver.common.keys import Keys
    page.keys(Keys.END, Keys.BACKSPACE)  # `led = false;` loses its `;`
    page.until(lambda: page.status() == "unsaved")
    time.sleep(0.5)  # the debounce: the page's text sent
    assert not any("E144" in p for p in page.problems())  # g++ runs at save only
    page.chord("s")
    page.until(lambda: any("E144" in p and "expected ';'" in p for p in page.problems()),
               timeout=120)
    page.until(lambda: page.has('.field[data-field="entry"] .cm-lint-marker-error'))
    assert page.has('g.state.error[data-path="Blinking/Dark"]')
    assert "led = false\n" in model.read_text()
    page.shot("cpp-missing-semicolon")
    stop_editor(server)


def test_new_files_behind_the_trust_rules(logged: Callable[..., Process], tmp_path: Path) -> None:
    """The live side adds two files and no route: both behind the token, Host and Origin
    rules; its operations come on the WebSocket those rules guard."""
    server = editor(logged, copy_of(tmp_path, BLINKER))
    cookie = {"Cookie": f"hfsmc-view-{server.port}={server.token}"}
    for name in ("editor_live.js", "editor_live.css"):
        assert server.ask(f"/{name}")[0] == 403  # no token, no cookie
        assert server.ask(f"/{name}", {"Cookie": f"hfsmc-view-{server.port}={'x' * 43}"})[0] == 403
        assert server.ask(f"/{name}", cookie, host="evil.example")[0] == 403  # DNS rebinding
        status, headers = server.ask(f"/{name}", cookie)
        assert status == 200 and "unsafe-eval" not in headers["Content-Security-Policy"]
    ws = {**cookie, "Upgrade": "websocket", "Connection": "Upgrade",
          "Sec-WebSocket-Version": "13", "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="}
    assert server.ask("/ws", {**ws, "Origin": "http://127.0.0.1:1"})[0] == 403
    assert server.ask("/ws", {**ws, "Origin": "null"})[0] == 403
    assert server.ask("/ws", {**ws, "Origin": f"http://127.0.0.1:{server.port}"},
                      host="evil.example")[0] == 403
    assert server.ask("/ws", {**ws, "Origin": f"http://127.0.0.1:{server.port}"})[0] == 101
    stop_editor(server)


def test_live_operations_in_process(tmp_path: Path) -> None:
    model = copy_of(tmp_path, BLINKER)

    async def scenario() -> None:
        told: list[dict[str, Any]] = []
        ed = Editor(model, ("127.0.0.1", free_port()))

        async def tell(msg: dict[str, Any]) -> None:
            told.append(msg)
        ed.live._tell = tell
        assert await ed.live.handle("live_watch", True, False) is None
        assert ed.live.paused and told[-1]["on"] is True
        for op in ({"op": "add_state", "args": {"parent": "", "name": "X"}},
                   {"op": "move", "args": {"state": "Done", "x": 1, "y": 1}}, {"op": "undo"}):
            with pytest.raises(EditError, match="editing is paused"):
                ed.handle(op)
        assert ed.handle({"op": "save"}) == "saved blinker.yaml"  # nothing lost meanwhile
        await asyncio.sleep(0.3)  # nobody listens there: the component is gone
        assert told[-1]["status"] == "connecting" and told[-1]["active"] == []
        assert await ed.live.handle("run_stop", True, False) == "no run to stop"
        assert await ed.live.handle("run_start", True, True) == \
            "not run: the file changed on disk (Reload first)"
        assert "save first" in str(await ed.live.handle("run_start", False, False))
        assert await ed.live.handle("live_resume", True, False) == "editing resumed"
        assert not ed.live.paused
        ed.handle({"op": "add_state", "args": {"parent": "", "name": "X"}})
        await ed.live.close()

    asyncio.run(scenario())


def test_bad_monitor_arguments(tmp_path: Path) -> None:
    model = copy_of(tmp_path, BLINKER)
    for bad, said in (("nope:x", "--monitor: "), ("0", "port 0 is not a component's port")):
        r = hfsmc("edit", str(model), "--monitor", bad)
        assert r.returncode in (1, 2) and said in r.stderr and "Traceback" not in r.stderr


SLOW_LANDING = """\
hfsm: 1
name: slow
description: Flies until asked to stop, then lands for LANDING.
on_interrupt: Landing
period: 50ms
initial: Flying
states:
  Flying:
    during: pass
  Landing:
    transitions:
      - {to: Down, after: LANDING}
  Down:
    final: true
"""


@pytest.mark.parametrize(("landing", "second_ctrl_c"), [("2s", False), ("60s", True)])
def test_the_editor_waits_for_its_runs_landing(tmp_path: Path, landing: str,
                                               second_ctrl_c: bool) -> None:
    """The editor stopping ends its run as Ctrl+C ends `hfsmc run`: the run's on_interrupt
    is waited for (a landing is never cut short) and said; only a second Ctrl+C kills it,
    with the warning that a vehicle may be left armed."""
    model = tmp_path / "slow.yaml"
    model.write_text(SLOW_LANDING.replace("LANDING", landing))

    async def go() -> tuple[str, int | None, list[str]]:
        lines: list[str] = []
        monitor = asyncio.Event()

        async def on_lines(got: list[dict[str, Any]]) -> None:
            lines.extend(x["text"] for x in got)

        async def on_monitor(_host: str, _port: int) -> None:
            monitor.set()

        async def on_end(_status: int) -> None:
            return None

        run = Run(model, on_lines, on_monitor, on_end)
        await run.start()
        await asyncio.wait_for(monitor.wait(), 60)
        await asyncio.sleep(1.0)  # flying: its instants run (the announcement comes first)
        log = io.StringIO()
        closing = asyncio.ensure_future(run.close(log))
        for _ in range(400):
            if "waiting for the run" in log.getvalue() or closing.done():
                break
            await asyncio.sleep(0.05)
        assert "Ctrl+C again kills it" in log.getvalue(), (log.getvalue(), lines[-6:], run.status)
        assert run.running  # still landing: not killed
        if second_ctrl_c:
            os.kill(os.getpid(), signal.SIGINT)  # the editor's second Ctrl+C (its loop's)
        await asyncio.wait_for(closing, 60)
        return log.getvalue(), run.status, lines

    said, status, lines = asyncio.run(go())
    if second_ctrl_c:
        assert status == -signal.SIGKILL
        assert "run killed (SIGKILL): a vehicle it drove may still be armed" in said
    else:
        assert status == 130, lines  # landed: on_interrupt reached its final state
        assert "killed" not in said
