"""`hfsmc edit`'s forms, copy and paste, lanes, keys and tabs (docs/editor.md): in Debian's
chromium on copies of follow_colors and regions_arm, each edit's lines checked in the saved
file and everything undone back to the original bytes; the forms' whitelist and the tabs'
confinement in-process."""

from __future__ import annotations

import difflib
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hfsmc.edit.text import EditError
from hfsmc.editor import tabs
from hfsmc.editor.server import Editor
from tests.support import ROOT, Process, needs_browser, wait_until
from tests.test_editor import Page, Server


def copy_of(tmp_path: Path, example: str) -> Path:
    shutil.copytree(ROOT / "examples" / example, tmp_path / "m" / example,
                    ignore=shutil.ignore_patterns("*.mcap", "tests"))
    shutil.copytree(ROOT / "examples/lib", tmp_path / "m/lib")
    return tmp_path / "m" / example / f"{example}.yaml"


def diff(before: str, after: str) -> tuple[list[str], list[str]]:
    """The lines ``after`` removed from ``before``, and those it added."""
    lines = list(difflib.unified_diff(before.splitlines(), after.splitlines(), lineterm="", n=0))
    return ([x[1:] for x in lines if x.startswith("-") and not x.startswith("---")],
            [x[1:] for x in lines if x.startswith("+") and not x.startswith("+++")])


def check(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hfsmc", "check", str(path)], capture_output=True,
                          text=True, timeout=120)


class Forms(Page):
    def field(self, selector: str, value: str) -> None:
        from selenium.webdriver.common.keys import Keys

        box = self.css(selector)[0]
        box.click()
        box.send_keys(Keys.CONTROL, "a")
        box.send_keys(value, Keys.ENTER)

    def save(self, path: Path, before: bytes) -> None:
        self.chord("s")
        self.until(lambda: path.read_bytes() != before and self.status() == "saved")

    def selected(self) -> str | None:
        path = self.d.execute_script("return sel && sel.kind === 'state' ? sel.path : null")
        return None if path is None else str(path)

    def blank(self) -> None:
        """A click on the empty canvas: nothing selected, the forms shown."""
        from selenium.webdriver.common.action_chains import ActionChains

        canvas = self.css("#canvas")[0]
        ActionChains(self.d).move_to_element_with_offset(canvas, 300, 180).click().perform()
        self.until(lambda: self.has("#forms"))


@pytest.fixture
def follow(tmp_path: Path) -> Path:
    return copy_of(tmp_path, "follow_colors")


def undo_everything(page: Forms) -> None:
    from selenium.webdriver.common.keys import Keys

    page.keys(Keys.ESCAPE)  # out of a form's field: the canvas has the keys
    for _ in range(200):
        if not page.d.execute_script("return model.can_undo"):
            return
        page.chord("z")
        wait_until(lambda: False, 0.05)
    raise AssertionError("undo never ran out")


@needs_browser
def test_forms_copy_paste_keys_and_tabs(logged: Callable[..., Process], follow: Path,
                                        browsers: Callable[..., Any], tmp_path: Path) -> None:
    from selenium.webdriver.common.keys import Keys

    server = Server(logged, follow)
    original = follow.read_bytes()
    driver = browsers()
    driver.execute_cdp_cmd("Browser.grantPermissions", {
        "origin": f"http://127.0.0.1:{server.port}",
        "permissions": ["clipboardReadWrite", "clipboardSanitizedWrite"]})
    page = Forms(driver, server.url, tmp_path)
    page.until(lambda: page.has("#forms"))

    # the forms: a variable's value and the timer's period; only their lines change
    page.field('tr[data-decl="variable:frames"] input[data-key="init"]', "5")
    page.until(lambda: "unsaved" in page.status())
    page.field('#forms input[data-setting="period"]', "40ms")
    page.until(lambda: page.d.execute_script("return model.settings.automata[''].period") == "40ms")
    page.shot("forms-edited")
    page.save(follow, original)
    removed, added = diff(original.decode(), follow.read_text())
    assert removed == ["  frames: 0", "period: 50ms"]
    assert added == ["  frames: 5", "period: 40ms"]
    saved = follow.read_bytes()

    # a parameter added and a wrong value refused in one line
    page.blank()
    add = 'tr[data-add="parameter"] input[data-key="%s"]'
    page.css(add % "name")[0].send_keys("speed")
    page.css(add % "type")[0].send_keys("float")
    page.css(add % "default")[0].send_keys("1.5", Keys.ENTER)
    page.until(lambda: page.has('tr[data-decl="parameter:speed"]'))
    page.field('tr[data-decl="parameter:speed"] input[data-key="default"]', "fast")
    page.until(lambda: "`fast` is not a float" in page.css("#message")[0].text)

    # copy a state: its YAML on the system clipboard; paste it: LinkLost2, its arrows said
    page.state("LinkLost").click()
    page.chord("c")
    page.until(lambda: page.d.execute_script("return document.body.dataset.copied") == "LinkLost")
    clip = page.d.execute_async_script(
        "const done = arguments[0]; navigator.clipboard.readText().then(done, (e) => done('!' + e))")
    assert clip.startswith("LinkLost:\n  entry: log(f\"link lost"), clip
    assert "to: Mission" in clip and "the link never came back" in clip
    page.blank()
    page.chord("v")
    page.until(lambda: page.has('g.state[data-path="LinkLost2"]'))
    said = page.css("#message")[0].text
    assert "pasted `LinkLost2`" in said and "Mission, Done" in said
    page.shot("pasted")

    # the keyboard only: into LinkLost2 (Tab selects, Enter enters), two states (N), an
    # arrow between them (A, type its target, Enter), its condition (E, type, Escape)
    page.blank()
    for _ in range(12):
        if page.selected() == "LinkLost2":
            break
        page.keys(Keys.TAB)
    assert page.selected() == "LinkLost2"
    page.keys(Keys.ENTER)
    page.until(lambda: page.d.execute_script("return cur") == "LinkLost2")
    layout = follow.with_name("follow_colors.layout.yaml")  # each new state's place, written
    for name in ("Wait", "Go"):
        page.keys("n")
        page.until(lambda: page.css("#inline")[0].is_displayed())
        page.keys(name, Keys.ENTER)
        path = f"LinkLost2/{name}"
        page.until(lambda: page.has(f'g.state[data-path="{path}"]'))  # noqa: B023
        page.until(lambda: layout.exists() and f"{path}:" in layout.read_text())  # noqa: B023
    page.until(lambda: page.d.execute_script(  # Go drawn where N put it: below Wait
        "return model.positions['LinkLost2/Go'][1] > model.positions['LinkLost2/Wait'][1] + 50"))
    page.keys(Keys.ARROW_UP)
    page.until(lambda: page.selected() == "LinkLost2/Wait")
    page.keys("a")
    page.until(lambda: page.has("#rubber"))
    page.keys("g")
    page.until(lambda: page.has('g.state.target[data-path="LinkLost2/Go"]'))
    page.shot("keyboard-arrow-aimed")
    page.keys(Keys.ENTER)
    page.until(lambda: page.has('g.edge[data-state="LinkLost2/Wait"]'))
    page.keys("e")
    page.until(lambda: page.d.execute_script(
        "return !!document.activeElement.closest('[data-field=\"when\"]')"))
    page.keys("elapsed() > 1")
    page.keys(Keys.ESCAPE)
    page.until(lambda: page.d.execute_script(
        "return (model.states['LinkLost2/Wait'].transitions[0] || {}).when") == "elapsed() > 1")
    page.shot("keyboard-automaton")
    # and an arrow to it from LinkLost, also from the keys, so that it is reachable
    page.keys(Keys.BACKSPACE)
    page.until(lambda: page.d.execute_script("return cur") == "")
    for _ in range(12):
        if page.selected() == "LinkLost":
            break
        page.keys(Keys.TAB)
    page.keys("a", "linklost2")
    page.until(lambda: page.has('g.state.target[data-path="LinkLost2"]'))
    page.keys(Keys.ENTER)
    page.until(lambda: len(page.d.execute_script("return model.states.LinkLost.transitions")) == 3)
    page.keys("e", "now() > 1e9", Keys.ESCAPE)
    page.until(lambda: page.d.execute_script(
        "return model.states.LinkLost.transitions[2].when") == "now() > 1e9")
    before = follow.read_bytes()
    page.save(follow, before)
    text = follow.read_text()
    assert "initial: Wait" in text and "to: Go" in text and "when: elapsed() > 1" in text
    done = check(follow)
    assert done.returncode == 0 and "warning" not in done.stdout + done.stderr, \
        done.stdout + done.stderr

    # a used file in its own tab
    first = driver.current_window_handle
    page.state("TakeOff").click()
    page.keys(Keys.ENTER)
    page.until(lambda: len(driver.window_handles) == 2)
    driver.switch_to.window(next(w for w in driver.window_handles if w != first))
    page.until(lambda: driver.execute_script(
        "return document.body.dataset.ready === '1' && model.file") == "takeoff.yaml")
    assert driver.execute_script("return model.tab") == "../lib/takeoff.yaml"
    page.shot("used-file-tab")
    driver.close()
    driver.switch_to.window(first)

    # every edit undone: the original bytes again
    undo_everything(page)
    page.save(follow, follow.read_bytes())
    assert follow.read_bytes() == original
    assert saved != original


@needs_browser
def test_regions_as_lanes(logged: Callable[..., Process], tmp_path: Path,
                          browsers: Callable[..., Any]) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    model = copy_of(tmp_path, "regions_arm")
    original = model.read_bytes()
    server = Server(logged, model)
    page = Forms(browsers(), server.url, tmp_path)
    ActionChains(page.d).double_click(page.state("Working")).perform()
    page.until(lambda: len(page.css("g.state.lane")) == 3)
    lanes = [g.get_attribute("data-path") for g in page.css("g.state.lane")]
    assert lanes == ["Working/Cycle", "Working/Led", "Working/Battery"]
    assert page.has('g.lane g.chip[data-path="Working/Cycle/Parked"].final')
    page.shot("lanes")

    # a region added (R); its lane drawn
    page.blank()
    page.keys("r")
    page.until(lambda: page.css("#inline")[0].is_displayed())
    page.keys("Fan", Keys.ENTER)
    page.until(lambda: len(page.css("g.state.lane")) == 4)
    page.shot("lanes-region-added")

    # into a lane: the region's period in the timer form
    ActionChains(page.d).double_click(page.css('g.state.lane[data-path="Working/Led"] rect.body')[0]).perform()
    page.until(lambda: page.d.execute_script("return cur") == "Working/Led")
    page.blank()
    page.field('#forms input[data-setting="period"]', "500ms")
    page.until(lambda: page.d.execute_script(
        "return model.settings.automata['Working/Led'].period") == "500ms")
    page.save(model, original)
    removed, added = diff(original.decode(), model.read_text())
    assert removed == ["        period: 250ms"]
    assert added[0] == "        period: 500ms" and "      Fan:" in added

    undo_everything(page)
    page.save(model, model.read_bytes())
    assert model.read_bytes() == original


def test_forms_operations_are_checked(follow: Path) -> None:
    editor = Editor(follow)
    for op, args, said in [
        ("set_setting", {"key": "states", "value": "x"}, "not a setting"),
        ("set_declaration", {"kind": "variable", "name": "frames", "key": "states", "value": "1"},
         "not a field"),
        ("add_declaration", {"kind": "states", "name": "x"}, "no kind of declaration"),
        ("set_declaration", {"kind": "parameter", "name": "altitude", "key": "default",
                             "value": "high"}, "not a float"),
        ("add_declaration", {"kind": "variable", "name": "not a name", "value": "1"}, "not a valid"),
        ("set_automaton", {"state": "Mission", "key": "states", "value": "x"}, "not a field"),
        ("add_region", {"state": "", "name": "R"}, "the root has states"),
        ("delete_import", {"index": 9}, "no import number 10"),
        ("paste", {"parent": "", "text": "a: [b"}, "not YAML"),
        ("paste", {"parent": "TakeOff", "text": "X: {}"}, "its own tab"),
    ]:
        with pytest.raises(EditError, match=said):
            editor.handle({"op": op, "args": args})
    assert editor.session.text == follow.read_text()
    editor.handle({"op": "set_declaration", "args": {"kind": "variable", "name": "frames",
                                                     "key": "type", "value": "int"}})
    assert "  frames: {type: int, init: 0}\n" in editor.session.text


def test_tabs_open_only_the_files_the_model_uses(follow: Path) -> None:
    editor = Editor(follow)
    assert set(tabs.allowed(editor)) == {"../lib/takeoff.yaml", "../lib/land.yaml"}
    for key in ("../lib/hold.yaml", "follow_colors.yaml/../../lib/hold.yaml", "/etc/passwd",
                "../lib/../lib/takeoff.yaml"):
        with pytest.raises(ValueError, match="not a file"):
            tabs.pick(editor, key, Editor)
    assert tabs.pick(editor, "", Editor) is editor
