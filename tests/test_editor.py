"""`hfsmc edit` (docs/editor.md): the page in Debian's chromium on a copy of follow_colors,
driven as a person would (double-click, F2, Del, drags, typing in CodeMirror, Ctrl+Z/S),
the file's bytes checked after each save; the server's refusals in plain HTTP; the
whitelist of operations in-process."""

from __future__ import annotations

import difflib
import http.client
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hfsmc.edit.text import EditError
from hfsmc.editor.server import BadRequest, Editor
from tests.support import ROOT, Process, hfsmc, needs_browser, screenshot, wait_until

EDIT_URL = r"on (http://127\.0\.0\.1:(\d+)/\?token=([\w-]+)) "


@pytest.fixture
def model(tmp_path: Path) -> Path:
    """A copy of follow_colors with the library it uses, beside it as in examples/."""
    shutil.copytree(ROOT / "examples/follow_colors", tmp_path / "m/follow_colors",
                    ignore=shutil.ignore_patterns("*.mcap", "tests"))
    shutil.copytree(ROOT / "examples/lib", tmp_path / "m/lib")
    return tmp_path / "m/follow_colors/follow_colors.yaml"


class Server:
    def __init__(self, logged: Callable[..., Process], path: Path) -> None:
        self.p = logged([sys.executable, "-m", "hfsmc", "edit", str(path), "--web", "0"], "edit")
        m = self.p.wait_for(EDIT_URL, where="out", timeout=30)
        self.url, self.port, self.token = m[1], int(m[2]), m[3]

    def ask(self, path: str, headers: dict[str, str] | None = None,
            host: str | None = None) -> tuple[int, Any]:
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=10)
        try:
            conn.request("GET", path, headers={"Host": host or f"127.0.0.1:{self.port}",
                                               **(headers or {})})
            r = conn.getresponse()
            if r.status != 101:
                r.read()
            return r.status, r.headers
        finally:
            conn.close()


@pytest.fixture
def server(logged: Callable[..., Process], model: Path) -> Server:
    return Server(logged, model)


class Page:
    """The editor's page in a browser."""

    def __init__(self, driver: Any, url: str, shots: Path) -> None:
        self.d, self.shots = driver, shots
        driver.get(url)
        self.until(lambda: driver.execute_script("return document.body.dataset.ready === '1'"))

    def until(self, what: Callable[[], object], timeout: float = 15) -> None:
        if not wait_until(what, timeout):
            self.shot("editor-failed")
            raise AssertionError("the page did not get there (editor-failed.png shows it)")

    def css(self, selector: str) -> list[Any]:
        from selenium.webdriver.common.by import By

        return list(self.d.find_elements(By.CSS_SELECTOR, selector))

    def has(self, selector: str) -> bool:
        return bool(self.css(selector))

    def state(self, path: str) -> Any:
        return self.css(f'g.state[data-path="{path}"] rect.body')[0]

    def keys(self, *keys: str) -> None:
        from selenium.webdriver.common.action_chains import ActionChains

        chain = ActionChains(self.d)
        for k in keys:
            chain.send_keys(k)
        chain.perform()

    def chord(self, key: str) -> None:
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.keys import Keys

        ActionChains(self.d).key_down(Keys.CONTROL).send_keys(key).key_up(Keys.CONTROL).perform()

    def shot(self, name: str) -> None:
        screenshot(self.d, name, self.shots)

    def problems(self) -> list[str]:
        return list(self.d.execute_script(
            "return [...document.querySelectorAll('#problems li')].map(li => li.textContent)"))

    def status(self) -> str:
        return str(self.css("#status")[0].text)


def changed_lines(before: str, after: str) -> list[str]:
    """The lines of ``before`` that ``after`` removed or replaced."""
    return [line[1:] for line in difflib.unified_diff(before.splitlines(), after.splitlines(),
                                                      lineterm="", n=0)
            if line.startswith("-") and not line.startswith("---")]


@needs_browser
def test_edit_in_the_page(server: Server, model: Path, browsers: Callable[..., Any],
                          tmp_path: Path) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    original = model.read_bytes()
    page = Page(browsers(), server.url, tmp_path)
    assert page.has('g.state[data-path="Mission"].composite')
    page.shot("editor-open")

    # a state: double-click on the empty canvas, name it
    canvas = page.css("#canvas")[0]
    ActionChains(page.d).move_to_element_with_offset(canvas, 250, 150).double_click().perform()
    page.until(lambda: page.css("#inline")[0].is_displayed())
    page.keys("Extra", Keys.ENTER)
    page.until(lambda: page.has('g.state[data-path="Extra"]'))
    assert "unsaved" in page.status()
    # F2 renames it
    page.state("Extra").click()
    page.keys(Keys.F2)
    page.until(lambda: page.css("#inline")[0].is_displayed())
    page.keys("Spare", Keys.ENTER)
    page.until(lambda: page.has('g.state[data-path="Spare"]'))
    assert not page.has('g.state[data-path="Extra"]')

    # a transition: drag from Spare's handle onto Done
    handle = page.css('g.state[data-path="Spare"] circle.handle')[0]
    ActionChains(page.d).click_and_hold(handle).move_by_offset(10, 10) \
        .move_to_element(page.state("Done")).release().perform()
    page.until(lambda: page.has('g.edge[data-state="Spare"]'))

    # its condition with a typo: E141 on the arrow and in the list; fixed, gone
    page.css('g.edge[data-state="Spare"] text')[0].click()
    page.until(lambda: page.has('.field[data-field="when"] .cm-content'))
    page.css('.field[data-field="when"] .cm-content')[0].click()
    page.keys("blobb('red')")
    # a transition needs a condition (E137) until one is typed; then the typo's E141
    page.until(lambda: any("E141" in p and "blobb" in p for p in page.problems()))
    assert page.has('g.edge.error[data-state="Spare"]')
    assert "E141" in page.css('g.edge[data-state="Spare"] title')[0].get_attribute("textContent")
    page.shot("editor-typo")
    page.css('.field[data-field="when"] .cm-content')[0].click()
    page.chord("a")
    page.keys("bool(blob('red'))")
    page.until(lambda: page.has('g.edge[data-state="Spare"]') and
               not page.has('g.edge.error[data-state="Spare"]'))
    assert not any("E141" in p for p in page.problems())

    # delete the transition, then the state (Del)
    page.css('g.edge[data-state="Spare"] text')[0].click()
    page.d.execute_script("document.activeElement.blur()")
    page.keys(Keys.DELETE)
    page.until(lambda: not page.has('g.edge[data-state="Spare"]'))
    page.state("Spare").click()
    page.keys(Keys.DELETE)
    page.until(lambda: not page.has('g.state[data-path="Spare"]'))

    # undo everything: the text is the file's again, byte for byte (a save writes nothing)
    page.until(lambda: page.css("#undo")[0].is_enabled())
    for _ in range(40):
        if not page.css("#undo")[0].is_enabled():
            break
        page.chord("z")
        time.sleep(0.15)
    page.until(lambda: page.status() == "saved")
    page.chord("s")
    page.until(lambda: "saved follow_colors.yaml" in page.css("#message")[0].text)
    assert model.read_bytes() == original
    # redo comes back too
    page.chord("y")
    page.until(lambda: page.has('g.state[data-path="Extra"]'))
    page.css("#undo")[0].click()
    page.until(lambda: page.status() == "saved")

    # into a composite and back
    ActionChains(page.d).double_click(page.state("Mission")).perform()
    page.until(lambda: page.has('g.state[data-path="Mission/FollowGreen"]'))
    assert [a.text for a in page.css("#crumbs a")] == ["follow_colors", "Mission"]
    page.shot("editor-mission")
    page.css("#up")[0].click()
    page.until(lambda: page.has('g.state[data-path="Mission"]'))

    # the tree: Mission folded hides its subtree, unfolded shows it; a search shows only
    # the states whose path matches, and Enter opens the first one's automaton
    shown = '#tree span[data-path="Mission/FollowBlue/Lost"]'
    assert page.has(shown)
    page.css('#tree b.fold[data-fold="Mission"]')[0].click()
    page.until(lambda: not page.has(shown))
    page.css('#tree b.fold[data-fold="Mission"]')[0].click()
    page.until(lambda: page.has(shown))
    page.css("#search")[0].send_keys("followblu")
    page.until(lambda: [e.text for e in page.css("#tree span:not(.hidden)")] ==
               ["FollowBlue", "Track", "Lost"])
    page.css("#search")[0].send_keys(Keys.ENTER)
    page.until(lambda: page.has('g.state.selected[data-path="Mission/FollowBlue"]'))
    page.css("#search")[0].clear()
    page.css("#up")[0].click()
    page.until(lambda: page.has('g.state[data-path="Mission"]'))

    # a rename saved: only the lines naming it change, and the model checks clean
    page.state("LinkLost").click()
    page.keys(Keys.F2)
    page.until(lambda: page.css("#inline")[0].is_displayed())
    page.keys("LinkDown", Keys.ENTER)
    page.until(lambda: page.has('g.state[data-path="LinkDown"]'))
    page.chord("s")
    page.until(lambda: page.status() == "saved")
    after = model.read_text()
    removed = changed_lines(original.decode(), after)
    assert removed and all("LinkLost" in line for line in removed), removed
    # the state's key and `to:` renamed, nothing else (the comments that mention it stay)
    assert after.replace("LinkDown", "LinkLost") == original.decode()
    assert after.count("LinkDown") == 2
    done = hfsmc("check", str(model))
    assert done.returncode == 0, done.stdout + done.stderr

    # a state dragged: the layout file beside the model, the model unchanged
    saved = model.read_bytes()
    ActionChains(page.d).click_and_hold(page.state("Done")).move_by_offset(120, 40) \
        .release().perform()
    layout = model.with_name("follow_colors.layout.yaml")
    page.until(lambda: layout.exists() and "Done:" in layout.read_text())
    assert model.read_bytes() == saved
    page.shot("editor-saved")


@needs_browser
def test_conflict_from_disk(server: Server, model: Path, browsers: Callable[..., Any],
                            tmp_path: Path) -> None:
    from selenium.webdriver.common.keys import Keys

    page = Page(browsers(), server.url, tmp_path)
    page.css("#canvas")[0].click()
    page.keys("n")  # a state from the keyboard
    page.until(lambda: page.css("#inline")[0].is_displayed())
    page.keys("Mine", Keys.ENTER)
    page.until(lambda: page.has('g.state[data-path="Mine"]'))
    theirs = model.read_text() + "# their edit\n"
    model.write_text(theirs)
    page.until(lambda: page.css("#conflict")[0].is_displayed())
    page.chord("s")
    page.until(lambda: "not saved: follow_colors.yaml changed on disk"
               in page.css("#message")[0].text)
    assert model.read_text() == theirs  # never overwritten
    page.shot("editor-conflict")
    page.css("#reload")[0].click()
    page.until(lambda: not page.css("#conflict")[0].is_displayed() and page.status() == "saved")
    assert not page.has('g.state[data-path="Mine"]')
    # unsaved: with nothing unsaved, a change on disk is simply taken
    model.write_text(theirs.replace("LinkLost", "LinkGone"))
    page.until(lambda: page.has('g.state[data-path="LinkGone"]'))


def test_who_it_answers(server: Server) -> None:
    status, headers = server.ask("/")
    assert status == 403  # no token
    status, headers = server.ask(f"/?token={server.token}", host="evil.example")
    assert status == 403  # DNS rebinding
    status, headers = server.ask(f"/?token={'x' * 43}")
    assert status == 403
    status, headers = server.ask(f"/?token={server.token}")
    assert status == 303 and "HttpOnly" in headers["Set-Cookie"]
    cookie = {"Cookie": f"hfsmc-view-{server.port}={server.token}"}
    status, headers = server.ask("/", cookie)
    assert status == 200
    csp = headers["Content-Security-Policy"]
    assert "unsafe-eval" not in csp and "script-src 'self'" in csp
    ws = {**cookie, "Upgrade": "websocket", "Connection": "Upgrade",
          "Sec-WebSocket-Version": "13", "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="}
    assert server.ask("/ws", {**ws, "Origin": "http://127.0.0.1:1"})[0] == 403
    assert server.ask("/ws", {**ws, "Origin": "null"})[0] == 403
    assert server.ask("/ws", {k: v for k, v in ws.items() if k != "Cookie"})[0] == 403
    assert server.ask("/ws", {**ws, "Origin": f"http://127.0.0.1:{server.port}"})[0] == 101
    assert server.ask("/vendor/codemirror.js", cookie)[0] == 200
    assert server.ask("/../follow_colors.yaml", cookie)[0] == 404


def test_operations_are_a_whitelist(model: Path, tmp_path: Path) -> None:
    editor = Editor(model)
    for bad in ({"op": "__init__"}, {"op": "save_as", "args": {"path": "/tmp/x"}},
                {"op": "set_state_field", "args": {"state": "Done", "key": "use",
                                                   "value": "/etc/passwd"}},
                {"op": "set_transition_field", "args": {"state": "Land", "index": 0,
                                                        "key": "with", "value": "x"}},
                {"op": "rename", "args": {"path": "Done", "new": 3}},
                {"op": "move", "args": {"state": "Done", "x": float("nan"), "y": 1}}):
        with pytest.raises(BadRequest):
            editor.handle(bad)
    with pytest.raises(EditError, match="not a valid state name"):
        editor.handle({"op": "rename", "args": {"path": "Done", "new": "a b"}})
    assert editor.session.text == model.read_text()
    xml = tmp_path / "traffic_light.xml"
    shutil.copy(ROOT / "examples/traffic_light/traffic_light.xml", xml)
    with pytest.raises(EditError, match="read-only"):
        Editor(xml).handle({"op": "add_state", "args": {"parent": "", "name": "X"}})


def test_bad_command_lines(tmp_path: Path) -> None:
    done = hfsmc("edit", str(tmp_path / "missing.yaml"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "no such model file" in done.stderr
    done = hfsmc("edit", str(ROOT / "examples/follow_colors/follow_colors.yaml"), "--web", "x:y")
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "--web" in done.stderr
