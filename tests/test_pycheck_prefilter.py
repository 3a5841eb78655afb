"""The snippet check's prefilter (hfsmc/pycheck.py: a symbol table pass decides which
snippets pyflakes must look at, and which need an ast tree) changes no diagnostic:
with it and without it, every example, every invalid model and generated snippets
give the same diagnostics, text and position."""

from __future__ import annotations

import functools
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyflakes.checker import Checker

from hfsmc import lower, pycheck
from hfsmc.pipeline import compile_file
from tests.conftest import ROOT, examples

MODELS = sorted(str(p.relative_to(ROOT)) for p in [
    *examples(), *(ROOT / "examples" / "lib").glob("*.yaml"),
    *(ROOT / "tests" / "invalid").glob("*.yaml"), *(ROOT / "tests" / "invalid").glob("*.xml")])


def _both(path: str, text: str | None, monkeypatch: pytest.MonkeyPatch) -> tuple[list[str], list[str]]:
    """The diagnostics with the prefilter and without it."""
    fast = [repr(d) for d in compile_file(path, text).diagnostics]
    with monkeypatch.context() as m:
        m.setattr(lower, "check_python_snippets",
                  functools.partial(pycheck.check_python_snippets, prefilter=False))
        slow = [repr(d) for d in compile_file(path, text).diagnostics]
    return fast, slow


@pytest.mark.parametrize("path", MODELS)
def test_models_same_with_and_without_prefilter(path: str, monkeypatch: pytest.MonkeyPatch) -> None:
    fast, slow = _both(str(ROOT / path), None, monkeypatch)
    assert fast == slow


# --- generated snippets -------------------------------------------------------------
# Known names: variables count and flag, parameter limit, function helper, builtins,
# helpers; the others are undefined unless a snippet binds them.
NAMES = st.sampled_from(["count", "flag", "limit", "helper", "len", "log", "x", "y", "e", "zz",
                         "tmp", "math"])
TARGETS = st.sampled_from(["count", "limit", "x", "y", "e", "tmp", "len"])


@st.composite
def expressions(draw: st.DrawFn, depth: int = 0) -> str:
    n, t, t2 = draw(NAMES), draw(TARGETS), draw(TARGETS)
    forms = [n, f"{n} + 1", f"{n}({draw(NAMES)})", f"{n}.real", f'"{n}"', f'f"{{{n}}}"',
             f"[{n} for {t} in {draw(NAMES)}]", f"[{t} for {t} in {n} if {draw(NAMES)}]",
             f"[{n} for {t} in {draw(NAMES)} for {t2} in {t}]", f"({t} := {n})",
             f"[({t2} := {t}) for {t} in {n}]", f"lambda {t}: {n}", f"lambda: {n}",
             f"{{{t}: {n} for {t} in {draw(NAMES)}}}", f"active(\"{n}\")", "done()"]
    if depth < 2 and draw(st.booleans()):
        inner = draw(expressions(depth + 1))
        forms += [f"({inner}) and {n}", f"[{inner} for {t} in {n}]", f"lambda {t}: {inner}"]
    return draw(st.sampled_from(forms))


@st.composite
def statements(draw: st.DrawFn, depth: int = 0) -> list[str]:
    t, t2, e = draw(TARGETS), draw(TARGETS), draw(expressions())
    simple = [f"{t} = {e}", f"{t} += {e}", f"{t}: int = {e}", f'{t}: "{draw(NAMES)}" = {e}',
              f"log({e})", f"del {t}", f"global {t}", f"import math as {t}",
              f"{t}, {t2} = {e}, 1", f"x = {e}; {t}: \"{draw(NAMES)}\" = 1"]
    if depth >= 2 or draw(st.booleans()):
        return [draw(st.sampled_from(simple))]
    body = ["    " + line for stmt in draw(st.lists(statements(depth + 1), min_size=1, max_size=2))
            for line in stmt]
    other = ["    " + line for line in draw(statements(depth + 1))]
    block = draw(st.sampled_from([
        [f"for {t} in {e}:", *body],
        [f"if {e}:", *body, "else:", *other],
        ["try:", *body, f"except Exception as {t}:", *other],
        [f"def {t}({t2}):", *body, f"    return {draw(expressions())}"],
        [f"def {t}(*, {t2}=1) -> \"{draw(NAMES)}\":", *body],
        [f"class {t.capitalize()}:", *body],
        [f"with {e} as {t}:", *body],
        [f"match {e}:", f"    case {t}:", *("    " + b for b in body)],
    ]))
    return block


@st.composite
def models(draw: st.DrawFn) -> str:
    # Mostly one snippet to a model: a model is checked by pyflakes as soon as one of its
    # snippets needs it, so the prefilter decides alone only where all are clean.
    count = draw(st.sampled_from([1, 1, 1, 2, 4]))
    lines = ["hfsm: 1", "name: generated", "language: python",
             "parameters:", "  limit: {type: int, default: 3}",
             "variables:", "  count: 0", "  flag: false",
             "functions: |", "  def helper(v):", "      return v", "initial: S0", "states:"]
    for i in range(count):
        body = [line for stmt in draw(st.lists(statements(), min_size=1, max_size=2)) for line in stmt]
        lines += [f"  S{i}:", "    entry: |", *("      " + b for b in body),
                  "    transitions:", f"      - to: S{(i + 1) % count}",
                  "        when: |-", f"          {draw(st.just('flag') | expressions())}"]
    return "\n".join(lines) + "\n"


@settings(max_examples=500, deadline=None, derandomize=True, database=None)
@given(models())
def test_generated_snippets_same_with_and_without_prefilter(text: str) -> None:
    with pytest.MonkeyPatch.context() as monkeypatch:
        fast, slow = _both("generated.yaml", text, monkeypatch)
    assert fast == slow, text


def test_prefilter_leaves_clean_snippets_to_no_one() -> None:
    """The prefilter does decide: clean snippets are not handed to pyflakes."""
    text = ("hfsm: 1\nname: m\nlanguage: python\nvariables:\n  count: 0\ninitial: A\nstates:\n"
            "  A:\n    entry: count = len([v for v in range(3)])\n")
    checked: list[int] = []
    original = Checker

    def counting(*args: Any, **kwargs: Any) -> Checker:
        checked.append(1)
        return original(*args, **kwargs)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(pycheck, "Checker", counting)
        assert compile_file("m.yaml", text).ok
        assert checked == []
        assert not compile_file("m.yaml", text.replace("range(3)", "rnge(3)")).ok
        assert checked == [1]


# Snippets where pyflakes reports something that a symbol table alone does not show
# (a use before the binding, an unbinding, a string annotation, a read by `+=`...), and
# their clean twins; each is the only snippet of its model.
TRICKY = [
    "x += 1", "count += 1", "log(tmp)\ntmp = 1", "tmp = 1\nlog(tmp)", "len = len([])",
    "del count", "del tmp", "global tmp\ntmp = 1", "global count\ncount = 1",
    "def f(v):\n    log(w)\n    w = v\n    return w", "def f(v):\n    v += 1\n    return v",
    "def f():\n    n += 1", "f = lambda v: v + count\nlog(f(1))", "g = lambda v: v + zz",
    "log([v for w in range(3) for v in [w]])", "log([v for w in v for v in [1]])",
    "log([w for w in range(3) if w])", "log([w for w in w])",
    "log([y := 1 for w in range(3)])\nlog(y)", "log(y)\nlog([y := 1 for w in range(3)])",
    "log([len := 1 for w in range(3)])", "[c := c for _ in range(2)]", "[count := count + 1 for _ in range(2)]",
    'x: "Undefined" = 1', 'count: "int" = 1', 'count.real: "Nope"', "x: int",
    'def f(v: "Nope") -> "int":\n    return v', "try:\n    pass\nexcept Exception as err:\n    pass\nlog(err)",
    "class K:\n    a = 1\n    b = a", "class K:\n    __p = 1\n    q = __p", "log(__name__)",
    "from typing import cast\nlog(cast('Nope', 1))", "import math as m\nlog(m.pi)",
    "match count:\n    case 1:\n        log(1)\n    case other:\n        log(other)",
    "with open('f') as fh:\n    log(fh)", "for i in range(3):\n    log(i)", "log(i)\nfor i in range(3):\n    pass",
    "def f():\n    return g()\ndef g():\n    return 1", "def f():\n    [q for _ in range(2)]\n    q = 1",
    "limit = 3", "for limit in range(2):\n    pass", "[v for v in range(3) if (limit := v)]",
    "nonlocal q", "x = 1 \\\n    + 2", "log(f'{count} {zz}')", "log(_snippet_0)",
    "log([1 for w in range(3) if v for v in range(w)])", "log(len)\nlog([len := 1 for w in range(3)])",
    "log(cast('Nope', 1))", "log(cast(int, 1))",
    "x = " + "-" * 3000 + "1", "log(" + "(" * 250 + "1" + ")" * 251, "log(" + "not " * 2000 + "zz)",
]


@pytest.mark.parametrize("snippet", TRICKY)
def test_tricky_snippets_same_with_and_without_prefilter(snippet: str,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    body = "".join(f"      {line}\n" for line in snippet.split("\n"))
    text = ("hfsm: 1\nname: m\nlanguage: python\nparameters:\n  limit: {type: int, default: 3}\n"
            f"variables:\n  count: 0\ninitial: A\nstates:\n  A:\n    entry: |\n{body}")
    for functions in ("", "functions: |\n  from typing import cast\n"):
        fast, slow = _both("m.yaml", functions + text, monkeypatch)
        assert fast == slow, functions
