"""The live view: the view model, plain lines, the rich screen, replay, and the
component's --display as a person sees it (run in tmux, read with capture-pane)."""

from __future__ import annotations

import importlib
import io
import json
import re
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from rich.console import Console

from hfsmc.commands.view import view
from hfsmc.emit.structure import structure_of
from hfsmc.pipeline import compile_file
from tests.support import (
    BLINKER,
    GREEN,
    PARALLEL_RECORDS,
    PARALLEL_STRUCTURE,
    PARALLEL_TRACE,
    RECORDS,
    STRUCTURE,
    TRACE,
    USED_STRUCTURE,
    Tmux,
    py,
    write_used_models,
)

# The component's own module, shipped in the data package hfsmc.templates. mypy cannot
# follow the wheel's mapping of hfsmc.templates onto templates/, so it reads the same file
# by its place in the repository.
if TYPE_CHECKING:
    from templates.python import hfsmc_view
    from templates.python.hfsmc_view import Display, PlainLines, ViewState, render
else:
    hfsmc_view = importlib.import_module("hfsmc.templates.python.hfsmc_view")
    Display, PlainLines, ViewState, render = (hfsmc_view.Display, hfsmc_view.PlainLines,
                                              hfsmc_view.ViewState, hfsmc_view.render)

def fed(records: list[dict[str, Any]], structure: dict[str, Any] | None = STRUCTURE) -> ViewState:
    v = ViewState(structure)
    for rec in records:
        v.apply_record(rec)
    return v


def upto(t: int, ev_count: int | None = None) -> list[dict[str, Any]]:
    recs = [r for r in RECORDS if r["t"] <= t]
    return recs if ev_count is None else recs[:ev_count]


# -- ViewState ---------------------------------------------------------------------------
def test_structure_gives_the_tree_in_model_order() -> None:
    v = ViewState(STRUCTURE)
    assert v.name == "blinker"
    assert v.paths() == ["Blinking", "Blinking/Lit", "Blinking/Dark", "Paused", "Done"]
    assert v.children["Blinking"] == ["Blinking/Lit", "Blinking/Dark"]
    assert v.final == {"Done"}
    assert v.periods == {"": 100, "Blinking": 50}
    assert v.history == {"Blinking"}
    assert v.transition_names[("Blinking", 1)] == "pause"
    assert not v.started


def test_records_track_active_states_and_entry_times() -> None:
    v = fed(upto(500))
    assert v.started
    assert v.active == {"Blinking": 0, "Blinking/Dark": 500}
    assert v.innermost() == "Blinking/Dark"
    assert v.t_ms == 500
    v = fed(upto(3000))
    assert v.active == {"Paused": 3000}
    assert [(t["from"], t["to"], t["name"]) for t in v.transitions] == [
        ("Blinking/Lit", "Blinking/Dark", None), ("Blinking", "Paused", "pause")]
    assert list(v.logs) == [{"t": 3000, "state": "Paused", "msg": "paused with the LED off"}]


def test_interrupt_and_stop_keep_the_states_the_stop_left() -> None:
    v = fed(RECORDS)
    assert v.interrupt == {"t": 3200, "reason": "sigint", "to": "Done"}
    assert v.stop_reason == "sigint"
    assert v.active == {}
    assert v.stopped_in == {"Done": 3200}
    v.advance(9000)
    assert v.t_ms == 3200, "a stopped component's clock stays"


def test_stop_of_nested_states_lists_them_outermost_first() -> None:
    recs = [*upto(500), {"t": 900, "ev": "exit", "state": "Blinking/Dark"},
            {"t": 900, "ev": "exit", "state": "Blinking"},
            {"t": 900, "ev": "log", "state": "", "msg": "bye"},
            {"t": 900, "ev": "stop", "reason": "until"}]
    v = fed(recs)
    assert list(v.stopped_in.items()) == [("Blinking", 0), ("Blinking/Dark", 500)]


def test_errors_are_kept_with_the_logs() -> None:
    v = fed([*upto(0), {"t": 50, "ev": "error", "state": "Blinking/Lit", "snippet": "during"}])
    assert list(v.logs) == [{"t": 50, "state": "Blinking/Lit", "error": "during"}]


def test_only_the_last_transitions_are_kept() -> None:
    recs = list(upto(0))
    for k in range(1, 21):
        src, dst = ("Blinking/Lit", "Blinking/Dark") if k % 2 else ("Blinking/Dark", "Blinking/Lit")
        recs += [{"t": 500 * k, "ev": "fire", "from": src, "to": dst, "index": 0},
                 {"t": 500 * k, "ev": "exit", "state": src}, {"t": 500 * k, "ev": "enter", "state": dst}]
    v = fed(recs)
    assert len(v.transitions) == hfsmc_view.RECENT
    assert v.transitions[-1]["t"] == 10_000
    assert v.active == {"Blinking": 0, "Blinking/Lit": 10_000}


def test_samples_give_variables_overruns_and_time() -> None:
    v = fed(upto(500))
    v.apply_sample(740, {"led": "False", "count": "1"}, 3)
    assert (v.values, v.overruns, v.t_ms) == ({"led": "False", "count": "1"}, 3, 740)


def test_a_new_start_resets_the_run() -> None:
    v = fed([*RECORDS, *upto(0)])
    assert v.stop_reason is None and v.interrupt is None
    assert v.active == {"Blinking": 0, "Blinking/Lit": 0}


@pytest.mark.parametrize("t", [0, 500, 3000, 3200])
def test_a_snapshot_gives_a_late_viewer_the_same_view(t: int) -> None:
    source = fed(upto(t))
    source.apply_sample(t, {"led": "True"}, 2)
    late = ViewState(STRUCTURE)
    late.apply_snapshot(json.loads(json.dumps(source.snapshot())))
    for attr in ("active", "values", "overruns", "t_ms", "started", "interrupt", "stop_reason",
                 "stopped_in"):
        assert getattr(late, attr) == getattr(source, attr), attr
    assert list(late.transitions) == list(source.transitions)
    assert list(late.logs) == list(source.logs)


def test_the_tree_is_inferred_from_the_paths_of_a_trace() -> None:
    s = infer = hfsmc_view.infer_structure(RECORDS)
    assert infer["name"] == "blinker"
    assert [(x["path"], x["composite"]) for x in s["states"]] == [
        ("Blinking", True), ("Blinking/Lit", False), ("Blinking/Dark", False),
        ("Paused", False), ("Done", False)]


def test_unknown_paths_are_learned_on_the_way() -> None:
    v = fed([{"t": 0, "ev": "start", "name": "x"}, {"t": 0, "ev": "enter", "state": "A/B/C"}], None)
    assert v.paths() == ["A", "A/B", "A/B/C"]
    assert v.active == {"A/B/C": 0}


@pytest.mark.parametrize(("rec", "why"), [
    ([], "not a JSON object"),
    ({"ev": "start", "name": "x"}, "`t`"),
    ({"t": -1, "ev": "start", "name": "x"}, "`t`"),
    ({"t": True, "ev": "start", "name": "x"}, "`t`"),
    ({"t": 0}, "`ev` is missing"),
    ({"t": 0, "ev": "enter"}, "`enter` record without a string `state`"),
    ({"t": 0, "ev": "fire", "from": "A", "to": "B"}, "`fire` record without an integer `index`"),
    ({"t": 0, "ev": "log", "state": "A", "msg": 3}, "`msg`"),
])
def test_bad_records_are_named(rec: object, why: str) -> None:
    reason = hfsmc_view.check_record(rec)
    assert reason is not None and why in reason


def test_good_records_pass_the_check() -> None:
    assert [hfsmc_view.check_record(r) for r in RECORDS] == [None] * len(RECORDS)


# -- plain lines -------------------------------------------------------------------------
def plain(records: list[dict[str, Any]], focus: str | None = None,
          structure: dict[str, Any] = STRUCTURE) -> list[str]:
    v, p, out = ViewState(structure), PlainLines(focus), []
    for rec in records:
        out += p.lines(v, "record", rec)
        v.apply_record(rec)
    return out


def test_one_plain_line_per_transition_interrupt_and_stop() -> None:
    assert plain(RECORDS) == [
        "  0.000  start blinker in Blinking/Lit",
        "  0.500  Blinking/Lit -> Blinking/Dark",
        "  3.000  Blinking -> Paused  (pause)",
        "  3.200  interrupt (sigint) -> Done",
        "  3.200  stop (sigint)",
    ]


def test_plain_focus_keeps_the_transitions_inside_one_state() -> None:
    lines = plain(RECORDS, focus="Blinking")
    assert "  0.500  Blinking/Lit -> Blinking/Dark" in lines
    assert not any("Blinking -> Paused" in line for line in lines)


def test_the_start_line_names_the_initial_states_before_a_stop() -> None:
    recs = [*upto(0), {"t": 100, "ev": "exit", "state": "Blinking/Lit"},
            {"t": 100, "ev": "exit", "state": "Blinking"}, {"t": 100, "ev": "stop", "reason": "until"}]
    assert plain(recs) == ["  0.000  start blinker in Blinking/Lit", "  0.100  stop (until)"]


def test_control_characters_never_reach_the_terminal() -> None:
    recs = [*upto(0), {"t": 1, "ev": "fire", "from": "Blinking/Lit", "to": "X\x1b[2J", "index": 0}]
    assert plain(recs)[-1] == "  0.001  Blinking/Lit -> X?[2J"


def drive(observer: Any, records: list[dict[str, Any]], samples: bool = True) -> None:
    """Feed an observer the way the runtime does, from one thread."""
    observer.start(STRUCTURE)
    last = 0
    for rec in records:
        if samples and rec["t"] != last:  # between instants, as the runtime samples
            observer.sample(last, {"led": "True", "count": "1", "pauses": "0"}, 0)
            last = rec["t"]
        observer.record(rec)
    observer.close()


def test_display_without_a_terminal_prints_plain_lines() -> None:
    out = io.StringIO()
    t0 = time.monotonic()
    drive(Display(stream=out), RECORDS)
    assert time.monotonic() - t0 < 1.5
    assert out.getvalue().splitlines() == plain(RECORDS)


def test_display_calls_do_not_wait_for_a_blocked_stream() -> None:
    class Stuck(io.StringIO):
        def __init__(self) -> None:
            super().__init__()
            self.release = threading.Event()

        def write(self, s: str) -> int:
            self.release.wait(5)
            return super().write(s)

    stream = Stuck()
    d = Display(stream=stream)
    d.start(STRUCTURE)
    t0 = time.monotonic()
    for _ in range(200):
        for rec in RECORDS[:6]:
            d.record(rec)
    assert time.monotonic() - t0 < 0.5, "observer calls must not block on the terminal"
    stream.release.set()
    d.close()


# -- the rich screen -----------------------------------------------------------------------
def screen(v: ViewState, width: int = 120, color: bool = False, **kw: Any) -> str:
    buffer = io.StringIO()
    console = Console(file=buffer, width=width, force_terminal=color,
                      color_system="standard" if color else None, legacy_windows=False)
    console.print(render(v, width=width, **kw))
    return buffer.getvalue()


def test_screen_shows_active_states_with_time_in_state() -> None:
    v = fed(upto(500))
    v.apply_sample(1250, {"led": "False", "count": "1", "pauses": "0"}, 0)
    text = screen(v)
    assert re.search(r"● Blinking\s+1\.2s", text)
    assert re.search(r"● Dark\s+0\.8s", text)
    assert re.search(r"○ Lit", text)
    assert re.search(r"○ Done\s+final", text)
    assert "1.250 s" in text and "running" in text
    assert re.search(r"count\s+1", text)
    assert "0.500  Blinking/Lit -> Blinking/Dark" in text


def test_on_the_simulators_clock_the_time_says_it_is_simulated_and_its_rate() -> None:
    """--clock sim: samples carry the rate (schemas/monitor.md, minor 2); the time row says
    the time is simulated and how fast it runs; a later sample without a rate keeps it."""
    v = fed(upto(500))
    v.apply_sample(1250, {"led": "False"}, 0)
    assert "simulated" not in screen(v) and v.sim_rate is None
    v.apply_sample(1300, {"led": "False"}, 0, 24.83)
    assert re.search(r"time\s+1\.300 s simulated, 24\.8× real time", screen(v)), screen(v)
    v.apply_sample(1400, {"led": "False"}, 0)
    assert v.sim_rate == 24.83


def test_active_states_are_green() -> None:
    text = screen(fed(upto(500)), color=True)
    assert re.search(GREEN + "● Dark", text), text


def test_autofocus_collapses_inactive_branches() -> None:
    v = fed(upto(3000))
    text = screen(v)
    assert "Lit" not in text.split("╭")[0]  # the tree column holds no Lit
    assert re.search(r"○ Blinking.*▸ 2 states", text)
    assert re.search(r"● Paused", text)
    full = screen(v, autofocus=False)
    assert re.search(r"○ Lit", full) and re.search(r"○ Dark", full)
    assert "off (a: on)" in full


def test_focus_shows_one_sub_automaton() -> None:
    text = screen(fed(upto(500)), focus="Blinking")
    tree = [line for line in text.splitlines() if "Dark" in line or "Lit" in line]
    assert tree
    assert "Paused" not in text.split("recent")[0].split("╭")[0]
    assert "no state Nope" in screen(fed(upto(500)), focus="Nope")


def test_stopped_screen_shows_the_reason_and_the_last_states() -> None:
    text = screen(fed(RECORDS))
    assert "stopped (sigint)" in text
    assert re.search(r"interrupt\s+sigint at 3\.200 s -> Done", text)
    assert re.search(r"■ Done.*at stop", text)
    assert "stopped after 1 blinks" in text


def test_narrow_terminals_stack_the_panel_under_the_tree() -> None:
    lines = screen(fed(upto(500)), width=70).splitlines()
    tree_row = next(i for i, line in enumerate(lines) if "Dark" in line)
    panel_row = next(i for i, line in enumerate(lines) if "time" in line)
    assert panel_row > tree_row


def busy() -> ViewState:
    """A long run: every transition and log line the view keeps, and long values."""
    v = fed(upto(500))
    for k in range(40):
        v.apply_record({"t": 600 + k, "ev": "log", "state": "Blinking/Dark", "msg": f"line {k}"})
        v.apply_record({"t": 600 + k, "ev": "fire", "from": "Blinking/Dark", "to": "Blinking/Lit",
                        "index": 0})
    v.apply_sample(700, {"led": "0.30000000000000004", "count": "[1.2345678, 'x1.2345678']",
                         "pauses": "x" * 200}, 0)
    return v


@pytest.mark.parametrize("width", [80, 120])
def test_the_screen_fits_an_80x24_terminal(width: int) -> None:
    """23 lines at most (the last one is the cursor's), each within the width; the
    history is shortened, and the newest log line, variables and transition stay."""
    lines = screen(busy(), width=width, height=24).splitlines()
    assert len(lines) <= 23, "\n".join(lines)
    assert all(len(line) <= width for line in lines), "\n".join(lines)
    text = "\n".join(lines)
    assert "line 39" in text and "line 32" not in text  # the newest of the 8 kept
    assert re.search(r"0\.639  Blinking/Dark -> Blinking/Lit", text)
    assert re.search(r"led\s+0\.3\s", text) and re.search(r"pauses\s+xxx", text)


def test_floats_are_shown_readable_but_kept_whole() -> None:
    v = busy()
    text = screen(v)
    assert re.search(r"led\s+0\.3\s", text) and "0.30000000000000004" not in text
    assert "[1.23457, 'x1.2345678']" in text
    assert v.values["led"] == "0.30000000000000004"  # what the monitor serves
    assert hfsmc_view.readable("-2.0000000000000004e-05") == "-2e-05"
    assert hfsmc_view.readable("v2.5555555 (1.5, 7)") == "v2.5555555 (1.5, 7)"


def test_the_autofocus_line_says_when_keys_are_not_read() -> None:
    assert "on (a: off)" in screen(fed(upto(500)))
    assert "on (no keys: in the background)" in screen(fed(upto(500)), keys="in the background")
    assert "off (no keys: stdin is not a terminal)" in screen(
        fed(upto(500)), autofocus=False, keys="stdin is not a terminal")


def test_keys_are_not_read_from_a_stdin_that_is_not_a_terminal(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    keys = importlib.import_module("hfsmc.templates.python.hfsmc_terminal").Keys(lambda item: None)
    keys.start()
    assert keys.why == "stdin is not a terminal"
    keys.stop()


# -- replay ----------------------------------------------------------------------------------
@pytest.fixture
def trace_file(tmp_path: Path) -> Path:
    p = tmp_path / "blinker.trace"
    p.write_text(TRACE)
    return p


def test_replay_prints_the_run(trace_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert view(None, str(trace_file), speed=0) == 0
    out, err = capsys.readouterr()
    assert out.splitlines() == [line.replace("  (pause)", "") for line in plain(RECORDS)]
    assert f"replayed {len(RECORDS)} records" in err


def test_replay_with_the_model_names_transitions(trace_file: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    assert view(None, str(trace_file), speed=0, model=BLINKER) == 0
    assert "  3.000  Blinking -> Paused  (pause)" in capsys.readouterr().out


def test_replay_keeps_the_trace_times(trace_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    t0 = time.monotonic()
    assert view(None, str(trace_file), speed=16) == 0  # 3.2 s of trace in 0.2 s
    assert 0.19 < time.monotonic() - t0 < 5
    assert capsys.readouterr().out.splitlines()[-1] == "  3.200  stop (sigint)"


@pytest.mark.parametrize(("text", "message"), [
    ('{"t":0,"ev":"start","name":"b"}\nnot json\n', "blinker.trace:2: bad trace record: Expecting value"),
    ('{"t":0,"ev":"enter"}\n', "blinker.trace:1: bad trace record: `enter` record without a string"),
    ("\n\n", "blinker.trace: no trace records"),
])
def test_bad_traces_are_one_line_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        text: str, message: str) -> None:
    p = tmp_path / "blinker.trace"
    p.write_text(text)
    assert view(None, str(p), speed=0) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("hfsmc: error: ") and message in err and err.count("\n") == 1


@pytest.mark.parametrize(("args", "status", "message"), [
    ((None, "no/such.trace"), 1, "cannot read no/such.trace: No such file or directory"),
    ((None, None), 2, "give either [HOST:]PORT or --replay TRACE"),
    (("1234", "x.trace"), 2, "give either"),
    (("a:b:c", None), 2, "write an IPv6 address in brackets"),
    (("99999", None), 2, "port from 0 to 65535"),
    (("0", None), 2, "port 0"),
])
def test_usage_and_file_errors(capsys: pytest.CaptureFixture[str], args: tuple[str | None, str | None],
                               status: int, message: str) -> None:
    assert view(*args) == status
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_replay_checks_speed_and_focus(trace_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert view(None, str(trace_file), speed=-1) == 2
    assert view(None, str(trace_file), speed=float("nan")) == 2
    assert view(None, str(trace_file), focus="Nope", speed=0) == 2
    assert "--focus Nope: no state" in capsys.readouterr().err


def test_structure_of_a_model_matches_the_runtime_shape() -> None:
    result = compile_file(BLINKER)
    assert result.model is not None
    assert structure_of(result.model) == STRUCTURE


# -- as a person sees it: tmux -----------------------------------------------------------------
@pytest.mark.timeout(60)
def test_component_display_in_a_terminal(tmux: Callable[..., Tmux], blinker: Path,
                                         tmp_path: Path) -> None:
    t = tmux(py(blinker, "--clock", "real", "--until", "6s", "--display"), tmp_path)
    lit = re.compile(GREEN + "● (Lit|Dark)")  # an active leaf
    text = t.wait(lambda s: bool(lit.search(s)), colors=True)
    assert re.search(GREEN + "● Blinking", text)
    plain_text = t.screen()
    assert re.search(r"● (Lit|Dark)\s+\d\.\ds", plain_text), plain_text
    assert "○ Paused" in plain_text and "○ Done" in plain_text and "overruns" in plain_text
    # While paused (3 s to 4 s), autofocus folds the blinking branch; the log line of
    # Paused's entry is printed above the tree, not across it.
    text = t.wait(lambda s: "● Paused" in s)
    assert re.search(r"○ Blinking.*▸ 2 states", text)
    assert "Paused: paused with the LED" in text.splitlines()[0]
    text = t.wait(lambda s: "EXIT=0" in s)
    assert "stopped (until)" in text and "at stop" in text


@pytest.mark.timeout(60)
def test_component_display_without_rich_prints_lines_and_one_notice(
        tmux: Callable[..., Tmux], blinker: Path, tmp_path: Path) -> None:
    code = ("import runpy, sys; sys.modules['rich'] = None; sys.argv = sys.argv[1:]; "
            "runpy.run_path(sys.argv[0], run_name='__main__')")
    t = tmux(py("-c", code, blinker, "--clock", "virtual", "--until", "4s", "--display"), tmp_path)
    text = t.wait(lambda s: "EXIT=" in s)
    assert "EXIT=0" in text
    assert text.count("rich package is not installed") == 1
    assert "  0.500  Blinking/Lit -> Blinking/Dark" in text
    assert "  3.000  Blinking -> Paused  (pause)" in text
    assert "  4.000  stop (until)" in text


@pytest.mark.timeout(60)
def test_replay_in_a_terminal_toggles_autofocus_and_quits(tmux: Callable[..., Tmux],
                                                        tmp_path: Path) -> None:
    long = TRACE.replace('"t":3200', '"t":2400000')  # paused for ten minutes at --speed 4
    (tmp_path / "long.trace").write_text(long)
    stty = "stty -a | tr ' ;' '\\n\\n' | grep -x -e -icanon -e icanon -e echo -e -echo | tr '\\n' ' '"
    t = tmux(py("-m", "hfsmc", "view", "--replay", "long.trace", "--speed", "4"), tmp_path, stty)
    text = t.wait(lambda s: "● Paused" in s)
    assert re.search(r"○ Blinking.*▸ 2 states", text) and "○ Lit" not in text
    t.keys("a")
    text = t.wait(lambda s: "○ Lit" in s)
    assert "○ Dark" in text and "off (a: on)" in text
    t.keys("q")
    # stty prints after EXIT=: wait for its line too, not only for the exit.
    text = t.wait(lambda s: "EXIT=" in s and re.search(r"-?icanon -?echo", s) is not None)
    assert "EXIT=0" in text
    assert "icanon echo" in text, "the terminal is back in line mode with echo"


# -- regions ---------------------------------------------------------------------------------
def par_upto(t: int) -> ViewState:
    return fed([r for r in PARALLEL_RECORDS if r["t"] <= t], PARALLEL_STRUCTURE)


def test_regions_are_nodes_of_the_tree_under_their_state() -> None:
    v = ViewState(PARALLEL_STRUCTURE)
    assert v.children["Mission"] == ["Mission/Nav", "Mission/Watch"]
    assert v.regions == {"Mission/Nav", "Mission/Watch"}
    assert v.periods == {"": 100, "Mission/Nav": 100, "Mission/Watch": 300}
    assert v.history == {"Mission/Watch"}
    v = par_upto(200)
    assert v.leaves() == ["Mission/Nav/B", "Mission/Watch/Ok"]  # model order, not entry order
    assert v.lit("Mission/Watch") and not v.lit("Mission/Watch/Seen")
    assert v.owner("Mission/Watch/Ok") == "Mission" and v.owner("Mission") == ""


def test_the_screen_shows_each_region_as_a_named_group_all_lit_at_once() -> None:
    text = screen(par_upto(900), width=120)
    tree = [line[:34].rstrip() for line in text.splitlines()[:9]]
    assert tree == ["par  100 ms",
                    "├── ● Mission ‖  0.9s",
                    "│   ├── [Nav 100 ms]",
                    "│   │   ├── ○ A",
                    "│   │   └── ● B  0.7s  final",
                    "│   └── [Watch 300 ms history]",
                    "│       ├── ○ Ok",
                    "│       └── ● Seen  0.0s  final",
                    "└── ○ Done  final"], text
    colored = screen(par_upto(900), color=True)
    assert re.search(GREEN + "● B", colored) and re.search(GREEN + "● Seen", colored)
    assert re.search(GREEN + r"\[Nav 100 ms\]", colored)


def test_autofocus_folds_a_parallel_state_and_focus_takes_a_state_or_a_region() -> None:
    v = par_upto(1000)
    assert re.search(r"○ Mission ‖\s+▸ 2 regions", screen(v))
    assert "[Nav" in screen(v, autofocus=False)
    v = par_upto(200)
    mission = "\n".join(line[:34] for line in screen(v, focus="Mission").splitlines())
    assert "[Nav 100 ms]" in mission and "[Watch 300 ms history]" in mission and "Done" not in mission
    watch = [line[:30].rstrip() for line in screen(v, focus="/Mission/Watch/").splitlines()[:3]]
    assert watch == ["[Watch 300 ms history]", "├── ● Ok  0.2s", "└── ○ Seen  final"]
    assert plain(PARALLEL_RECORDS, focus="Mission/Watch", structure=PARALLEL_STRUCTURE) == [
        "  0.000  start par in Mission/Nav/A, Mission/Watch/Ok",
        "  0.900  Mission/Watch/Ok -> Mission/Watch/Seen  (seen)",
        "  1.000  stop (final)"]


def test_regions_are_inferred_from_a_trace_and_survive_a_snapshot() -> None:
    s = hfsmc_view.infer_structure(PARALLEL_RECORDS)
    assert [(a["owner"], a["region"], a["initial"]) for a in s["automata"]] == [
        ("Mission", "Nav", "A"), ("Mission", "Watch", "Ok")]
    assert "Mission/Nav" not in [st["path"] for st in s["states"]]
    v = ViewState(s)
    assert v.children["Mission"] == ["Mission/Nav", "Mission/Watch"] and not v.periods
    source = par_upto(900)
    late = ViewState(PARALLEL_STRUCTURE)
    late.apply_snapshot(json.loads(json.dumps(source.snapshot())))
    assert late.active == source.active
    assert hfsmc_view.PlainLines().lines(late, "snapshot", source.snapshot()) == [
        "  0.900  in Mission/Nav/B, Mission/Watch/Seen"]


SLOW_PAR = """\
hfsm: 1
name: slowpar
period: 100ms
variables: {n: 0}
initial: Mission
states:
  Mission:
    regions:
      Navigate:
        period: 50ms
        initial: A
        states:
          A: {transitions: [{to: B, after: 600ms}]}
          B: {transitions: [{to: C, after: 600ms}]}
          C: {final: true}
      Watch:
        period: 200ms
        initial: Ok
        history: true
        states:
          Ok: {during: "n += 1", transitions: [{to: Seen, when: n >= 10}]}
          Seen: {final: true}
    transitions: [{to: Done, when: done()}]
  Done: {final: true}
"""


@pytest.mark.timeout(90)
def test_component_display_of_regions_in_a_terminal(tmux: Callable[..., Tmux], tmp_path: Path) -> None:
    """A real component with two regions: both regions' active states green at once, then
    --focus on a region shows that region alone."""
    (tmp_path / "slowpar.yaml").write_text(SLOW_PAR)
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "slowpar.yaml", "-o", "out"], cwd=tmp_path,
                   check=True, capture_output=True, timeout=120, stdin=subprocess.DEVNULL)
    main = tmp_path / "out" / "slowpar.py"
    t = tmux(py(main, "--clock", "real", "--until", "4s", "--display"), tmp_path)
    text = t.wait(lambda s: bool(re.search(GREEN + "● B", s)), colors=True)
    assert re.search(GREEN + "● Ok", text) and re.search(GREEN + r"\[Watch 200 ms history\]", text)
    tree = [line[:31].rstrip() for line in t.screen().splitlines()[:9]]
    assert [re.sub(r"\d\.\ds", "_", line) for line in tree] == [
        "slowpar  100 ms", "├── ● Mission ‖  _", "│   ├── [Navigate 50 ms]", "│   │   ├── ○ A",
        "│   │   ├── ● B  _", "│   │   └── ○ C  final", "│   └── [Watch 200 ms history]",
        "│       ├── ● Ok  _", "│       └── ○ Seen  final"], tree
    text = t.wait(lambda s: "EXIT=0" in s)
    assert re.search(r"○ Mission ‖\s+▸ 2 regions", text) and "stopped (final)" in text
    done = subprocess.run([sys.executable, str(main), "--until", "5s", "--display", "--focus", "/Mission/Watch/"],
                          capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["  0.000  start slowpar in Mission/Navigate/A, Mission/Watch/Ok",
                                        "  2.000  Mission/Watch/Ok -> Mission/Watch/Seen",
                                        "  2.100  stop (final)"]


def test_replay_of_a_trace_with_regions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Without the model the regions are inferred from the trace; --focus takes a region."""
    trace = tmp_path / "par.trace"
    trace.write_text(PARALLEL_TRACE)
    assert view(None, str(trace), focus="Mission/Watch", speed=0) == 0
    assert capsys.readouterr().out.splitlines() == [
        "  0.000  start par in Mission/Nav/A, Mission/Watch/Ok",
        "  0.900  Mission/Watch/Ok -> Mission/Watch/Seen",
        "  1.000  stop (final)"]
    assert view(None, str(trace), focus="Mission/Wat", speed=0) == 2
    assert "--focus Mission/Wat: no state of that path" in capsys.readouterr().err


# -- sub-automata used from other files --------------------------------------------------------
def test_a_state_names_the_file_its_sub_automaton_is_used_from(tmp_path: Path) -> None:
    """From the model (hfsmc view --model) as from a component's structure: the file as the
    using model writes it, on the state's line, whether it is active, left at a stop or not."""
    result = compile_file(str(write_used_models(tmp_path)))
    assert result.model is not None, result.diagnostics
    v = ViewState(structure_of(result.model))
    assert v.uses == {"First": "lib/climb.yaml", "First/Hold": "hold.yaml",
                      "Second": "lib/climb.yaml", "Second/Hold": "hold.yaml"}
    for rec in [{"t": 0, "ev": "start", "name": "legs"}, {"t": 0, "ev": "enter", "state": "First"},
                {"t": 200, "ev": "enter", "state": "First/Hold"},
                {"t": 200, "ev": "enter", "state": "First/Hold/Wait"}]:
        v.apply_record(rec)
    v.advance(500)
    tree = [line[:50].rstrip() for line in screen(v).splitlines()[:9]]
    assert tree == ["legs  100 ms",
                    "├── ● First · lib/climb.yaml  0.5s  100 ms",
                    "│   ├── ○ Climb",
                    "│   ├── ● Hold · hold.yaml  0.3s  100 ms",
                    "│   │   ├── ● Wait  0.3s",
                    "│   │   └── ○ Still  final",
                    "│   └── ○ Up  final",
                    "├── ○ Second · lib/climb.yaml  100 ms  ▸ 3 states",
                    "└── ○ Done  final"], tree
    assert screen(v, focus="First/Hold").startswith("● Hold · hold.yaml  0.3s  100 ms ")
    stopped = fed(upto(500), USED_STRUCTURE)
    stopped.apply_record({"t": 600, "ev": "exit", "state": "Blinking/Dark"})
    stopped.apply_record({"t": 600, "ev": "exit", "state": "Blinking"})
    stopped.apply_record({"t": 600, "ev": "stop", "reason": "sigint"})
    assert "■ Blinking · lib/blink.yaml  0.6s, at stop  50 ms history" in screen(stopped)
    colored = screen(fed(upto(500), USED_STRUCTURE), color=True)
    assert re.search(r"● Blinking\x1b\[0m\x1b\[(?:[0-9;]*;)?2(?:;[0-9;]*)?m · lib/blink\.yaml", colored), \
        "the file is dim"


@pytest.mark.timeout(90)
def test_component_display_of_used_files_in_a_terminal(tmux: Callable[..., Tmux], tmp_path: Path) -> None:
    """A real component using one file twice, that file using another: each using state's
    line names its file, the instances' states below it, paths through them in the panel."""
    write_used_models(tmp_path)
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "legs.yaml", "-o", "out"], cwd=tmp_path,
                   check=True, capture_output=True, timeout=120, stdin=subprocess.DEVNULL)
    t = tmux(py(tmp_path / "out" / "legs.py", "--clock", "real", "--display"), tmp_path)
    text = t.wait(lambda s: bool(re.search(GREEN + "● Hold", s)), colors=True)
    assert re.search(GREEN + "● First", text), text
    tree = [re.sub(r"\d\.\ds", "_", line[:50].rstrip()) for line in t.screen().splitlines()[:9]]
    assert tree == ["legs  100 ms",
                    "├── ● First · lib/climb.yaml  _  100 ms",
                    "│   ├── ○ Climb",
                    "│   ├── ● Hold · hold.yaml  _  100 ms",
                    "│   │   ├── ● Wait  _",
                    "│   │   └── ○ Still  final",
                    "│   └── ○ Up  final",
                    "├── ○ Second · lib/climb.yaml  100 ms  ▸ 3 states",
                    "└── ○ Done  final"], tree
    assert "0.200  First/Climb -> First/Hold" in t.screen()
    text = t.wait(lambda s: "EXIT=0" in s)
    assert "○ Second · lib/climb.yaml  100 ms  ▸ 3 states" in text and "stopped (final)" in text
