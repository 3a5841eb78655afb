"""The intermediate representation: plain, frozen data with source spans.

Spans are excluded from equality (``compare=False``), so two models are equal
when they mean the same automaton, whatever file or format they came from:
the YAML → XML → YAML round trip is checked with ``==``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal, TypeAlias

from hfsmc.drivers import Driver
from hfsmc.errors import Span

Language = Literal["python", "cpp"]
ValueType = Literal["bool", "int", "float", "str", "list", "dict"]
# Literal values of variables and parameters, frozen: lists become tuples and
# mappings become DictValue, so that the IR stays hashable and comparable.
@dataclass(frozen=True, slots=True)
class DictValue:
    items: tuple[tuple[str, Value], ...]


Value: TypeAlias = bool | int | float | str | tuple["Value", ...] | DictValue | None

SNIPPET_KINDS = ("entry", "during", "exit", "when", "do", "functions", "on_shutdown")
# The functions every snippet may call (docs/interfaces.md lists them).
HELPERS = ("log", "elapsed", "now", "done", "active", "shutdown", "yaw_of",
           "euler_from_quaternion")
# Generated components name their own symbols with this prefix; a model may not.
RESERVED_PREFIX = "_hfsm"
# The root automaton's period when a model does not give one.
DEFAULT_ROOT_PERIOD_MS = 100


@dataclass(frozen=True, slots=True)
class Code:
    """A snippet of user code and where it sits in the model file.

    Line ``k`` (0-based) of ``text`` is at model line ``span.line + k``; its
    first character is at ``span.col`` for ``k == 0`` and at ``cont_col`` plus
    its own indentation after that.
    """

    text: str
    span: Span = field(compare=False)
    cont_col: int = field(default=1, compare=False)
    # Folded YAML scalars: (offset in text, model line, model col) of each source line.
    segments: tuple[tuple[int, int, int], ...] = field(default=(), compare=False)

    def position(self, line: int, col: int) -> Span:
        """Model position of 1-based (line, col) inside the snippet text."""
        if self.segments:
            rows = self.text.split("\n")
            offset = sum(len(r) + 1 for r in rows[:max(line - 1, 0)]) + max(col - 1, 0)
            best = self.segments[0]
            for seg in self.segments:
                if seg[0] <= offset:
                    best = seg
            return Span(self.span.file, best[1], best[2] + offset - best[0])
        if line <= 1:
            return Span(self.span.file, self.span.line, self.span.col + max(col - 1, 0))
        return Span(self.span.file, self.span.line + line - 1, self.cont_col + max(col - 1, 0))


@dataclass(frozen=True, slots=True)
class Transition:
    index: int  # position in the source state's list (trace `fire` records)
    target: str  # a sibling's name (or the state itself)
    when: Code | None
    after_us: int | None  # microseconds since the source state was entered
    do: Code | None
    name: str | None
    span: Span = field(compare=False)
    target_span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class State:
    name: str
    path: str  # "Follow/Track"; the root state's path is ""
    entry: Code | None
    during: Code | None
    exit: Code | None
    transitions: tuple[Transition, ...]
    final: bool
    # Its sub-automaton (one), its parallel regions (two or more, in the order written), or none.
    automata: tuple[Automaton, ...]
    span: Span = field(compare=False)

    @property
    def composite(self) -> bool:
        return bool(self.automata)

    @property
    def parallel(self) -> bool:
        """The state holds regions (docs/semantics.md: regions)."""
        return bool(self.automata) and self.automata[0].region is not None

    @property
    def automaton(self) -> Automaton | None:
        """Its one sub-automaton; None for a leaf and for a state with regions."""
        return self.automata[0] if len(self.automata) == 1 and self.automata[0].region is None \
            else None


@dataclass(frozen=True, slots=True)
class Automaton:
    """The sub-automaton held by a composite state (or the root), or one of its regions."""

    owner: str  # path of the owning state ("" for the root)
    region: str | None  # the region's name; None for a state's one sub-automaton and the root
    period_ms: int  # resolved: inherited from the parent when not written
    period_written: bool  # whether the model wrote it (for round trips)
    initial: str
    history: bool
    states: tuple[State, ...]
    span: Span = field(compare=False)
    initial_span: Span = field(compare=False)
    # Set on the root sub-automaton of a used file where it is used (`use`): its states'
    # paths continue the using state's, their snippets run in the instance's namespace.
    instance: Instance | None = None

    @property
    def path(self) -> str:
        """The prefix of its states' paths: the owner's path, and the region's name if any."""
        if self.region is None:
            return self.owner
        return f"{self.owner}/{self.region}" if self.owner else self.region

    def state(self, name: str) -> State | None:
        for s in self.states:
            if s.name == name:
                return s
        return None


@dataclass(frozen=True, slots=True)
class Binding:
    """One `with` entry: a parameter or an interface of the used model, and what it gets."""

    name: str  # the used model's parameter or interface
    kind: Literal["parameter", "interface"]
    value: Value  # a literal (parameters), None when bound to a name of the using model
    source: str | None  # the using model's parameter (`$NAME`) or interface bound to it
    span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class Instance:
    """A sub-automaton taken from another model file (`use`), as it is used at one state.

    ``model`` is the used file built and checked on its own (paths relative to its root,
    spans in its file); the using state's ``automata`` holds the same states again with
    paths that continue the using state's (``TakeOff/Climb``) and this instance set on
    their automaton.  ``bindings`` are what `with` says, in the order written; a
    parameter it does not name keeps its default, an interface binds to the using
    model's interface of the same name (``Instance.binding`` says which, for each).
    """

    file: str  # the used file's path, as hfsmc reads it (relative to the using file's folder)
    written: str  # as written after `use:`
    model: Model
    bindings: tuple[Binding, ...]
    span: Span = field(compare=False)  # the `use` value in the using file

    def binding(self, name: str) -> Binding:
        """What the used model's parameter or interface ``name`` gets in this instance."""
        for b in self.bindings:
            if b.name == name:
                return b
        for p in self.model.parameters:
            if p.name == name:
                return Binding(name, "parameter", p.default, None, self.span)
        return Binding(name, "interface", None, name, self.span)


@dataclass(frozen=True, slots=True)
class Import:
    text: str  # as written: "math", "numpy as np", "from math import pi", "<vector>"
    span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class DriverFile:
    """A user's driver file (``type: driver``; docs/drivers.md), read at compile time."""

    written: str  # as the model writes it, relative to the model's folder
    path: str  # the model's folder joined with it
    text: str
    span: Span = field(compare=False)  # the key's position in the model


@dataclass(frozen=True, slots=True)
class Ros2Topic:
    """One entry of a ``ros2`` interface's ``subscribe`` or ``publish`` (docs/ros2.md)."""

    name: str  # the identifier snippets use: `robot.scan`, `robot.publish("cmd_vel", m)`
    topic: str  # the ROS name as written (relative, absolute or `~/x`)
    type: str  # `pkg/msg/Name` as written (a ROS 1 `pkg/Name` too)
    qos: str | tuple[tuple[str, str | int], ...]  # a profile name, or the three written
    span: Span = field(compare=False)  # the entry's key
    type_span: Span = field(compare=False)
    topic_span: Span = field(compare=False)


SERVICE_TIMEOUT_US = 10_000_000  # a service call's time limit when the model gives none


@dataclass(frozen=True, slots=True)
class Ros2Rpc:
    """One entry of a ``ros2`` interface's ``actions`` or ``services`` (SPEC 5.3)."""

    name: str  # the identifier snippets use: `robot.send_goal("navigate", g)`
    ros_name: str  # the action's or service's ROS name as written
    type: str  # `pkg/action/Name` or `pkg/srv/Name`
    timeout_us: int | None  # the time limit of each goal or call, as written (None: none)
    span: Span = field(compare=False)
    type_span: Span = field(compare=False)
    name_span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class MsgRef:
    """One of a ``ros2`` interface's ``messages``: the model's own `.msg` file."""

    written: str  # relative to the model's folder: `my_msgs/msg/Detection.msg`
    path: str  # the model's folder joined with it
    span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class Ros2Settings:
    """A ``ros2`` interface's keys (SPEC 5.2); None where the model leaves the default."""

    node: str | None
    namespace: str | None
    domain: int | None
    distro: str | None
    subscribe: tuple[Ros2Topic, ...]
    publish: tuple[Ros2Topic, ...]
    messages: tuple[MsgRef, ...]
    actions: tuple[Ros2Rpc, ...] = ()
    services: tuple[Ros2Rpc, ...] = ()
    # SPEC 5.4: publish the automaton on /fsm_viewer and ~/hfsm/status (None: not written,
    # off); Python components only.
    introspection: bool | None = None

    @property
    def distro_or_default(self) -> str:
        return self.distro or "jazzy"


@dataclass(frozen=True, slots=True)
class Interface:
    name: str
    type: str  # mavlink | camera | ros_topic | ice | driver | ros2
    url: str | None
    options: tuple[tuple[str, str], ...]
    span: Span = field(compare=False)
    python: DriverFile | None = None  # type driver: the Python driver
    cpp: DriverFile | None = None  # type driver: the C++ driver's header
    # type driver: what the driver of the model's language declares (None: not read)
    declaration: Driver | None = field(default=None, compare=False)
    ros2: Ros2Settings | None = None  # type ros2: its keys

    @property
    def kind(self) -> str:
        """The interface's type as components and recordings name it: a user driver's
        KIND (``gadget``), else ``type``."""
        return self.declaration.type if self.declaration is not None else self.type


@dataclass(frozen=True, slots=True)
class Parameter:
    name: str
    type: ValueType
    default: Value
    span: Span = field(compare=False)
    description: str | None = None  # shown by the component's --help


@dataclass(frozen=True, slots=True)
class Variable:
    name: str
    type: str  # a ValueType, or any C++ type in a cpp model
    init: Value
    typed: bool = field(compare=False)  # written as {type, init}, not a bare literal
    span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class Model:
    name: str
    language: Language
    description: str | None
    imports: tuple[Import, ...]
    interfaces: tuple[Interface, ...]
    parameters: tuple[Parameter, ...]
    variables: tuple[Variable, ...]
    functions: Code | None
    on_shutdown: Code | None
    on_interrupt: str | None
    interrupt_timeout_us: int | None
    root: Automaton
    file: str = field(compare=False)
    span: Span = field(compare=False)
    on_interrupt_span: Span | None = field(default=None, compare=False)
    interrupt_timeout_span: Span | None = field(default=None, compare=False)
    # `time_limit`: the mission's time limit, as --time-limit (which overrides it) gives one.
    time_limit_us: int | None = None
    time_limit_span: Span | None = field(default=None, compare=False)
    # States whose `use` could not be built (the error says why): checks that would only
    # repeat it (done() there, active() paths below them) leave them out.
    unresolved_uses: tuple[str, ...] = field(default=(), compare=False)
    source: str = field(default="", compare=False, repr=False)  # the text it was built from

    def states(self) -> Iterator[State]:
        """Every state, depth first, parents before children, in model order (a state's
        regions in the order written)."""
        stack = list(reversed(self.root.states))
        while stack:
            s = stack.pop()
            yield s
            for a in reversed(s.automata):
                stack.extend(reversed(a.states))

    def own_states(self) -> Iterator[State]:
        """The states this model's file writes, in the order of ``states()``: those of
        used files' instances (checked with the used file) left out; the using state stays."""
        stack = list(reversed(self.root.states))
        while stack:
            s = stack.pop()
            yield s
            for a in reversed(s.automata):
                if a.instance is None:
                    stack.extend(reversed(a.states))

    def automata(self) -> Iterator[Automaton]:
        """Every sub-automaton and region in pre-order: each one, then those inside its
        states, before its next sibling (the order ticks due together run in)."""
        stack = [self.root]
        while stack:
            a = stack.pop()
            yield a
            for s in reversed(a.states):
                stack.extend(reversed(s.automata))

    def find(self, path: str) -> State | None:
        """The state at ``path`` (region names included: ``Mission/Watch/Ok``)."""
        autos: tuple[Automaton, ...] = (self.root,)
        state: State | None = None
        parts = path.split("/")
        k = 0
        while k < len(parts):
            if len(autos) > 1 or (autos and autos[0].region is not None):
                autos = tuple(a for a in autos if a.region == parts[k])
                k += 1
                if not autos or k == len(parts):
                    return None
            if not autos:
                return None
            state = autos[0].state(parts[k])
            if state is None:
                return None
            autos = state.automata
            k += 1
        return state

    def automaton_at(self, path: str) -> Automaton | None:
        """The sub-automaton or region whose states' paths start with ``path``."""
        for a in self.automata():
            if a.path == path:
                return a
        return None
