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
from hfsmc.frontend.legacy.levels import Sub, SubAutomata, find_target
from hfsmc.frontend.legacy.reader import Reader, norm_id
from hfsmc.frontend.xmlsource import Element

# Modules VisualHFSM's generated Python imported for the code.
_IMPLICIT = ("sys", "threading", "time", "traceback")


def read(r: Reader, root: Element) -> Legacy | None:
    groups = r.children(root, ("libraries", "config"), ("SubAutomata",))
    glob = Space("", "the automaton", r.span(root))
    glob.ctx = Context({k: (glob,) for k in ("self", "global", "local", "bare")})
    levels = _Levels(r, glob)
    for el in groups.get("SubAutomata", []):
        sub = _sub(r, el, glob)
        if sub is not None:
            levels.add(sub, r.attr(el, "id")[1])
    order = levels.order
    roots = [s for s in order if s.father == "0"]
    if not roots:
        r.error("E102", "no root `<SubAutomata>` (the one with idFather=\"0\")", r.span(root))
        return None
    top = levels.one_root(roots, 'idFather="0"')
    for sub in order:
        for st in sub.states:
            levels.where.setdefault(norm_id(st.get("id", "")), sub.uid)
    level = levels.level(top, 0)
    held = {norm_id(son.text or "") for sub in order for st in sub.states
            if (son := st.find("idSubautomataSon")) is not None}
    for sub in order:
        if sub is not top and sub.owner is None and sub.father != "0":
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


def _sub(r: Reader, el: Element, glob: Space) -> Sub | None:
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
    return Sub(el, norm_id(uid), norm_id(father), groups, groups.get("state", []), father_span)


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


class _Levels(SubAutomata):
    """The tree of sub-automata, from the root, through each state's idSubautomataSon."""

    period_tag = "iteration_time"
    initial_attr = "initial"

    def __init__(self, r: Reader, glob: Space) -> None:
        super().__init__(r, glob)
        self.where: dict[str, str] = {}  # state id -> id of its sub-automaton

    def transitions(self, sub: Sub, level: Level, states: dict[str, LState]) -> None:
        for el in sub.groups.get("transition", []):
            found = self.transition(el, sub, states)
            if found is not None:
                found[0].transitions.append(found[1])

    def finish(self, sub: Sub, level: Level) -> None:
        r = self.r
        if level.states and level.initial is None:
            r.error("E130", f"sub-automaton {sub.uid} has no initial state", r.span(sub.el),
                    f"mark one of {', '.join(s.written for s in level.states)} "
                    "with initial=\"true\"")
        if not level.states:
            r.error("E102", f"sub-automaton {sub.uid} has no `<state>`", r.span(sub.el))

    def adopted(self, s: LState, child: Sub, sub: Sub) -> None:
        if child.father != sub.uid:
            assert child.father_span is not None
            self.r.warn("W208", f"sub-automaton {child.uid} says its father is {child.father}, "
                        f"but state `{s.written}` of sub-automaton {sub.uid} holds it: read as "
                        "held by that state", child.father_span)

    def state(self, el: Element, sub: Sub) -> tuple[LState, Span, tuple[str, Span] | None]:
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
        return s, uid_span, None if norm_id(son) in ("", "0") else (norm_id(son), son_span)

    def transition(self, el: Element, sub: Sub,
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
        target = find_target(r, source, dest, dest_span, states, self.where,
                             lambda other: f" of sub-automaton {other}: transitions join "
                             "states of one sub-automaton")
        if target is None:
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
