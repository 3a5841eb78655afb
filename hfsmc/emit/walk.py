"""The structure both back ends print, computed once: states and sub-automata numbered
as the schedulers walk them, and per state its snippets and transitions.

A back end subclasses ``Walk`` and ``Snippet`` and says how one snippet becomes text in
its language (``make_snippet``); everything else (numbering, owners, comments, the
target's ``during`` that runs after a transition) is the same for Python and C++ and
comes back from ``Walk.machine()`` as a ``MachineView``, which each back end's
component view holds as ``machine``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

from hfsmc.durations import format_us
from hfsmc.emit.comments import comment_text
from hfsmc.ir import Code, Model, State


@dataclass(frozen=True, slots=True)
class Snippet:
    """One snippet of the model as a back end prints it (subclassed per back end)."""

    sid: int  # its number, in the order of the generated code
    kind: str  # entry | during | exit | when | do | functions | on_shutdown
    owner: int  # state index; len(states) for the root's snippets
    where: str  # comment text: "blinker.yaml:31 entry of Blinking/Lit"


S = TypeVar("S", bound=Snippet)  # a back end's snippet view


@dataclass(frozen=True, slots=True)
class AutomatonView:
    """A sub-automaton or a region, numbered in pre-order (the order ticks due together run)."""

    index: int
    owner: int  # index of the composite state holding it; -1 for the root
    region: str | None  # the region's name; None for a state's one sub-automaton and the root
    period_ms: int
    initial: int  # index of its initial state
    history: bool


@dataclass(frozen=True, slots=True)
class TransitionView(Generic[S]):
    index: int
    target: int
    after_us: int | None
    when: S | None
    do: S | None
    target_during: S | None  # runs after entering the target, in the same tick
    comment: str


@dataclass(frozen=True, slots=True)
class StateView(Generic[S]):
    index: int
    path: str
    container: int  # index of the sub-automaton (or region) holding it
    children: tuple[AutomatonView, ...]  # its sub-automaton, or its regions in order; () for a leaf
    final: bool
    entry: S | None
    during: S | None
    exit: S | None
    transitions: tuple[TransitionView[S], ...]
    comment: str


@dataclass(frozen=True, slots=True)
class MachineView(Generic[S]):
    """The state machine as both back ends print it: states, sub-automata, snippets."""

    functions: S | None
    on_shutdown: S | None
    states: tuple[StateView[S], ...]
    automata: tuple[AutomatonView, ...]
    snippets: tuple[S, ...]  # in sid order
    on_interrupt: int  # index of the state to go to on an interrupt, or -1


class Walk(ABC, Generic[S]):
    """One pass over the IR. Snippets are numbered in the order they are made:
    ``functions``, then entry/during/exit of every state, then the transitions'
    when/do, then ``on_shutdown`` (the order of the generated code)."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self.base = Path(model.file).name
        self.states: list[State] = list(model.states())
        self.index = {s.path: i for i, s in enumerate(self.states)}
        self.root = len(self.states)  # the owner of the root's snippets
        self.snippets: list[S] = []
        # Sub-automata numbered parents first, as the scheduler walks them.
        self.automata: list[AutomatonView] = []
        self.auto_of: dict[str, int] = {}  # the prefix of its states' paths -> index
        for auto in model.automata():
            self.auto_of[auto.path] = len(self.automata)
            owner = self.index[auto.owner] if auto.owner else -1
            initial = self.index[f"{auto.path}/{auto.initial}" if auto.path else auto.initial]
            self.automata.append(AutomatonView(len(self.automata), owner, auto.region,
                                               auto.period_ms, initial, auto.history))

    @abstractmethod
    def make_snippet(self, sid: int, kind: str, owner: int, code: Code, where: str) -> S:
        """The back end's view of one snippet; ``where`` is its comment text."""

    def snippet(self, kind: str, owner: int, code: Code | None, what: str = "") -> S | None:
        if code is None:
            return None
        path = self.states[owner].path if owner < self.root else ""
        where = f"{self.base}:{code.span.line} {kind}" + (f" of {path}" if path else "") + what
        view = self.make_snippet(len(self.snippets), kind, owner, code, comment_text(where))
        self.snippets.append(view)
        return view

    def machine(self) -> MachineView[S]:
        """Every snippet made, in the order of the generated code, and the tables."""
        m = self.model
        functions = self.snippet("functions", self.root, m.functions)
        states = tuple(self.state_views())
        on_shutdown = self.snippet("on_shutdown", self.root, m.on_shutdown)
        return MachineView(functions, on_shutdown, states, tuple(self.automata),
                           tuple(self.snippets),
                           self.index[m.on_interrupt] if m.on_interrupt is not None else -1)

    def target(self, s: State, name: str) -> int:
        """Index of the sibling ``name`` of state ``s``."""
        parent = s.path.rpartition("/")[0]
        return self.index[f"{parent}/{name}" if parent else name]

    def state_views(self) -> list[StateView[S]]:
        """Every state with its snippets and transitions, in state order."""
        own = [self._own_snippets(i, s) for i, s in enumerate(self.states)]
        return [StateView(i, s.path, self.auto_of[s.path.rpartition("/")[0]],
                          tuple(self.automata[self.auto_of[a.path]] for a in s.automata),
                          s.final, entry, during, exit_, self._transitions(i, s, own),
                          comment_text(f"{self.base}:{s.span.line} {s.path}"))
                for (i, s), (entry, during, exit_) in zip(enumerate(self.states), own, strict=True)]

    def _own_snippets(self, i: int, s: State) -> tuple[S | None, S | None, S | None]:
        return (self.snippet("entry", i, s.entry), self.snippet("during", i, s.during),
                self.snippet("exit", i, s.exit))

    def _transitions(self, i: int, s: State,
                     own: list[tuple[S | None, S | None, S | None]]) -> tuple[TransitionView[S], ...]:
        out: list[TransitionView[S]] = []
        for t in s.transitions:
            target = self.target(s, t.target)
            label = f" {t.name}:" if t.name else ""
            after = format_us(t.after_us) if t.after_us is not None else ""
            when = self.snippet("when", i, t.when, f" (transition {t.index})")
            do = self.snippet("do", i, t.do, f" (transition {t.index})")
            cond = (f" after {after}" if after else "") + (" when ..." if when else "")
            out.append(TransitionView(
                t.index, target, t.after_us, when, do, own[target][1],
                comment_text(f"{self.base}:{t.span.line}{label} {s.path} -> "
                             f"{self.states[target].path}{cond}")))
        return tuple(out)
