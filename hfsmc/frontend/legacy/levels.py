"""The levels of states the format readers build: a level's period, its states by id with
their initial mark, a transition's target, and (VisualHFSM 3 and 5, whose files list their
sub-automata flat) the tree of sub-automata that states hold by id (docs/legacy.md)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field

from hfsmc.errors import Span
from hfsmc.frontend.legacy.form import Level, LState, Space
from hfsmc.frontend.legacy.reader import Reader, norm_id
from hfsmc.frontend.xmlsource import Element

MAX_NESTING = 100  # sub-automata inside sub-automata: far beyond any real model


def read_period(r: Reader, level: Level, step: Element | None, tag: str) -> None:
    """The level's cycle written in ``step`` (whole milliseconds, at least 1)."""
    if step is None:
        return
    level.period_ms, level.period_span = r.milliseconds(step, tag)
    if level.period_ms == 0:
        r.error("E111", f"{tag} 0: a period is at least 1 ms", level.period_span)
        level.period_ms = None


@dataclass(eq=False)
class LevelStates:
    """The states of one level as they are read: by id, and the first marked initial.

    ``among`` ends the message of a duplicate id ("in sub-automaton 3"), ``owner``
    names the level in that of a second initial state ("sub-automaton 3")."""

    r: Reader
    level: Level
    among: str
    owner: str
    kept: str = ""  # said after "the first ... is kept"
    by_id: dict[str, LState] = field(default_factory=dict)

    def add(self, s: LState, id_span: Span, el: Element, initial: str, *notes: str) -> None:
        r, level = self.r, self.level
        if s.uid in self.by_id:
            r.error("E121", f"duplicate state id {s.uid} {self.among}", id_span, *notes)
        else:
            self.by_id[s.uid] = s
        level.states.append(s)
        if r.flag(el, initial):
            span = r.attr(el, initial)[1]
            if level.initial is None:
                level.initial, level.initial_span = s, span
            else:
                r.warn("W208", f"`{s.written}` is a second initial state of {self.owner}: the "
                       f"first, `{level.initial.written}`, is kept{self.kept}", span)


def find_target(r: Reader, source: LState, dest: str, span: Span, states: dict[str, LState],
                elsewhere: dict[str, str] | None = None, where: Callable[[str], str] = str,
                unknown: str = "", list_states: bool = False) -> LState | None:
    """The state of the level a transition goes to, or None: E133 when ``dest`` is the id of
    a state in ``elsewhere`` (``where`` says where, from ``elsewhere[id]``), else E132
    (``unknown`` says it in the format's words; ``list_states`` adds the level's states)."""
    target = states.get(norm_id(dest))
    if target is not None:
        return target
    other = (elsewhere or {}).get(norm_id(dest))
    if other is not None:
        r.error("E133", f"transition of `{source.written}` to state {dest}{where(other)}", span)
        return None
    notes = ["siblings: " + ", ".join(f"{k} ({v.written})" for k, v in states.items())] \
        if list_states else []
    r.error("E132", f"transition of `{source.written}` "
            f"{unknown or f'to id {dest}: no state has that id'}", span, *notes)
    return None


@dataclass(eq=False)
class Sub:
    """A sub-automaton as the file lists it, before the tree is built."""

    el: Element
    uid: str
    father: str | None  # None: not written
    groups: dict[str, list[Element]]
    states: list[Element]
    father_span: Span | None = None
    owner: LState | None = None  # the state that holds it, once reached


class SubAutomata(ABC):
    """A flat list of sub-automata as a tree of levels, from the root, through the id of the
    sub-automaton each state holds.  A format says how it reads a state and the
    transitions of a level, and what a level without an initial state is."""

    period_tag = ""  # the element that holds a sub-automaton's cycle
    initial_attr = ""  # the attribute that marks a state initial

    def __init__(self, r: Reader, glob: Space) -> None:
        self.r = r
        self.glob = glob
        self.subs: dict[str, Sub] = {}
        self.order: list[Sub] = []  # in the file's order

    def add(self, sub: Sub, id_span: Span) -> bool:
        """Whether ``sub`` is added: a second one of the same id is E121."""
        if sub.uid in self.subs:
            self.r.error("E121", f"duplicate sub-automaton id {sub.uid}", id_span,
                         f"the first is on line {self.r.span(self.subs[sub.uid].el).line}")
            return False
        self.subs[sub.uid] = sub
        self.order.append(sub)
        return True

    def one_root(self, roots: list[Sub], father: str) -> Sub:
        """The first root; each further one is E003 (``father`` says how the file marks one)."""
        for extra in roots[1:]:
            self.r.error("E003", f"a second root sub-automaton (id {extra.uid}, {father})",
                         self.r.span(extra.el), f"the root is sub-automaton {roots[0].uid}")
        return roots[0]

    def level(self, sub: Sub, depth: int) -> Level:
        r = self.r
        level = Level(r.span(sub.el))
        read_period(r, level, r.first(sub.groups, self.period_tag), self.period_tag)
        states = LevelStates(r, level, f"in sub-automaton {sub.uid}", f"sub-automaton {sub.uid}")
        for el in sub.states:
            s, id_span, son = self.state(el, sub)
            states.add(s, id_span, el, self.initial_attr)
            if son is not None:
                self.hold(s, son, sub, depth)
        self.transitions(sub, level, states.by_id)
        self.finish(sub, level)
        return level

    def hold(self, s: LState, son: tuple[str, Span], sub: Sub, depth: int) -> None:
        """State ``s`` of ``sub`` holds the sub-automaton of id ``son`` (not 0)."""
        r = self.r
        uid, span = son
        child = self.subs.get(uid)
        if child is None:
            r.error("E103", f"state `{s.written}` holds sub-automaton {uid}, which does not "
                    "exist", span)
        elif child.father == "0":
            r.error("E103", f"state `{s.written}` holds the root sub-automaton {uid}", span)
        elif child.owner is not None:
            r.error("E103", f"sub-automaton {uid} is already held by state "
                    f"`{child.owner.written}`", span)
        elif depth >= MAX_NESTING:
            r.error("E006", f"sub-automata nest deeper than {MAX_NESTING} levels", span)
        else:
            child.owner = s
            self.adopted(s, child, sub)
            s.child = self.level(child, depth + 1)

    # -- what a format says ----------------------------------------------------
    @abstractmethod
    def state(self, el: Element, sub: Sub) -> tuple[LState, Span, tuple[str, Span] | None]:
        """A state, where its id is written, and the id of the sub-automaton it holds and
        where, or None when it holds none."""
        ...

    @abstractmethod
    def transitions(self, sub: Sub, level: Level, states: dict[str, LState]) -> None:
        ...

    @abstractmethod
    def finish(self, sub: Sub, level: Level) -> None:
        """What a level without states or without an initial state is."""
        ...

    @abstractmethod
    def adopted(self, s: LState, child: Sub, sub: Sub) -> None:
        """``child`` is now held by state ``s`` of ``sub`` (before its level is read)."""
