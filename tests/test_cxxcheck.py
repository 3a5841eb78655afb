"""`hfsmc check` of C++ models: g++ -fsyntax-only at model positions, and the checks of
C++ and Python snippets that need no compiler (goto, active() paths, done()).

The g++ runs share the session's cache (conftest.py): small models with no
interfaces, so they share one precompiled header of the runtime.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from hfsmc import cxxcheck
from hfsmc.cli import main
from hfsmc.cppcompile import messages
from hfsmc.cppsnippets import tokens
from hfsmc.errors import Diagnostic
from hfsmc.pipeline import compile_file

# Each snippet misses its last `;`, or ends early: g++ sees it only at the generated
# `}` or `)` after the snippet, and hfsmc places it at the end of the snippet's last line.
ENDS = """\
hfsm: 1
name: ends
language: cpp
variables:
  count: 0
initial: A
states:
  A:
    entry: count = 1
    during: |
      count += 1;
      count = count * 2
    transitions:
      - to: B
        when: count >
        do: log("to B")
  B: {final: true}
"""

FUNCTIONS = """\
hfsm: 1
name: funcs
language: cpp
functions: |
  int twice(int x) { return 2 * x; }
  int limit = 3
initial: A
states:
  A: {final: true}
"""

TYPO = """\
hfsm: 1
name: typo
language: cpp
variables:
  count: 0
initial: A
states:
  A:
    entry: |
      count = 1;
      cuont += 2;
    during: int unused = 0;
    transitions: [{to: B, after: 1s}]
  B: {final: true}
"""


def write(tmp_path: Path, name: str, text: str) -> str:
    path = tmp_path / name
    path.write_text(text, "utf-8")
    return str(path)


def found(diags: list[Diagnostic], code: str) -> list[str]:
    """``FILE:LINE:COL`` of each diagnostic with that code."""
    return [str(d.span) for d in diags if d.code == code]


# ---------------------------------------------------------------------------
# g++'s messages on generated lines next to a snippet (no g++ needed)

GENERATED = """\
#define HFSMC_SOURCE "src/m.cpp"
    void _hfsm_s1() {
        try {
#line 9 "m.yaml"
           count = 1
#line 7 HFSMC_SOURCE
        } catch (...) {
        }
    }
    bool _hfsm_s2() {
        try {
            return static_cast<bool>(
#line 15 "m.yaml"
              count >  // a comment
#line 16 HFSMC_SOURCE
            );
        } catch (...) {
"""


def test_messages_on_generated_lines_go_to_the_snippet_they_close() -> None:
    out = ("/abs/comp/src/m.cpp:7:9: error: expected ';' before '}' token\n"
           "src/m.cpp:16:13: error: expected primary-expression before ')' token\n"
           "src/m.cpp:12:20: error: invalid 'static_cast' from type 'void' to type 'bool'\n"
           "/usr/include/c++/12/bits/stl_algo.h: In instantiation of 'void std::__sort()':\n"
           "m.yaml:9:12:   required from here\n"
           "/usr/include/c++/12/bits/stl_algo.h:1950:50: error: no match for 'operator-'\n"
           "<stdin>:18:1: error: a follow-up error outside every snippet\n")
    diags = messages(out, "m.yaml", [GENERATED])
    assert [(str(d.span), d.code, d.message) for d in diags] == [
        ("m.yaml:9:21", "E144", "expected ';' before '}' token"),  # after `count = 1`
        ("m.yaml:15:22", "E144", "expected primary-expression before ')' token"),
        ("m.yaml:15:15", "E144", "invalid 'static_cast' from type 'void' to type 'bool'"),
        ("m.yaml:9:12", "E144", "no match for 'operator-'"),
    ]  # the follow-up error is left out: the model's errors explain it
    alone = messages("src/m.cpp:18:1: error: broken generator\n", "m.yaml", [GENERATED])
    assert [(str(d.span), d.code) for d in alone] == [("m.yaml:1:1", "E150")]


HEADER = """\
#define HFSMC_HEADER "src/m.hpp"
class A {
    // Functions (m.yaml:5 functions).
#line 5 "m.yaml"
  int f() { return 1;
#line 7 HFSMC_HEADER
};
"""


def test_messages_in_the_class_header_go_to_the_model_too() -> None:
    """The class (src/NAME.hpp, `functions` in it) and the snippets' unit (src/NAME.cpp): a
    message on either file's generated lines is placed by that file's lines."""
    out = ("/abs/comp/src/m.hpp:7:2: error: expected '}' at end of input\n"
           "src/m.cpp:7:9: error: expected ';' before '}' token\n")
    diags = messages(out, "m.yaml", [HEADER, GENERATED])
    assert [(str(d.span), d.code) for d in diags] == [("m.yaml:5:22", "E144"),
                                                      ("m.yaml:9:21", "E144")]
    # Without the header's text its line is no snippet's: left out, as a consequence of the
    # error placed in the model.
    alone = messages(out, "m.yaml", [GENERATED])
    assert [(str(d.span), d.code) for d in alone] == [("m.yaml:9:21", "E144")]


def test_a_legacy_interface_used_in_cpp_is_explained() -> None:
    out = "m.yaml:9:12: error: base operand of '->' has non-pointer type 'hfsmc::Unavailable'\n"
    [d] = messages(out, "m.yaml", [GENERATED])
    assert (str(d.span), d.code) == ("m.yaml:9:12", "E144")
    assert any("legacy ROS topic or ICE proxy" in n for n in d.notes)


# ---------------------------------------------------------------------------
# g++ at `hfsmc check`


def test_missing_semicolon_at_the_end_of_a_snippet_is_at_its_last_line(tmp_path: Path) -> None:
    path = write(tmp_path, "ends.yaml", ENDS)
    r = compile_file(path, cxx=True)
    # entry (after `count = 1`), during's last line, when (after `count >`), do
    assert found(r.diagnostics, "E144") == [f"{path}:9:21", f"{path}:12:24", f"{path}:15:22",
                                            f"{path}:16:24"], r.diagnostics
    assert not found(r.diagnostics, "E150")
    assert r.model is None and not r.ok


def test_missing_semicolon_at_the_end_of_functions(tmp_path: Path) -> None:
    path = write(tmp_path, "funcs.yaml", FUNCTIONS)
    r = compile_file(path, cxx=True)
    assert [(d.code, str(d.span)) for d in r.diagnostics] == [("E144", f"{path}:6:16")]


USED = """\
hfsm: 1
name: climb
language: cpp
parameters: {step: {type: float, default: 0.5}}
variables: {height: 0.0}
initial: Climb
states:
  Climb:
    during: height += stepp;
    transitions: [{to: Up, when: height > 1.0}]
  Up: {final: true}
"""
USING = """\
hfsm: 1
name: twice
language: cpp
initial: A
states:
  A:
    use: lib/climb.yaml
    transitions: [{to: B, when: done()}]
  B:
    use: lib/climb.yaml
    with: {step: 1}
    transitions: [{to: C, when: done()}]
  C: {final: true}
"""


def test_a_compiler_error_in_a_used_file_is_at_its_line_there(tmp_path: Path) -> None:
    (tmp_path / "lib").mkdir()
    used = write(tmp_path / "lib", "climb.yaml", USED)
    path = write(tmp_path, "twice.yaml", USING)
    r = compile_file(path, cxx=True)
    assert [(d.code, str(d.span), d.notes[-1]) for d in r.diagnostics] == [
        ("E144", f"{used}:9:23", f"used from {path}:7:10, {path}:10:10")], r.diagnostics
    assert r.model is None


def test_check_compiles_cpp_snippets_and_no_cxx_skips_it(tmp_path: Path) -> None:
    path = write(tmp_path, "typo.yaml", TYPO)
    r = CliRunner().invoke(main, ["check", path])
    assert r.exit_code == 1, r.output
    assert f"{path}:11:7: error[E144]: 'cuont' was not declared in this scope" in r.stderr
    assert "      cuont += 2;\n        ^" in r.stderr  # the model's line and the caret
    assert f"{path}:12:17: warning[W209]: unused variable 'unused' [-Wunused-variable]" in r.stderr
    skipped = CliRunner().invoke(main, ["check", "--no-cxx", path])
    assert skipped.exit_code == 0 and skipped.stderr == "", skipped.output


def test_warm_check_reads_the_cache_not_gxx(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write(tmp_path, "typo.yaml", TYPO)
    cold = compile_file(path, cxx=True).diagnostics
    real = cxxcheck._run

    def no_compile(cmd: list[str], stdin: str) -> tuple[int, str]:
        assert "-fsyntax-only" not in cmd and "c++-header" not in cmd, cmd
        return real(cmd, stdin)

    monkeypatch.setattr(cxxcheck, "_run", no_compile)
    assert compile_file(path, cxx=True).diagnostics == cold
    assert found(cold, "E144") == [f"{path}:11:7"]


def test_a_missing_compiler_is_a_note_not_an_error(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-g++"))
    path = write(tmp_path, "typo.yaml", TYPO)
    r = CliRunner().invoke(main, ["check", path])
    assert r.exit_code == 0, r.output
    assert r.stderr == (f"hfsmc: note: {path}: CXX names {tmp_path / 'no-such-g++'}, which is not "
                        "found: C++ snippets are compiled only by `hfsmc build --compile` "
                        "(`make deps` installs g++)\n")
    monkeypatch.setenv("PATH", str(tmp_path))  # no g++ on the PATH
    monkeypatch.delenv("CXX")
    r = CliRunner().invoke(main, ["check", path])
    assert r.exit_code == 0, r.output
    assert r.stderr.startswith(f"hfsmc: note: {path}: g++ is not installed: "), r.stderr


def test_a_cache_that_cannot_be_written_only_costs_time(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "file").write_text("not a folder")
    monkeypatch.setenv("HFSMC_CACHE_DIR", str(tmp_path / "file"))
    path = write(tmp_path, "typo.yaml", TYPO)
    r = compile_file(path, cxx=True)
    assert found(r.diagnostics, "E144") == [f"{path}:11:7"] and not r.notes


def test_a_value_the_cpp_component_cannot_hold_is_found_by_check(tmp_path: Path) -> None:
    path = write(tmp_path, "lst.yaml", "hfsm: 1\nname: lst\nlanguage: cpp\nvariables:\n"
                 "  xs: [1, 2]\ninitial: A\nstates:\n  A: {final: true}\n")
    r = compile_file(path, cxx=True)
    assert [(d.code, str(d.span)) for d in r.diagnostics] == [("E150", f"{path}:5:3")]


def test_concurrent_cold_checks_share_one_header_set(tmp_path: Path) -> None:
    """Two checks on an empty cache at once: both right, one header set, no debris."""
    cache = tmp_path / "cache"
    path = write(tmp_path, "typo.yaml", TYPO)
    env = {**os.environ, "HFSMC_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "hfsmc", "check", path]
    procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    try:
        outs = [p.communicate(timeout=240) for p in procs]
    finally:
        for p in procs:
            p.kill()
            p.wait()
    for p, (_out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 1, err
        assert f"{path}:11:7: error[E144]" in err, err
    sets = [q for q in (cache / "pch").iterdir() if not q.name.endswith(".lock")]
    assert len(sets) == 1 and not sets[0].name.startswith("."), sets
    assert (sets[0] / "pch.hpp").is_file() and (sets[0] / "include/hfsmc/runtime.hpp").is_file()
    assert not [q for q in sets[0].iterdir() if q.name.startswith(".")]
    assert [q.name for q in (cache / "out").iterdir() if q.name.startswith(".")] == []


# The header set of a model with no interface: the snippets' helpers and the runtime.
RUNTIME_ONLY_PCH = '#include "hfsmc/helpers.hpp"\n#include "hfsmc/runtime.hpp"\n'


def test_a_later_check_precompiles_the_headers(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The process that makes a header set compiles without a precompiled header; the
    next process that checks a new unit with it makes one."""
    typo, funcs = write(tmp_path, "typo.yaml", TYPO), write(tmp_path, "funcs.yaml", FUNCTIONS)
    first = compile_file(typo, cxx=True)
    monkeypatch.setattr(cxxcheck, "_MADE_HERE", set())  # as in a later `hfsmc check`
    second = compile_file(funcs, cxx=True)
    assert found(first.diagnostics, "E144") == [f"{typo}:11:7"]
    assert found(second.diagnostics, "E144") == [f"{funcs}:6:16"]
    runtime_only = [q for q in (cxxcheck.cache_dir() / "pch").iterdir()
                    if (q / "pch.hpp").is_file()
                    and (q / "pch.hpp").read_text() == RUNTIME_ONLY_PCH]
    assert len(runtime_only) == 1 and (runtime_only[0] / "pch.hpp.gch").is_file()


# ---------------------------------------------------------------------------
# checks that need no compiler: goto, active() paths, done()


def test_the_cpp_lexer_skips_comments_and_literals() -> None:
    text = ('x.goto(1); // y.goto(2)\n/* active("A") */ s = "z.goto(3)";\n'
            'r = R"(done())"; c = \'"\'; active("B/C"); n = f(1\'000);')
    seen = [(t.kind, t.text) for t in tokens(text)]
    assert [t for k, t in seen if k == "ident"] == ["x", "goto", "s", "r", "c", "active", "n", "f"]
    assert ("raw", 'R"(done())"') in seen and ("string", '"B/C"') in seen
    assert ("char", "'\"'") in seen and ("number", "1'000") in seen


BRACKETS = """\
hfsm: 1
name: brackets
language: cpp
variables:
  xs: {type: "std::vector<int>", init: "{1, 2}"}
initial: A
states:
  A:
    entry: xs[0 = 1);
    during: log("{ is fine in a string"); int n = 1'000; (void)n;
    transitions:
      - to: B
        when: (xs.size() > 3}
      - to: B
        after: 1s
        do: xs.clear(); }
  B: {final: true}
"""


def test_brackets_a_cpp_snippet_leaves_open_or_closes_wrongly(tmp_path: Path) -> None:
    path = write(tmp_path, "brackets.yaml", BRACKETS)
    got = [(str(d.span), d.message) for d in compile_file(path).diagnostics if d.code == "E147"]
    assert got == [(f"{path}:9:20", "`)` closes `[` in entry of `A`"),
                   (f"{path}:13:29", "`}` closes `(` in when of `A`"),
                   (f"{path}:16:25", "`}` closes nothing in do of `A`")]


PATHS = {
    "python": """\
hfsm: 1
name: paths
initial: Patrol
states:
  Patrol:
    initial: Forward
    during: ok = done() or active("Patrol/Back")
    states:
      Forward:
        entry: ok = done()
        transitions: [{to: Back, when: active("/Patrol/Forward/") and active("Patrol/Fwd")}]
      Back: {final: true}
""",
    "cpp": """\
hfsm: 1
name: paths
language: cpp
initial: Patrol
states:
  Patrol:
    initial: Forward
    during: bool ok = done() || active("Patrol/Back"); (void)ok;
    states:
      Forward:
        entry: bool ok = done(); (void)ok;
        transitions: [{to: Back, when: active("/Patrol/Forward/") && active("Patrol/Fwd")}]
      Back: {final: true}
""",
}


@pytest.mark.parametrize("language", ["python", "cpp"])
def test_active_paths_and_done_are_checked_in_both_languages(tmp_path: Path, language: str) -> None:
    path = write(tmp_path, "paths.yaml", PATHS[language])
    r = compile_file(path)
    first = 10 if language == "python" else 11  # the line of `entry: ...` (cpp: one more line)
    entry_col = 21 if language == "python" else 26  # done() in the entry of a leaf state
    fwd_col = 78 if language == "python" else 77  # the literal "Patrol/Fwd"
    got = [(d.code, str(d.span), d.notes) for d in r.diagnostics if d.code in ("E146", "W215")]
    assert got == [
        ("W215", f"{path}:{first}:{entry_col}",
         ("done() says whether the owning state's sub-automaton (every one of its regions) is in a "
          "final state",)),
        ("E146", f"{path}:{first + 1}:{fwd_col}", ("did you mean `Patrol/Forward`?",)),
    ], r.diagnostics
    messages = [d.message for d in r.diagnostics if d.code == "E146"]
    assert messages == ['active("Patrol/Fwd"): no state has this path']
