"""The structure both back ends print, computed once: states and sub-automata numbered
as the schedulers walk them, and per state its snippets and transitions.

A back end subclasses ``Walk`` and ``Snippet`` and says how one snippet becomes text in
its language (``make_snippet``); everything else (numbering, owners, comments, the
target's ``during`` that runs after a transition) is the same for Python and C++ and
comes back from ``Walk.machine()`` as a ``MachineView``, which each back end's
component view holds as ``machine``.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

from hfsmc import __version__
from hfsmc.durations import format_us
from hfsmc.emit.comments import comment_text
from hfsmc.ir import Automaton, Code, Instance, Model, State
from hfsmc.model_sources import model_hash, model_sources


@dataclass(frozen=True, slots=True)
class Snippet:
    """One snippet of the model as a back end prints it (subclassed per back end).

    A snippet of a state inside an instance of a used file (`use`) is defined in that
    file's code unit, not in the component's own code: the walk of the using model makes
    only a reference to it (this base class), whose ``call`` names it there."""

    sid: int  # its number, in the order of its unit's generated code
    kind: str  # entry | during | exit | when | do | functions | on_shutdown
    owner: int  # state index; len(states) for the root's snippets
    where: str  # comment text: "blinker.yaml:31 entry of Blinking/Lit"

    @property
    def call(self) -> str:
        """What calls it from the component's state functions."""
        return f"_hfsm_s{self.sid}"


@dataclass(frozen=True, slots=True)
class SnippetRef(Snippet):
    """A snippet defined in the code unit of instance ``instance`` (`use`)."""

    instance: int

    @property
    def call(self) -> str:
        return f"_hfsm_i{self.instance}._hfsm_s{self.sid}"


S = TypeVar("S", bound=Snippet)  # a back end's snippet view


@dataclass(frozen=True, slots=True)
class AutomatonView:
    """A sub-automaton or a region, numbered in pre-order (the order ticks due together run)."""

    index: int
    owner: int  # index of the composite state holding it; -1 for the root
    region: str | None  # the region's name; None for a state's one sub-automaton and the root
    use: str | None  # the used file it comes from (`use`), as written; None for the others
    period_ms: int
    initial: int  # index of its initial state
    history: bool


@dataclass(frozen=True, slots=True)
class InstanceView:
    """An instance of a used file (`use`): its states are numbered like the others (a
    contiguous run, from ``base``); its snippets are defined in its file's code unit."""

    number: int  # 1, 2, ... in pre-order: the component names it `_hfsm_i{number}`
    unit: str  # the code unit of its file (one per used file): an identifier
    instance: Instance
    owner: int  # index of the using state
    base: int  # index of its first state: a state's index in the used model, plus base
    count: int  # its number of states (those of instances inside it too)
    parent: int  # the instance it is used in (its number), 0 for the component's own model
    prefix: str  # the using state's path: active() inside reads paths below it
    sid0: int  # where its snippets start in the component's table of every snippet
    n_snippets: int


@dataclass(frozen=True, slots=True)
class UnitView:
    """A used file's code, defined once and instantiated per `use`."""

    name: str  # an identifier, unique in the component
    file: str  # the used file
    model: Model


@dataclass(frozen=True, slots=True)
class TransitionView(Generic[S]):
    index: int
    target: int
    after_us: int | None
    when: S | Snippet | None
    do: S | Snippet | None
    target_during: S | Snippet | None  # runs after entering the target, in the same tick
    comment: str


@dataclass(frozen=True, slots=True)
class StateView(Generic[S]):
    index: int
    path: str
    container: int  # index of the sub-automaton (or region) holding it
    children: tuple[AutomatonView, ...]  # its sub-automaton, or its regions in order; () for a leaf
    final: bool
    entry: S | Snippet | None
    during: S | Snippet | None
    exit: S | Snippet | None
    transitions: tuple[TransitionView[S], ...]
    comment: str


@dataclass(frozen=True, slots=True)
class MachineView(Generic[S]):
    """The state machine as both back ends print it: states, sub-automata, snippets."""

    functions: S | None
    on_shutdown: S | None
    states: tuple[StateView[S], ...]
    automata: tuple[AutomatonView, ...]
    snippets: tuple[S, ...]  # the model's own, in sid order
    on_interrupt: int  # index of the state to go to on an interrupt, or -1
    instances: tuple[InstanceView, ...]  # in pre-order
    units: tuple[UnitView, ...]  # one per used file, in order of first use
    sources: tuple[tuple[str, str], ...]  # (path, text): the model, then each used file
    model_hash: str  # of the sources (hfsmc/model_sources.py)
    version: str  # of the hfsmc that generated the component


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
        self._instances()
        # Sub-automata numbered parents first, as the scheduler walks them.
        self.automata: list[AutomatonView] = []
        self.auto_of: dict[str, int] = {}  # the prefix of its states' paths -> index
        for auto in model.automata():
            self.auto_of[auto.path] = len(self.automata)
            owner = self.index[auto.owner] if auto.owner else -1
            initial = self.index[f"{auto.path}/{auto.initial}" if auto.path else auto.initial]
            self.automata.append(AutomatonView(
                len(self.automata), owner, auto.region,
                auto.instance.written if auto.instance is not None else None,
                auto.period_ms, initial, auto.history))

    def _instances(self) -> None:
        """Number the instances of used files, and say which one each state is in."""
        self.unit_of = [0] * len(self.states)  # per state: its instance's number, 0 for none
        self.next_sid: dict[int, int] = {}  # per instance: the number of its next snippet
        units: dict[str, UnitView] = {}  # by used file
        found: list[tuple[Instance, int, int]] = []  # instance, base, number of states
        for auto in self.model.automata():  # pre-order: an instance before those inside it
            inst = auto.instance
            if inst is None or not auto.states:
                continue
            base = self.index[auto.states[0].path]
            count = sum(1 for _ in _states_below(auto))
            found.append((inst, base, count))
            for i in range(base, base + count):
                self.unit_of[i] = len(found)
            if inst.file not in units:
                name = _identifier(Path(inst.file).stem)
                taken = {u.name for u in units.values()}
                unique, k = name, 2
                while unique in taken:
                    unique, k = f"{name}_{k}", k + 1
                units[inst.file] = UnitView(unique, inst.file, inst.model)
            self.next_sid[len(found)] = 1 if inst.model.functions is not None else 0
        self.unit_by_file = units
        self.units = tuple(units.values())
        self.found = found

    def instance_views(self) -> tuple[InstanceView, ...]:
        """The instances, once every snippet is numbered (``machine`` does it)."""
        out: list[InstanceView] = []
        sid0 = len(self.snippets)
        for number, (inst, base, count) in enumerate(self.found, start=1):
            owner = base - 1  # the using state comes just before its sub-automaton's states
            out.append(InstanceView(number, self.unit_by_file[inst.file].name,
                                    inst, owner, base, count, self.unit_of[owner],
                                    self.states[owner].path, sid0, self.next_sid[number]))
            sid0 += self.next_sid[number]
        return tuple(out)

    @abstractmethod
    def make_snippet(self, sid: int, kind: str, owner: int, code: Code, where: str) -> S:
        """The back end's view of one snippet; ``where`` is its comment text."""

    def snippet(self, kind: str, owner: int, code: Code | None, what: str = "") -> S | Snippet | None:
        if code is None:
            return None
        unit = self.unit_of[owner] if owner < self.root else 0
        if unit:  # defined in its file's code unit: numbered as that unit's walk numbers it
            sid = self.next_sid[unit]
            self.next_sid[unit] = sid + 1
            return SnippetRef(sid, kind, owner, "", unit)
        path = self.states[owner].path if owner < self.root else ""
        where = f"{self.base}:{code.span.line} {kind}" + (f" of {path}" if path else "") + what
        view = self.make_snippet(len(self.snippets), kind, owner, code, comment_text(where))
        self.snippets.append(view)
        return view

    def machine(self) -> MachineView[S]:
        """Every snippet made, in the order of the generated code, and the tables."""
        m = self.model
        functions = self._own(self.snippet("functions", self.root, m.functions))
        states = tuple(self.state_views())
        on_shutdown = self._own(self.snippet("on_shutdown", self.root, m.on_shutdown))
        sources = model_sources(m)
        return MachineView(functions, on_shutdown, states, tuple(self.automata),
                           tuple(self.snippets),
                           self.index[m.on_interrupt] if m.on_interrupt is not None else -1,
                           self.instance_views(), self.units, sources, model_hash(sources),
                           __version__)

    def _own(self, view: S | Snippet | None) -> S | None:
        """A snippet of the root: always the model's own."""
        assert view is None or not isinstance(view, SnippetRef)
        return view  # type: ignore[return-value]

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
                          comment_text(f"{Path(s.span.file).name}:{s.span.line} {s.path}"))
                for (i, s), (entry, during, exit_) in zip(enumerate(self.states), own, strict=True)]

    def _own_snippets(self, i: int, s: State) -> tuple[S | Snippet | None, S | Snippet | None,
                                                      S | Snippet | None]:
        return (self.snippet("entry", i, s.entry), self.snippet("during", i, s.during),
                self.snippet("exit", i, s.exit))

    def _transitions(self, i: int, s: State,
                     own: list[tuple[S | Snippet | None, S | Snippet | None, S | Snippet | None]]
                     ) -> tuple[TransitionView[S], ...]:
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
                comment_text(f"{Path(t.span.file).name}:{t.span.line}{label} {s.path} -> "
                             f"{self.states[target].path}{cond}")))
        return tuple(out)


def _states_below(auto: Automaton) -> Iterator[State]:
    for s in auto.states:
        yield s
        for a in s.automata:
            yield from _states_below(a)


def _identifier(text: str) -> str:
    """``text`` made an identifier (a used file's stem names its code unit)."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", text) or "unit"
    return out if not out[0].isdigit() else f"u{out}"
