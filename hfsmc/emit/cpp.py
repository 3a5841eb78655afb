"""The C++ back end: a model becomes a CMake project (docs/cpp.md).

The automaton is one class: parameters, variables and interfaces are its
members, each snippet is a member function wrapped in ``try``, and each state
has an enter, an exit and a tick function, dispatched through a ``switch``.
The runtime (``templates/cpp/hfsmc/*.hpp``) is copied into ``include/``.

This module computes everything the templates print (``CppComponentView``);
the templates only loop and print.  Every snippet line is preceded by a
``#line`` directive naming its model line and padded to its model column, so
that g++'s errors and gdb point into the model, column included.  After
rendering, the ``#line`` directives that return to the generated file get
their real line numbers.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import jinja2

from hfsmc.emit.comments import comment_text
from hfsmc.emit.cpp_ros2 import interface_class, interface_header, ros2_files
from hfsmc.emit.data import component_config
from hfsmc.emit.templating import environment, runtime_files, template_folder
from hfsmc.emit.walk import InstanceView, MachineView, Snippet, Walk
from hfsmc.errors import EmitError, Span, fail
from hfsmc.ir import Code, Model, Value
from hfsmc.ros2files import model_distro

RUNTIME_FILES = ("runtime.hpp", "json.hpp", "observer.hpp", "thread.hpp", "view.hpp",
                 "viewstate.hpp", "address.hpp", "monitor.hpp", "mcap.hpp", "record.hpp",
                 "playback.hpp", "jsonread.hpp", "jsonvalue.hpp", "simclock.hpp", "helpers.hpp",
                 "base64.hpp")
RUNTIME_SOURCE = "hfsmc_runtime.cpp"  # the automaton-independent part, one library
# The library hfsmc_runtime: start-up, the engine's model-independent part, --record, JSON.
RUNTIME_SOURCES = (RUNTIME_SOURCE, "hfsmc_engine.cpp", "hfsmc_record.cpp", "hfsmc_json.cpp")
INTERFACE_FILES = {"mavlink": ("mavlink.hpp", "px4.hpp", "driver.hpp"), "camera": ("camera.hpp", "driver.hpp"),
                   "driver": ("driver.hpp",),
                   "ros2": ("ros2_interface.hpp", "ros2.hpp", "cdr.hpp", "ros2_wire.hpp",
                            "ros2view.hpp", "ros2_rpc.hpp", "ros2_servers.hpp")}
# A driver's code, one library each (hfsmc_mavlink, hfsmc_camera, hfsmc_ros2): src/, beside
# the runtime's; the library's first file names it.
INTERFACE_SOURCES = {"mavlink": ("hfsmc_mavlink.cpp", "hfsmc_mavlink_link.cpp", "hfsmc_mavlink_commands.cpp",
                                 "hfsmc_mission.cpp", "hfsmc_mission_upload.cpp", "hfsmc_px4.cpp"),
                     "camera": ("hfsmc_camera.cpp",),
                     "ros2": ("hfsmc_ros2.cpp", "hfsmc_ros2_wire.cpp", "hfsmc_ros2_interface.cpp",
                              "hfsmc_ros2_playback.cpp", "hfsmc_ros2_rpc.cpp",
                              "hfsmc_ros2_servers.cpp")}
# What each driver's library links against, besides hfsmc_runtime.
_DRIVER_LINKS = {"mavlink": "Eigen3::Eigen", "camera": "${OpenCV_LIBS}",
                 "ros2": "CycloneDDS::ddsc"}
LIBRARY_SOURCES = frozenset(RUNTIME_SOURCES).union(*INTERFACE_SOURCES.values())
INTERFACE_CLASSES = {"mavlink": "hfsmc::Mavlink", "camera": "hfsmc::Camera"}  # ros2: generated
_TYPES = {"bool": "bool", "int": "long long", "float": "double", "str": "std::string"}
_BACK = "#line @HFSMC_BACK@ HFSMC_SOURCE"  # the line number is filled in after rendering


@dataclass(frozen=True, slots=True)
class CppSnippet(Snippet):
    body: str  # the code with its #line directives
    line: int  # model line and column of its first line
    col: int
    what: str  # ``where`` without the position ("entry of A/B"): the header's comment, which
    # must not change when a snippet above it grows (src/NAME.hpp would compile again)


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
    settings: bool = False  # made from NAME.yaml's settings of it (ros2), not url and options


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


@dataclass(frozen=True, slots=True)
class IncludeView:
    header: str  # <name> or "name"
    line_directive: str


@dataclass(frozen=True, slots=True)
class ParameterHelpView:
    """A parameter for the component's --help, every field a C++ string literal."""

    name: str
    type: str
    default: str  # as Python writes it
    description: str


@dataclass(frozen=True, slots=True)
class TransitionIndices:
    """A row of the component's transition table: states by index."""

    source: int
    target: int
    index: int
    name_literal: str  # C++ string literal ("" if unnamed)


@dataclass(frozen=True, slots=True)
class SnippetRow:
    """A row of the component's table of every snippet: one of an instance of a used file."""

    kind: str
    owner: int  # state index in the component
    line: int
    col: int
    file_literal: str  # the used file, as a C++ string literal


@dataclass(frozen=True, slots=True)
class CppUnitView:
    """A used file's code: a class template, one object per `use`."""

    cls: str  # `_hfsm_U_NAME`
    base: str  # the used file's name
    parameters: tuple[MemberView, ...]
    variables: tuple[MemberView, ...]
    interfaces: tuple[InterfaceView, ...]  # references to the using model's
    machine: MachineView[CppSnippet]


@dataclass(frozen=True, slots=True)
class CppInstanceView:
    """One instance of a used file: a member of the component, and its snippets' rows."""

    number: int  # the member `_hfsm_i{number}`
    cls: str
    base: int
    sid0: int
    prefix_literal: str  # the using state's path
    where_literal: str  # how active() errors name it
    arguments: tuple[str, ...]  # its parameters' then its interfaces' C++ expressions
    rows: tuple[SnippetRow, ...]


@dataclass(frozen=True, slots=True)
class BelowView:
    """A state a sub-automaton may be in after its tick, and the sub-automata (or
    regions, in order) active under it, ticked next."""

    state: int
    automata: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class StepView:
    """One state's part of the instant generated from the model: its tick, then what is
    active under the state its sub-automaton is in afterwards (itself or a transition's
    target), parents first."""

    index: int
    automaton: int  # the sub-automaton (or region) it is a state of
    below: tuple[BelowView, ...]  # only the states with a sub-automaton or regions


@dataclass(frozen=True, slots=True)
class DriverLibraryView:
    """A driver's library (hfsmc_mavlink, hfsmc_camera), built from its sources in src/."""

    name: str
    sources: str  # its source files, under src/
    links: str  # what it links against, besides hfsmc_runtime


@dataclass(frozen=True, slots=True)
class CppComponentView:
    """Everything ``component.cpp.j2``, ``CMakeLists.txt.j2`` and ``config.yaml.j2`` print,
    computed."""

    name: str  # the component's name, as an identifier
    name_literal: str  # and as a C++ string literal
    base: str  # the model's file name, for the headers
    file_literal: str  # the model's path as a C++ string literal, for error messages
    source_literal: str  # "src/NAME.cpp" as a C++ string literal
    header_literal: str  # "src/NAME.hpp" as a C++ string literal
    guard: str  # the header's include guard
    description_lines: tuple[str, ...]  # comment text
    includes: tuple[IncludeView, ...]
    driver_headers: tuple[str, ...]  # "hfsmc/mavlink.hpp", ...
    # The generated classes of the ros2 interfaces: never precompiled (they differ between
    # components of one CMake project that share a precompiled header set).
    ros2_headers: tuple[str, ...]
    driver_libraries: tuple[DriverLibraryView, ...]  # in the order of driver_headers
    parameters: tuple[MemberView, ...]
    parameter_help: tuple[ParameterHelpView, ...]
    variables: tuple[MemberView, ...]
    interfaces: tuple[InterfaceView, ...]
    machine: MachineView[CppSnippet]
    interrupt_timeout_us: int  # -1 without one
    time_limit_us: int  # the model's time_limit, -1 without one
    transition_indices: tuple[TransitionIndices, ...]
    first_child: tuple[int, ...]  # per state: where its sub-automata start in _hfsm_CHILDREN
    has_regions: bool  # the engine keeps its chain sorted only with regions
    automaton_states: tuple[tuple[int, ...], ...]  # per sub-automaton (or region), its states
    # The instant as code, per state in state order, when every sub-automaton has one
    # period: each active one is due at each instant, so the tick of a sub-automaton's
    # current state is followed by the ticks of those under it (pre-order), with no walk
    # of the engine's chain of active sub-automata. None with several periods.
    instant: tuple[StepView, ...] | None
    units: tuple[CppUnitView, ...]
    instances: tuple[CppInstanceView, ...]
    line_back: str  # a #line back into the generated file (numbered after rendering)
    config: str  # the body of NAME.yaml
    uses_ros2: bool  # Cyclone DDS is needed
    sources: tuple[tuple[str, str], ...]  # (path, text) as C++ string literals, for --record
    hash_literal: str  # the sources' hash
    version_literal: str  # hfsmc's version


class CppWalk(Walk[CppSnippet]):
    """Walks the IR once and makes the view of the templates."""

    def __init__(self, model: Model, unit: str = "") -> None:
        super().__init__(model)
        self.file = model.file
        self.unit = unit  # a used file's unit name (unit_view)

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

    def make_snippet(self, sid: int, kind: str, owner: int, code: Code, where: str) -> CppSnippet:
        body, line, col = self.lines(code)
        what = where.partition(f":{code.span.line} ")[2] or where
        return CppSnippet(sid, kind, owner, where, body, line, col, what)

    def members(self) -> tuple[tuple[MemberView, ...], tuple[MemberView, ...],
                               tuple[InterfaceView, ...]]:
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
            cls = (i.declaration.cls if i.declaration is not None
                   else interface_class(i.name) if i.ros2 is not None
                   else INTERFACE_CLASSES.get(i.type, "hfsmc::Unavailable"))
            interfaces.append(InterfaceView(
                i.name, cls,
                cpp_string(i.url or ""), "{" + options + "}", _line(self.file, i.span.line),
                i.ros2 is not None))
        return tuple(params), tuple(variables), tuple(interfaces)

    def unit_view(self) -> CppUnitView:
        """The code of a used file (this walk's model) as its class prints it."""
        params, variables, interfaces = self.members()
        return CppUnitView(unit_class(self.unit), self.base, params, variables, interfaces,
                           self.machine())

    def instance_view(self, i: InstanceView, unit: CppUnitView) -> CppInstanceView:
        inst = i.instance
        owner = "" if i.parent == 0 else f"_hfsm_i{i.parent}."
        args = []
        for p in inst.model.parameters:
            b = inst.binding(p.name)
            args.append(f"{owner}{b.source}" if b.source is not None else cpp_literal(b.value, p.type))
        for f in inst.model.interfaces:
            args.append(f"{owner}{inst.binding(f.name).source or f.name}")
        file = cpp_string(inst.file)
        rows = tuple(SnippetRow(s.kind, self.root if s.owner >= i.count else i.base + s.owner,
                                s.line, s.col, file) for s in unit.machine.snippets)
        return CppInstanceView(i.number, unit.cls, i.base, i.sid0, cpp_string(i.prefix),
                               cpp_string(f"{inst.written} (used at {i.prefix})"), tuple(args), rows)

    def view(self) -> CppComponentView:
        m = self.model
        machine = self.machine()
        params, variables, interfaces = self.members()
        kinds = {i.type for i in m.interfaces}
        units = {u.name: CppWalk(u.model, u.name).unit_view() for u in machine.units}
        imports = list(m.imports)
        for u in machine.units:  # the used files' imports are merged, once each
            imports += [i for i in u.model.imports if i.text not in {k.text for k in imports}]
        return CppComponentView(
            name=m.name,
            name_literal=cpp_string(m.name),
            base=self.base,
            file_literal=cpp_string(m.file),
            source_literal=cpp_string(f"src/{m.name}.cpp"),
            header_literal=cpp_string(f"src/{m.name}.hpp"),
            guard=f"HFSMC_MODEL_{m.name.upper()}_HPP",
            description_lines=tuple(comment_text(ln)
                                    for ln in (m.description or "").strip().splitlines()),
            includes=tuple(IncludeView(_include(i.text), _line(i.span.file, i.span.line))
                           for i in imports),
            driver_headers=tuple(f"hfsmc/{INTERFACE_FILES[k][0]}" for k in sorted(kinds)
                                 if k in INTERFACE_FILES) + tuple(user_headers(m).values()),
            ros2_headers=tuple(interface_header(i.name) for i in m.interfaces if i.ros2 is not None),
            driver_libraries=tuple(
                DriverLibraryView(_library(m, k), " ".join(f"src/{f}" for f in INTERFACE_SOURCES[k]),
                                  _DRIVER_LINKS[k])
                for k in sorted(kinds) if k in INTERFACE_SOURCES),
            uses_ros2="ros2" in kinds,
            parameters=params,
            parameter_help=tuple(
                ParameterHelpView(cpp_string(p.name), cpp_string(p.type),
                                  cpp_string(repr(p.default)), cpp_string(p.description or ""))
                for p in m.parameters),
            variables=variables,
            interfaces=interfaces,
            machine=machine,
            interrupt_timeout_us=(m.interrupt_timeout_us if m.interrupt_timeout_us is not None
                                  else -1),
            time_limit_us=m.time_limit_us if m.time_limit_us is not None else -1,
            transition_indices=tuple(
                TransitionIndices(self.index[s.path], self.target(s, t.target), t.index,
                                  cpp_string(t.name or ""))
                for s in self.states for t in s.transitions),
            first_child=_offsets([len(st.children) for st in machine.states]),
            has_regions=any(a.region is not None for a in machine.automata),
            automaton_states=_automaton_states(machine),
            instant=_instant(machine),
            units=tuple(units.values()),
            instances=tuple(self.instance_view(i, units[i.unit]) for i in machine.instances),
            line_back=_BACK,
            config=component_config(m),
            sources=tuple((cpp_string(path), _text_literal(text)) for path, text in machine.sources),
            hash_literal=cpp_string(machine.model_hash),
            version_literal=cpp_string(machine.version),
        )


def _library(m: Model, kind: str) -> str:
    """A driver's library: ``hfsmc_KIND``; ``hfsmc_ros2_DISTRO`` for ros2, whose node is
    compiled with the distro's discovery message (components of two distros in one CMake
    project each get theirs)."""
    if kind == "ros2":
        return f"hfsmc_ros2_{model_distro(m.interfaces)}"
    return f"hfsmc_{kind}"


def _automaton_states(machine: MachineView[CppSnippet]) -> tuple[tuple[int, ...], ...]:
    """Per sub-automaton (or region), its states, in one pass over the states."""
    states: list[list[int]] = [[] for _ in machine.automata]
    for st in machine.states:
        states[st.container].append(st.index)
    return tuple(tuple(s) for s in states)


def _instant(machine: MachineView[CppSnippet]) -> tuple[StepView, ...] | None:
    """The generated instant, for a model whose sub-automata all have one period."""
    if len({a.period_ms for a in machine.automata}) != 1:
        return None
    children = {st.index: tuple(a.index for a in st.children) for st in machine.states}
    steps = []
    for st in machine.states:
        after = dict.fromkeys([st.index, *(tr.target for tr in st.transitions)])
        steps.append(StepView(st.index, st.container, tuple(BelowView(j, children[j]) for j in after
                                              if children[j])))
    return tuple(steps)


def _text_literal(text: str) -> str:
    """A text as C++ string literals, one per line (the compiler joins them)."""
    return "\n    ".join(cpp_string(line) for line in text.splitlines(keepends=True)) or '""'


def unit_class(unit: str) -> str:
    """The class of a used file's code."""
    return f"_hfsm_U_{unit}"


def _offsets(counts: list[int]) -> tuple[int, ...]:
    """Where each run of ``counts`` starts in their concatenation."""
    out, at = [], 0
    for n in counts:
        out.append(at)
        at += n
    return tuple(out)


def component_view(model: Model) -> CppComponentView:
    """What the C++ templates print for ``model``."""
    return CppWalk(model).view()


def _unplaced(comment: str) -> str:
    """A state's or transition's comment without its model position ("a.yaml:12 A" -> "A"):
    src/NAME_main.cpp must not change when a snippet above the state grows."""
    return re.sub(r"^.*?:\d+ ", "", comment, count=1)


def _environment() -> jinja2.Environment:
    return environment("cpp", {"cstr": cpp_string, "bool": lambda b: "true" if b else "false",
                               "unplaced": _unplaced})


def _fill_back_lines(text: str, macro: str = "HFSMC_SOURCE") -> str:
    """Give every ``#line`` back into the generated file the number of the line after it;
    ``macro`` names the file (HFSMC_SOURCE, HFSMC_HEADER)."""
    lines = text.split("\n")
    for k, ln in enumerate(lines):
        if ln == _BACK:
            lines[k] = f"#line {k + 2} {macro}"
    return "\n".join(lines)


@dataclass(frozen=True, slots=True)
class ComponentSources:
    """The component's own C++ files: the automaton's class and its two units."""

    name: str
    header: str  # src/NAME.hpp: the class, its states (the snippets declared)
    code: str  # src/NAME.cpp: the snippets and tables, compiled again when a snippet changes
    main: str  # src/NAME_main.cpp: main(), where the engine and the states are compiled

    def files(self) -> dict[str, str]:
        return {f"src/{self.name}.hpp": self.header, f"src/{self.name}.cpp": self.code,
                f"src/{self.name}_main.cpp": self.main}

    def unit(self) -> str:
        """All three as one translation unit, each under its own name (``#line 1``), the
        header inlined: what ``hfsmc check`` hands to g++ on its standard input."""
        include = f'#include "{self.name}.hpp"'
        parts = [f'#line 1 "src/{self.name}.hpp"', self.header.rstrip("\n")]
        for file, text in ((f"{self.name}.cpp", self.code), (f"{self.name}_main.cpp", self.main)):
            parts.append(f'#line 1 "src/{file}"')
            parts.append("\n".join("" if ln == include else ln
                                   for ln in text.rstrip("\n").split("\n")))
        return "\n".join(parts) + "\n"


def _render_sources(env: jinja2.Environment, view: CppComponentView) -> ComponentSources:
    return ComponentSources(
        view.name,
        _fill_back_lines(env.get_template("component.hpp.j2").render(view=view), "HFSMC_HEADER"),
        _fill_back_lines(env.get_template("component.cpp.j2").render(view=view)),
        env.get_template("main.cpp.j2").render(view=view))


def component_sources(model: Model) -> ComponentSources:
    """The component's own C++ files alone: what ``hfsmc check`` hands to g++, without
    the MAVLink headers and the rest of the folder."""
    return _render_sources(_environment(), component_view(model))


def user_headers(model: Model) -> dict[str, str]:
    """A user's C++ driver headers, by path: where the component includes them from
    (``drivers/NAME.hpp`` under include/); two headers of one name are refused."""
    out: dict[str, str] = {}
    for i in model.interfaces:
        if i.cpp is None or i.declaration is None or i.cpp.path in out:
            continue
        base = i.cpp.written.replace("\\", "/").rsplit("/", 1)[-1]
        if f"drivers/{base}" in out.values():
            fail(EmitError, "E188", f"two driver headers are both `{base}`: rename one",
                 i.cpp.span)
        out[i.cpp.path] = f"drivers/{base}"
    return out


def generated_headers(model: Model) -> dict[str, str]:
    """The headers a component includes that come from the model, not from the runtime, by
    their path under include/: a user's driver headers, a ros2 interface's message types
    and classes (what ``hfsmc check`` puts beside the runtime's)."""
    out = {inc: i.cpp.text for i in model.interfaces if i.cpp is not None
           for path, inc in user_headers(model).items() if path == i.cpp.path}
    for path, text in ros2_files(model, _environment(), _base(model)).items():
        out[path.removeprefix("include/")] = text
    return out


def _base(model: Model) -> str:
    return Path(model.file).name


def component_files(model: Model) -> dict[str, bytes]:
    """Every file of the C++ component folder, by relative path."""
    if model.language != "cpp":
        fail(EmitError, "E150", f"`{model.name}` is a {model.language} model: build it "
             "with -t python", model.span)
    view = component_view(model)
    env = _environment()
    sources = _render_sources(env, view)
    cmake = env.get_template("CMakeLists.txt.j2").render(view=view)
    config = env.get_template("config.yaml.j2").render(view=view)
    out = {path: text.encode("utf-8") for path, text in sources.files().items()}
    out |= {"CMakeLists.txt": cmake.encode("utf-8"),
            f"{model.name}.yaml": config.encode("utf-8")}
    folder = template_folder("cpp")
    out.update(runtime_files(folder.joinpath("hfsmc"), RUNTIME_FILES, INTERFACE_FILES,
                             (i.type for i in model.interfaces), into="include/hfsmc/"))
    out.update(runtime_files(folder, RUNTIME_SOURCES, INTERFACE_SOURCES,
                             (i.type for i in model.interfaces), into="src/"))
    for i in model.interfaces:  # a user's driver headers (docs/drivers.md)
        if i.cpp is not None and i.declaration is not None:
            out[f"include/{user_headers(model)[i.cpp.path]}"] = i.cpp.text.encode("utf-8")
    for path, text in ros2_files(model, env, view.base).items():  # docs/ros2-cpp.md
        out[path] = text.encode("utf-8")
    if any(i.type == "mavlink" for i in model.interfaces):
        from hfsmc.emit.mavgen import MavgenError, mavlink_headers

        try:
            out.update(mavlink_headers())
        except MavgenError as e:
            fail(EmitError, "E150", f"the MAVLink C headers cannot be generated: {e}", model.span)
    return out
