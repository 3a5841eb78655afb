"""The C++ back end: a model becomes a CMake project (docs/cpp.md).

The automaton is one class: parameters, variables and interfaces are its
members, each snippet is a member function wrapped in ``try``, and each state
has an enter, an exit and a tick function, dispatched through a ``switch``.
The runtime (``templates/cpp/hfsmc/*.hpp``) is copied into ``include/``.

This module computes everything the template prints (the view model); the
template only loops and prints.  Every snippet line is preceded by a
``#line`` directive naming its model line and padded to its model column, so
that g++'s errors and gdb point into the model, column included.  After
rendering, the ``#line`` directives that return to the generated file get
their real line numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib.resources import files

import jinja2

from hfsmc.emit.comments import comment_text
from hfsmc.emit.data import component_config
from hfsmc.emit.walk import Walk
from hfsmc.errors import EmitError, Span, fail
from hfsmc.ir import Code, Model, Value

RUNTIME_FILES = ("runtime.hpp", "json.hpp", "observer.hpp", "thread.hpp", "view.hpp",
                 "viewstate.hpp", "monitor.hpp")
RUNTIME_SOURCE = "hfsmc_runtime.cpp"  # the automaton-independent part, one library
INTERFACE_FILES = {"mavlink": ("mavlink.hpp",), "camera": ("camera.hpp",)}
INTERFACE_CLASSES = {"mavlink": "hfsmc::Mavlink", "camera": "hfsmc::Camera"}
_TYPES = {"bool": "bool", "int": "long long", "float": "double", "str": "std::string"}
_BACK = "#line @HFSMC_BACK@ HFSMC_SOURCE"  # the line number is filled in after rendering


@dataclass(frozen=True, slots=True)
class SnippetView:
    sid: int
    kind: str  # entry | during | exit | when | do | functions | on_shutdown
    owner: int  # state index; len(states) for the root's snippets
    where: str  # comment text: "blinker.yaml:31 entry of Blinking/Lit"
    body: str  # the code with its #line directives
    line: int  # model line and column of its first line
    col: int


@dataclass(frozen=True, slots=True)
class MemberView:
    name: str
    type: str  # C++ type
    init: str  # C++ initializer text ("" for value-initialized)
    kind: str  # parameters: bool int float str
    line_directive: str  # "#line L \"file\"" before its declaration


@dataclass(frozen=True, slots=True)
class InterfaceView:
    name: str
    cls: str  # the driver class, or hfsmc::Unavailable
    url: str  # C++ string literal
    options: str  # C++ initializer of a std::map<std::string, std::string>
    line_directive: str


def cpp_string(text: str) -> str:
    """A C++ string literal holding ``text``'s UTF-8 bytes (octal escapes, never ambiguous)."""
    out = []
    for b in text.encode("utf-8"):
        ch = chr(b)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 0x20 <= b < 0x7F and ch != "?":
            out.append(ch)
        else:
            out.append(f"\\{b:03o}")
    return '"' + "".join(out) + '"'


def cpp_literal(value: Value, kind: str) -> str:
    """A literal of a bool/int/float/str model value as C++ text."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int) and kind != "float":
        return "(-9223372036854775807LL - 1)" if value == -(2**63) else f"{value}LL"
    if isinstance(value, (int, float)):
        v = float(value)
        if math.isnan(v):
            return "std::numeric_limits<double>::quiet_NaN()"
        if math.isinf(v):
            return ("" if v > 0 else "-") + "std::numeric_limits<double>::infinity()"
        return repr(v)
    if isinstance(value, str):
        return f"std::string({cpp_string(value)}, {len(value.encode('utf-8'))})"
    fail(EmitError, "E150", f"a C++ component cannot hold the value {value!r}", Span("<emit>", 1, 1))


def _line(file: str, line: int) -> str:
    return f"#line {max(line, 1)} {cpp_string(file)}"


def _include(text: str) -> str:
    t = text.strip()
    return t if t.startswith(("<", '"')) else f"<{t}>"


class _Builder(Walk[SnippetView]):
    """Walks the IR once and makes the view model of the template."""

    def __init__(self, model: Model) -> None:
        super().__init__(model)
        self.file = model.file

    def lines(self, code: Code) -> tuple[str, int, int]:
        """The snippet's text, each line after a #line directive and padded to its column."""
        text = code.text.rstrip("\n").replace("\r\n", "\n").replace("\r", "\n")
        rows = text.split("\n")
        raw = 'R"' in text  # a raw string may span lines: its lines stay as they are
        out: list[str] = []
        first = code.position(1, 1)
        continued = False
        for k, row in enumerate(rows):
            pos: Span = code.position(k + 1, 1)
            if k == 0 or not (raw or continued):
                out.append(_line(self.file, pos.line))
                out.append(" " * (pos.col - 1) + row)
            else:
                out.append(row)
            continued = row.endswith("\\")
        return "\n".join(out), first.line, first.col

    def make_snippet(self, sid: int, kind: str, owner: int, code: Code, where: str) -> SnippetView:
        body, line, col = self.lines(code)
        return SnippetView(sid, kind, owner, where, body, line, col)

    def members(self) -> tuple[list[MemberView], list[MemberView], list[InterfaceView]]:
        m = self.model
        params = []
        for p in m.parameters:
            if p.type not in _TYPES:
                fail(EmitError, "E150", f"parameter `{p.name}` is a {p.type}: a C++ component "
                     f"takes parameters of types {', '.join(_TYPES)}", p.span)
            params.append(MemberView(p.name, _TYPES[p.type], cpp_literal(p.default, p.type),
                                     p.type, _line(self.file, p.span.line)))
        variables = []
        for v in m.variables:
            if v.type in _TYPES:
                ctype, init = _TYPES[v.type], cpp_literal(v.init, v.type)
            elif v.type in ("list", "dict"):
                fail(EmitError, "E150", f"variable `{v.name}` is a {v.type}: in a C++ model give "
                     "it a C++ type, e.g. {type: \"std::vector<int>\", init: [1, 2]}", v.span)
            else:
                ctype, init = v.type, str(v.init)
            variables.append(MemberView(v.name, ctype, init, v.type, _line(self.file, v.span.line)))
        interfaces = []
        for i in m.interfaces:
            options = ", ".join(f"{{{cpp_string(k)}, {cpp_string(val)}}}" for k, val in i.options)
            interfaces.append(InterfaceView(
                i.name, INTERFACE_CLASSES.get(i.type, "hfsmc::Unavailable"),
                cpp_string(i.url or ""), "{" + options + "}", _line(self.file, i.span.line)))
        return params, variables, interfaces

    def build(self) -> dict[str, object]:
        m = self.model
        functions = self.snippet("functions", self.root, m.functions)
        views = self.state_views()
        on_shutdown = self.snippet("on_shutdown", self.root, m.on_shutdown)
        params, variables, interfaces = self.members()
        kinds = {i.type for i in m.interfaces}
        return {
            "model": m,
            "base": self.base,
            "source": cpp_string(f"src/{m.name}.cpp"),
            "description": [comment_text(ln) for ln in (m.description or "").strip().splitlines()],
            "includes": [(_include(i.text), _line(self.file, i.span.line)) for i in m.imports],
            "drivers": [f"hfsmc/{INTERFACE_FILES[k][0]}" for k in sorted(kinds) if k in INTERFACE_FILES],
            "parameters": params,
            # For the component's --help: name, type, default (as Python writes it), description.
            "parameter_help": [(cpp_string(p.name), cpp_string(p.type), cpp_string(repr(p.default)),
                                cpp_string(p.description or "")) for p in m.parameters],
            "variables": variables,
            "interfaces": interfaces,
            "functions": functions,
            "on_shutdown": on_shutdown,
            "states": views,
            "automata": self.automata,
            "snippets": self.snippets,
            "on_interrupt": self.index[m.on_interrupt] if m.on_interrupt is not None else -1,
            "interrupt_timeout_us": m.interrupt_timeout_us if m.interrupt_timeout_us is not None else -1,
            "root": self.root,
            "transitions": [(self.index[s.path], self.target(s, t.target), t.index,
                             cpp_string(t.name or "")) for s in self.states for t in s.transitions],
            "file": cpp_string(m.file),
            "name": cpp_string(m.name),
        }


def _environment() -> jinja2.Environment:
    source = files("hfsmc.templates").joinpath("cpp")
    loader = jinja2.FunctionLoader(lambda name: source.joinpath(name).read_text("utf-8"))
    env = jinja2.Environment(loader=loader, undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True,
                             autoescape=False)
    env.filters["cstr"] = cpp_string
    env.filters["bool"] = lambda b: "true" if b else "false"
    return env


def _fill_back_lines(text: str) -> str:
    """Give every ``#line`` back into the generated file the number of the line after it."""
    lines = text.split("\n")
    for k, ln in enumerate(lines):
        if ln == _BACK:
            lines[k] = f"#line {k + 2} HFSMC_SOURCE"
    return "\n".join(lines)


def _render_source(env: jinja2.Environment, view: dict[str, object]) -> str:
    return _fill_back_lines(env.get_template("component.cpp.j2").render(**view, back=_BACK))


def source_file(model: Model) -> str:
    """The component's translation unit (``src/NAME.cpp``) alone: what ``hfsmc check``
    hands to g++, without the MAVLink headers and the rest of the folder."""
    return _render_source(_environment(), _Builder(model).build())


def component_files(model: Model) -> dict[str, bytes]:
    """Every file of the C++ component folder, by relative path."""
    if model.language != "cpp":
        fail(EmitError, "E150", f"`{model.name}` is a {model.language} model: build it "
             "with -t python", model.span)
    view = _Builder(model).build()
    env = _environment()
    main = _render_source(env, view)
    cmake = env.get_template("CMakeLists.txt.j2").render(**view)
    config = env.get_template("config.yaml.j2").render(**view, config=component_config(model))
    out = {f"src/{model.name}.cpp": main.encode("utf-8"),
           "CMakeLists.txt": cmake.encode("utf-8"),
           f"{model.name}.yaml": config.encode("utf-8")}
    runtime = files("hfsmc.templates").joinpath("cpp").joinpath("hfsmc")
    needed = list(RUNTIME_FILES)
    for i in model.interfaces:
        needed += [f for f in INTERFACE_FILES.get(i.type, ()) if f not in needed]
    for name in needed:
        res = runtime.joinpath(name)
        if res.is_file():
            out[f"include/hfsmc/{name}"] = res.read_bytes()
    out[f"src/{RUNTIME_SOURCE}"] = files("hfsmc.templates").joinpath("cpp").joinpath(
        RUNTIME_SOURCE).read_bytes()
    if any(i.type == "mavlink" for i in model.interfaces):
        from hfsmc.emit.mavgen import MavgenError, mavlink_headers

        try:
            out.update(mavlink_headers())
        except MavgenError as e:
            fail(EmitError, "E150", f"the MAVLink C headers cannot be generated: {e}", model.span)
    return out
