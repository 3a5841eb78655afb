"""The Python back end: a model becomes a standalone component folder.

The automaton is straight code: one function per state to enter, exit and
tick, one per snippet (so each snippet sits at a fixed indentation inside its
own ``try``).  This module computes everything the template prints (the
"view model": names, tables, indented snippet text); the template only loops
and prints.  After rendering, the first generated line of every snippet is
read back from the text to make the line map that turns tracebacks into model
positions.
"""

from __future__ import annotations

import ast
import io
import json
import re
import tokenize
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import jinja2

from hfsmc.durations import format_us
from hfsmc.emit.data import thaw
from hfsmc.errors import EmitError, Span, fail
from hfsmc.ir import Code, DictValue, Model, State, Value
from hfsmc.pycheck import import_statement

RUNTIME_FILES = ("hfsmc_runtime.py", "hfsmc_viewstate.py", "hfsmc_view.py", "hfsmc_monitor.py")
INTERFACE_FILES = {"mavlink": ("hfsmc_mavlink.py",), "camera": ("hfsmc_camera.py",)}
_STATEMENT_INDENT = 8  # def / try / body
_EXPRESSION_INDENT = 12  # def / try / return bool( / body
_TRY_MARK = re.compile(r"^\s*try:  # s(\d+)$")


@dataclass(frozen=True, slots=True)
class SnippetView:
    sid: int
    kind: str  # entry | during | exit | when | do | functions | on_shutdown
    owner: int  # state index; len(states) for the root's snippets
    where: str  # comment text: "blinker.yaml:31 entry of Blinking/Lit"
    assigns: tuple[str, ...]  # model variables it assigns (declared global)
    body: str  # the code, indented for its place in the template
    rows: tuple[tuple[int, int, int], ...]  # per line: model line, model col, generated indent
    code: Code


@dataclass(frozen=True, slots=True)
class TransitionView:
    index: int
    target: int
    after_us: int | None
    after_text: str
    when: SnippetView | None
    do: SnippetView | None
    target_during: SnippetView | None
    comment: str


@dataclass(frozen=True, slots=True)
class StateView:
    index: int
    path: str
    container: int  # index of the sub-automaton holding it
    child: int  # its own sub-automaton, or -1
    child_initial: int  # index of that sub-automaton's initial state
    child_history: bool
    final: bool
    entry: SnippetView | None
    during: SnippetView | None
    exit: SnippetView | None
    transitions: tuple[TransitionView, ...]
    comment: str


def _py_literal(value: Value) -> str:
    if isinstance(value, DictValue):
        return "{" + ", ".join(f"{k!r}: {_py_literal(v)}" for k, v in value.items) + "}"
    if isinstance(value, tuple):
        return "[" + ", ".join(_py_literal(v) for v in value) + "]"
    if isinstance(value, float) and value != value:
        return 'float("nan")'
    if isinstance(value, float) and value in (float("inf"), float("-inf")):
        return 'float("inf")' if value > 0 else '-float("inf")'
    return repr(value)


def _string_continuations(text: str) -> set[int]:
    """0-based lines that continue a multi-line string: indenting them would change it."""
    out: set[int] = set()
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.start[0] != tok.end[0] and tok.type not in (tokenize.NEWLINE, tokenize.NL):
                out.update(range(tok.start[0], tok.end[0]))  # rows start+1..end, 0-based
    except (tokenize.TokenError, SyntaxError, IndentationError):
        pass
    return out


def _assigned(code: Code, mode: str, variables: frozenset[str]) -> tuple[str, ...]:
    try:
        tree = ast.parse(code.text, mode=mode)
    except (SyntaxError, ValueError):
        return ()
    names = {n.id for n in ast.walk(tree)
             if isinstance(n, ast.Name) and isinstance(n.ctx, (ast.Store, ast.Del))}
    return tuple(sorted(names & variables))


class _Builder:
    """Walks the IR once and makes the view model of the template."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self.base = Path(model.file).name
        self.variables = frozenset(v.name for v in model.variables)
        self.states: list[State] = list(model.states())
        self.index = {s.path: i for i, s in enumerate(self.states)}
        self.root = len(self.states)
        self.snippets: list[SnippetView] = []
        self.automata: list[tuple[int, int, int, bool]] = []  # owner, period, initial, history
        self.auto_of: dict[str, int] = {}

    def snippet(self, kind: str, owner: int, code: Code | None, what: str = "") -> SnippetView | None:
        if code is None:
            return None
        mode = "eval" if kind == "when" else "exec"
        indent = _EXPRESSION_INDENT if kind == "when" else _STATEMENT_INDENT
        if kind == "functions":
            indent = 4
        text = code.text.rstrip("\n").replace("\r\n", "\n").replace("\r", "\n")
        lines = text.split("\n")
        strings = _string_continuations(text + "\n")
        rows: list[tuple[int, int, int]] = []
        out: list[str] = []
        for k, line in enumerate(lines):
            pad = 0 if k in strings else indent
            pos: Span = code.position(k + 1, 1)
            rows.append((pos.line, pos.col, pad))
            out.append(" " * pad + line if line.strip() or k in strings else "")
        path = self.states[owner].path if owner < self.root else ""
        where = f"{self.base}:{code.span.line} {kind}" + (f" of {path}" if path else "") + what
        view = SnippetView(len(self.snippets), kind, owner, where.replace("\n", " "),
                           _assigned(code, mode, self.variables), "\n".join(out),
                           tuple(rows), code)
        self.snippets.append(view)
        return view

    def build(self) -> dict[str, object]:
        m = self.model
        functions = self.snippet("functions", self.root, m.functions)
        # Number the sub-automata parents first, as the scheduler walks them.
        for auto in m.automata():
            self.auto_of[auto.owner] = len(self.automata)
            owner = self.index[auto.owner] if auto.owner else -1
            initial = self.index[f"{auto.owner}/{auto.initial}" if auto.owner else auto.initial]
            self.automata.append((owner, auto.period_ms, initial, auto.history))
        views = [self.state_view(i, s) for i, s in enumerate(self.states)]
        # Transition views need the target's `during`, made with the states above.
        views = [self.with_transitions(v) for v in views]
        on_shutdown = self.snippet("on_shutdown", self.root, m.on_shutdown)
        on_interrupt = -1
        if m.on_interrupt is not None:
            on_interrupt = self.index[m.on_interrupt]
        return {
            "model": m,
            "base": self.base,
            "file": m.file,
            "description": (m.description or "").strip(),
            "imports": [(import_statement(i.text), i.text, i.span.line) for i in m.imports],
            "parameters": [(p.name, _py_literal(p.default), p.type) for p in m.parameters],
            "variables": [(v.name, _py_literal(v.init)) for v in m.variables],
            "interfaces": [(i.name, i.type, i.url, dict(i.options)) for i in m.interfaces],
            "functions": functions,
            "on_shutdown": on_shutdown,
            "states": views,
            "automata": self.automata,
            "snippets": self.snippets,
            "on_interrupt": on_interrupt,
            "interrupt_timeout_us": m.interrupt_timeout_us,
            "root": self.root,
            "transitions": [(s.path, f"{s.path.rpartition('/')[0]}/{t.target}".lstrip("/"),
                             t.index, t.name) for s in self.states for t in s.transitions],
        }

    def state_view(self, i: int, s: State) -> StateView:
        container = self.auto_of[s.path.rpartition("/")[0]]
        child, child_initial, history = -1, -1, False
        if s.automaton is not None:
            child = self.auto_of[s.path]
            child_initial = self.automata[child][2]
            history = s.automaton.history
        return StateView(i, s.path, container, child, child_initial, history, s.final,
                         self.snippet("entry", i, s.entry), self.snippet("during", i, s.during),
                         self.snippet("exit", i, s.exit), (),
                         f"{self.base}:{s.span.line} {s.path}")

    def with_transitions(self, v: StateView) -> StateView:
        s = self.states[v.index]
        parent = s.path.rpartition("/")[0]
        out: list[TransitionView] = []
        for t in s.transitions:
            target = self.index[f"{parent}/{t.target}" if parent else t.target]
            label = f" {t.name}:" if t.name else ""
            after = format_us(t.after_us) if t.after_us is not None else ""
            when = self.snippet("when", v.index, t.when, f" (transition {t.index})")
            do = self.snippet("do", v.index, t.do, f" (transition {t.index})")
            cond = (f" after {after}" if after else "") + (" when ..." if when else "")
            out.append(TransitionView(
                t.index, target, t.after_us, after, when, do,
                self._during_of(target),
                f"{self.base}:{t.span.line}{label} {s.path} -> {self.states[target].path}{cond}"))
        return StateView(v.index, v.path, v.container, v.child, v.child_initial, v.child_history,
                         v.final, v.entry, v.during, v.exit, tuple(out), v.comment)

    def _during_of(self, target: int) -> SnippetView | None:
        for sn in self.snippets:
            if sn.kind == "during" and sn.owner == target:
                return sn
        return None


def _environment() -> jinja2.Environment:
    source = files("hfsmc.templates").joinpath("python")
    loader = jinja2.FunctionLoader(
        lambda name: source.joinpath(name).read_text("utf-8"))
    env = jinja2.Environment(loader=loader, undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True,
                             autoescape=False)
    env.filters["py"] = repr
    env.filters["json"] = lambda v: json.dumps(v, ensure_ascii=True)
    return env


def _line_table(text: str, snippets: list[SnippetView]) -> str:
    """Read back where each snippet landed; write the table the error reporter uses."""
    by_id = {s.sid: s for s in snippets}
    first: dict[int, int] = {}
    lines = text.split("\n")
    k = 0
    while k < len(lines):
        m = _TRY_MARK.match(lines[k])
        if m is not None and int(m.group(1)) in by_id and int(m.group(1)) not in first:
            sid = int(m.group(1))
            skip = 2 if by_id[sid].kind == "when" else 1  # `return bool(` comes first
            first[sid] = k + 1 + skip  # 1-based number of the snippet's first line
            k += skip + len(by_id[sid].rows)
            continue
        k += 1
    if len(first) != len(snippets):
        fail(EmitError, "E150", "internal: a snippet was not found in the generated code",
             Span("<emit>", 1, 1))
    rows = []
    for s in snippets:
        rows.append(f"    ({s.kind!r}, {s.owner}, {first[s.sid]}, {s.rows!r}),")
    return "_hfsm_SNIPPETS = (\n" + "\n".join(rows) + "\n)"


def component_files(model: Model) -> dict[str, bytes]:
    """Every file of the component folder, by relative path."""
    if model.language != "python":
        fail(EmitError, "E150", f"`{model.name}` is a {model.language} model: build it "
             "with -t cpp", model.span)
    view = _Builder(model).build()
    env = _environment()
    main = env.get_template("component.py.j2").render(**view)
    table_at = main.rfind("_hfsm_SNIPPETS = ()")
    snippets = view["snippets"]
    assert isinstance(snippets, list)
    main = main[:table_at] + _line_table(main, snippets) + main[table_at + len("_hfsm_SNIPPETS = ()"):]
    config = env.get_template("config.yaml.j2").render(**view, config=_config(model))
    out = {f"{model.name}.py": main.encode("utf-8"), f"{model.name}.yaml": config.encode("utf-8")}
    runtime = files("hfsmc.templates").joinpath("python")
    needed = list(RUNTIME_FILES)
    for i in model.interfaces:
        needed += [f for f in INTERFACE_FILES.get(i.type, ()) if f not in needed]
    for name in needed:
        res = runtime.joinpath(name)
        if res.is_file():
            out[name] = res.read_bytes()
    return out


def _config(model: Model) -> str:
    data = {
        "parameters": {p.name: thaw(p.default) for p in model.parameters},
        "interfaces": {i.name: {"type": i.type, "url": i.url, **({"options": dict(i.options)}
                                                                 if i.options else {})}
                       for i in model.interfaces},
    }
    return json.dumps(data, indent=2, ensure_ascii=True)
