"""The intermediate representation: plain, frozen data with source spans.

Spans are excluded from equality (``compare=False``), so two models are equal
when they mean the same automaton, whatever file or format they came from:
the YAML → XML → YAML round trip is checked with ``==``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal, TypeAlias

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
HELPERS = ("log", "elapsed", "now", "done", "active", "shutdown")
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
    automaton: Automaton | None
    span: Span = field(compare=False)

    @property
    def composite(self) -> bool:
        return self.automaton is not None


@dataclass(frozen=True, slots=True)
class Automaton:
    """The sub-automaton held by a composite state (or the root)."""

    owner: str  # path of the owning state ("" for the root)
    period_ms: int  # resolved: inherited from the parent when not written
    period_written: bool  # whether the model wrote it (for round trips)
    initial: str
    history: bool
    states: tuple[State, ...]
    span: Span = field(compare=False)
    initial_span: Span = field(compare=False)

    def state(self, name: str) -> State | None:
        for s in self.states:
            if s.name == name:
                return s
        return None


@dataclass(frozen=True, slots=True)
class Import:
    text: str  # as written: "math", "numpy as np", "from math import pi", "<vector>"
    span: Span = field(compare=False)


@dataclass(frozen=True, slots=True)
class Interface:
    name: str
    type: str  # mavlink | camera | ros_topic | ice
    url: str | None
    options: tuple[tuple[str, str], ...]
    span: Span = field(compare=False)


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

    def states(self) -> Iterator[State]:
        """Every state, depth first, parents before children, in model order."""
        stack = list(reversed(self.root.states))
        while stack:
            s = stack.pop()
            yield s
            if s.automaton is not None:
                stack.extend(reversed(s.automaton.states))

    def automata(self) -> Iterator[Automaton]:
        """The root sub-automaton, then every nested one, parents first."""
        yield self.root
        for s in self.states():
            if s.automaton is not None:
                yield s.automaton

    def find(self, path: str) -> State | None:
        auto: Automaton | None = self.root
        state: State | None = None
        for part in path.split("/"):
            if auto is None:
                return None
            state = auto.state(part)
            if state is None:
                return None
            auto = state.automaton
        return state
