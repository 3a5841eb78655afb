"""VisualHFSM 5 files into the neutral legacy form.

The format: a flat list of ``<SubAutomata id idFather>`` (the one with
``idFather="0"`` is the root), each with its ``<state>`` elements (a state
names the sub-automaton it holds in ``<idSubautomataSon>``, 0 for none), its
``<transition>`` elements (``<origin>``, ``<destiny>``, ``<transcode>``,
``<trans type="condition|time">``), ``<iteration_time>`` (its cycle, ms),
``<variables>`` and ``<functions>``; then ``<libraries>`` and ``<config>``
(ICE interfaces).  All code of the file shares one namespace (the generated
automaton object, ``self`` in Python).  A sub-automaton resumed where it was
left when its state was entered again: ``history: true``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hfsmc.errors import Span
from hfsmc.frontend.legacy.form import (
    Context,
    Interface,
    Legacy,
    Level,
    LState,
    Space,
    Transition,
    ice_interface,
)
from hfsmc.frontend.legacy.reader import Reader, norm_id
from hfsmc.frontend.xmlsource import Element

MAX_NESTING = 100  # sub-automata inside sub-automata: far beyond any real model
# Modules VisualHFSM's generated Python imported for the code.
_IMPLICIT = ("sys", "threading", "time", "traceback")


@dataclass(eq=False)
class _Sub:
    el: Element
    uid: str
    father: str
    father_span: Span
    groups: dict[str, list[Element]]
    states: list[tuple[LState, Element]] = field(default_factory=list)
    owner: LState | None = None


def read(r: Reader, root: Element) -> Legacy | None:
    groups = r.children(root, ("libraries", "config"), ("SubAutomata",))
    glob = Space("", "the automaton", r.span(root))
    glob.ctx = Context({k: (glob,) for k in ("self", "global", "local", "bare")})
    subs: dict[str, _Sub] = {}
    order: list[_Sub] = []
    for el in groups.get("SubAutomata", []):
        sub = _sub(r, el, glob)
        if sub is None:
            continue
        if sub.uid in subs:
            r.error("E121", f"duplicate sub-automaton id {sub.uid}", r.attr(el, "id")[1],
                    f"the first is on line {r.span(subs[sub.uid].el).line}")
            continue
        subs[sub.uid] = sub
        order.append(sub)
    roots = [s for s in order if s.father == "0"]
    if not roots:
        r.error("E102", "no root `<SubAutomata>` (the one with idFather=\"0\")", r.span(root))
        return None
    for extra in roots[1:]:
        r.error("E003", f"a second root sub-automaton (id {extra.uid}, idFather=\"0\")",
                r.span(extra.el), f"the root is sub-automaton {roots[0].uid}")
    reader = _Levels(r, subs, glob)
    level = reader.level(roots[0], 0)
    held = {norm_id(son.text or "") for sub in order for st in sub.groups.get("state", [])
            if (son := st.find("idSubautomataSon")) is not None}
    for sub in order:
        if sub is not roots[0] and sub.owner is None and sub.father != "0":
            why = "the state that holds it is not reached from the root either" \
                if sub.uid in held else f"no state has idSubautomataSon {sub.uid}"
            r.error("E103", f"sub-automaton {sub.uid} is not reached from the root "
                    f"sub-automaton: {why}", r.span(sub.el))
    interfaces: list[Interface] = []
    config = r.first(groups, "config")
    if config is not None:
        for el in r.children(config, (), ("iceinterface",)).get("iceinterface", []):
            found = _ice(r, el)
            if found is not None:
                interfaces.append(found)
    libraries: list[tuple[str, Span]] = []
    libs = r.first(groups, "libraries")
    if libs is not None:
        for lib in r.children(libs, (), ("library",)).get("library", []):
            text, span = r.value(lib)
            if text:
                libraries.append((text, span))
    dropped = [(r.span(root), "the layout of the diagram (posx, posy)")]
    return Legacy(level, [glob], interfaces, libraries, True, _IMPLICIT, dropped)


def _sub(r: Reader, el: Element, glob: Space) -> _Sub | None:
    uid, uid_span = r.attr(el, "id")
    father, father_span = r.attr(el, "idFather")
    if uid is None or not uid.strip():
        r.error("E102", "this `<SubAutomata>` has no `id`", uid_span)
        return None
    if father is None or not father.strip():
        r.error("E102", f"sub-automaton {uid} has no `idFather` (0 for the root)", father_span)
        return None
    groups = r.children(el, ("iteration_time", "variables", "functions"), ("state", "transition"))
    for tag in ("functions", "variables"):
        found = r.first(groups, tag)
        if found is not None:
            (glob.functions if tag == "functions" else glob.variables).append(r.text(found))
    return _Sub(el, norm_id(uid), norm_id(father), father_span, groups)


def _ice(r: Reader, el: Element) -> Interface | None:
    tags = ("servertype", "nameinterface", "nameproxy", "topic", "ip", "port", "interface")
    g = r.children(el, tags)
    t = {tag: r.value(found) for tag in tags if (found := r.first(g, tag)) is not None}
    name, span = t.get("nameinterface", ("", r.span(el)))
    if not name:
        r.error("E102", "this `<iceinterface>` has no `<nameinterface>`", span)
        return None

    def get(tag: str) -> str:
        return t.get(tag, ("", span))[0]

    return ice_interface(name, get("servertype"), get("nameproxy"), get("ip"), get("port"),
                         get("interface"), get("topic"), r.span(el))


class _Levels:
    """The tree of sub-automata, from the root, through each state's idSubautomataSon."""

    def __init__(self, r: Reader, subs: dict[str, _Sub], glob: Space) -> None:
        self.r = r
        self.subs = subs
        self.glob = glob
        self.where: dict[str, str] = {}  # state id -> id of its sub-automaton
        for sub in subs.values():
            for st in sub.groups.get("state", []):
                self.where.setdefault(norm_id(st.get("id", "")), sub.uid)

    def level(self, sub: _Sub, depth: int) -> Level:
        r = self.r
        level = Level(r.span(sub.el))
        step = r.first(sub.groups, "iteration_time")
        if step is not None:
            level.period_ms, level.period_span = r.milliseconds(step, "iteration_time")
            if level.period_ms == 0:
                r.error("E111", "iteration_time 0: a period is at least 1 ms", level.period_span)
                level.period_ms = None
        by_id: dict[str, LState] = {}
        for el in sub.groups.get("state", []):
            s, son, son_span = self.state(el)
            if s.uid in by_id:
                r.error("E121", f"duplicate state id {s.uid} in sub-automaton {sub.uid}",
                        r.attr(el, "id")[1])
            else:
                by_id[s.uid] = s
            level.states.append(s)
            if r.flag(el, "initial"):
                if level.initial is None:
                    level.initial, level.initial_span = s, r.attr(el, "initial")[1]
                else:
                    r.warn("W208", f"`{s.written}` is a second initial state of sub-automaton "
                           f"{sub.uid}: the first, `{level.initial.written}`, is kept",
                           r.attr(el, "initial")[1])
            if son not in ("", "0"):
                self.child(s, son, son_span, sub, depth)
        for el in sub.groups.get("transition", []):
            found = self.transition(el, sub, by_id)
            if found is not None:
                found[0].transitions.append(found[1])
        if level.states and level.initial is None:
            r.error("E130", f"sub-automaton {sub.uid} has no initial state", r.span(sub.el),
                    f"mark one of {', '.join(s.written for s in level.states)} "
                    "with initial=\"true\"")
        if not level.states:
            r.error("E102", f"sub-automaton {sub.uid} has no `<state>`", r.span(sub.el))
        return level

    def child(self, s: LState, son: str, son_span: Span, sub: _Sub, depth: int) -> None:
        r = self.r
        child = self.subs.get(son)
        if child is None:
            r.error("E103", f"state `{s.written}` holds sub-automaton {son}, which does not "
                    "exist", son_span)
        elif child.father == "0":
            r.error("E103", f"state `{s.written}` holds the root sub-automaton {son}", son_span)
        elif child.owner is not None:
            r.error("E103", f"sub-automaton {son} is already held by state "
                    f"`{child.owner.written}`", son_span)
        elif depth >= MAX_NESTING:
            r.error("E006", f"sub-automata nest deeper than {MAX_NESTING} levels", son_span)
        else:
            child.owner = s
            if child.father != sub.uid:
                r.warn("W208", f"sub-automaton {son} says its father is {child.father}, but "
                       f"state `{s.written}` of sub-automaton {sub.uid} holds it: read as held "
                       "by that state", child.father_span)
            s.child = self.level(child, depth + 1)

    def state(self, el: Element) -> tuple[LState, str, Span]:
        r = self.r
        g = r.children(el, ("name", "idSubautomataSon", "code"))
        uid, uid_span = r.attr(el, "id")
        if uid is None or not uid.strip():
            r.error("E102", "this state has no `id`", uid_span)
        name_el = r.required(g, "name", el, "this state")
        written, name_span = r.value(name_el) if name_el is not None else ("", r.span(el))
        if name_el is not None and not written:
            r.error("E103", "this state's `<name>` is empty", name_span)
        code_el = r.required(g, "code", el, f"state `{written}`" if written else "this state")
        son_el = r.first(g, "idSubautomataSon")
        son, son_span = r.value(son_el) if son_el is not None else ("0", r.span(el))
        assert self.glob.ctx is not None
        s = LState(norm_id(uid or ""), written, name_span,
                   r.text(code_el) if code_el is not None else None, self.glob.ctx)
        return s, norm_id(son), son_span

    def transition(self, el: Element, sub: _Sub,
                   states: dict[str, LState]) -> tuple[LState, Transition] | None:
        r = self.r
        g = r.children(el, ("origin", "destiny", "transcode", "name", "trans"))
        origin_el = r.required(g, "origin", el, "this transition")
        dest_el = r.required(g, "destiny", el, "this transition")
        trans = r.required(g, "trans", el, "this transition")
        if origin_el is None or dest_el is None or trans is None:
            return None
        origin, origin_span = r.value(origin_el)
        source = states.get(norm_id(origin))
        if source is None:
            r.error("E103", f"transition from state {origin}, which is not a state of "
                    f"sub-automaton {sub.uid}", origin_span)
            return None
        dest, dest_span = r.value(dest_el)
        target = states.get(norm_id(dest))
        if target is None:
            elsewhere = self.where.get(norm_id(dest))
            if elsewhere is not None:
                r.error("E133", f"transition of `{source.written}` to state {dest} of "
                        f"sub-automaton {elsewhere}: transitions join states of one "
                        "sub-automaton", dest_span)
            else:
                r.error("E132", f"transition of `{source.written}` to id {dest}: no state has "
                        "that id", dest_span)
            return None
        name_el = r.first(g, "name")
        code_el = r.first(g, "transcode")
        t = Transition(r.span(el), (r.value(name_el)[0] or None) if name_el is not None else None,
                       target, dest_span, code=r.text(code_el) if code_el is not None else None)
        kind, kind_span = r.attr(trans, "type")
        if kind == "time":
            t.after_ms, t.after_span = r.milliseconds(trans, "time")
        elif kind == "condition":
            t.cond = r.text(trans)
            if not t.cond.text.strip():
                r.error("E137", "this transition's condition is empty", r.span(trans),
                        "write a boolean expression")
        elif kind is None:
            r.error("E102", "`<trans>` has no `type` (condition or time)", r.span(trans))
            return None
        else:
            r.error("E103", f"`<trans>` type must be condition or time, not {kind!r}", kind_span)
            return None
        return source, t
