"""VisualHFSM 3.x files (element names in Spanish) into the neutral legacy form.

The format, as VisualHFSM 3.1 wrote it (JdeRobot/base, src/components/visualHFSM-3.1):
a ``<VisualHFSM>`` root holding a flat list of ``<SubAutomata>``, each with
``<idSub>``, ``<idPadre>`` (absent in some files), its states ``<Estado
estado_inicial="true|false">`` (``<id>``, numbered within the sub-automaton;
``<nombre>``, possibly empty; ``<hijo>``, the idSub it holds, 0 for none;
``<codigo>``; ``<transiciones>`` of ``<transicion>`` with ``<nombre>``,
``<destino>`` and either ``<tiempo>`` (ms) or ``<codigo>`` (a C++ condition)),
``<tiempoIteracion>`` (its cycle, ms), ``<Librerias>`` (the JdeRobot sensors and
actuators the code reaches through ``control->``), ``<variables_aux>`` and
``<funciones_aux>``; then ``<nombreEsquema>``, the path the file was saved as.
Layout (``origenX``... ``destinoY``, ``box``) is dropped.

VisualHFSM 3 generated C++ only, so the code is C++ whatever it looks like.
Where the file leaves something open the generator's choice is followed (see
docs/legacy.md): an unnamed state is ``default_N`` (N counts unnamed states
through the file), a sub-automaton without an initial state starts at its
first state, a transition with neither time nor condition never fires.
"""

from __future__ import annotations

import re

from hfsmc.errors import Span
from hfsmc.frontend.legacy.code import Mapped, cpp_declaration, cpp_statements
from hfsmc.frontend.legacy.form import Context, Interface, Legacy, Level, LState, Space, Transition
from hfsmc.frontend.legacy.levels import Sub, SubAutomata, find_target
from hfsmc.frontend.legacy.reader import Reader, norm_id
from hfsmc.frontend.xmlsource import Element

_LAYOUT = ("origenX", "origenY", "destinoX", "destinoY", "box", "posx", "posy")
_SUB_TAGS = ("idSub", "idPadre", "tiempoIteracion", "Librerias", "variables_aux",
             "funciones_aux")


def is_visualhfsm3(root: Element) -> bool:
    """Whether a ``<VisualHFSM>`` root holds the 3.x layout (Spanish element names)."""
    return any(sub.find("idSub") is not None or sub.find("Estado") is not None
               for sub in root.iterchildren("SubAutomata"))


def read(r: Reader, root: Element) -> Legacy | None:
    groups = r.children(root, ("nombreEsquema",), ("SubAutomata",))
    glob = Space("", "the automaton", r.span(root))
    glob.ctx = Context({k: (glob,) for k in ("self", "global", "local", "bare")})
    dropped: list[tuple[Span, str]] = [(r.span(root), "the layout of the diagram "
                                        "(origenX, origenY, destinoX, destinoY, box)")]
    schema = r.first(groups, "nombreEsquema")
    if schema is not None and r.value(schema)[0]:
        dropped.append((r.value(schema)[1], f"`<nombreEsquema>` {r.value(schema)[0]} (where "
                        "VisualHFSM wrote the generated component)"))
    levels = _Levels(r, glob)
    libraries: dict[str, Span] = {}
    for el in groups.get("SubAutomata", []):
        g = r.children(el, _SUB_TAGS, ("Estado",), _LAYOUT)
        uid_el = r.required(g, "idSub", el, "this `<SubAutomata>`")
        if uid_el is None:
            continue
        uid, uid_span = r.value(uid_el)
        father_el = r.first(g, "idPadre")
        sub = Sub(el, norm_id(uid),
                  norm_id(r.value(father_el)[0]) if father_el is not None else None, g,
                  g.get("Estado", []))
        if not levels.add(sub, uid_span):
            continue
        funcs, variables = r.first(g, "funciones_aux"), r.first(g, "variables_aux")
        if funcs is not None:
            glob.functions.append(r.text(funcs))
        if variables is not None:
            glob.variables += _declarations(r, r.text(variables))
        libs = r.first(g, "Librerias")
        if libs is not None:
            for lib in r.children(libs, (), ("lib",)).get("lib", []):
                name, span = r.value(lib)
                if name:
                    libraries.setdefault(name, span)
    order = levels.order
    if not order:
        if not groups.get("SubAutomata"):
            r.error("E102", "this VisualHFSM file has no `<SubAutomata>`", r.span(root))
        return None
    roots = [s for s in order if s.father == "0"]
    if not roots:
        first = levels.subs.get("1", order[0])
        r.warn("W208", f"no `<SubAutomata>` says `<idPadre>0</idPadre>`: sub-automaton "
               f"{first.uid} is read as the root, the others hang from the states that name "
               "them in `<hijo>`", r.span(first.el))
        roots = [first]
    top = levels.one_root(roots, "idPadre 0")
    for sub in order:  # VisualHFSM's generator numbered unnamed states through the file
        for el in sub.states:
            name_el = el.find("nombre")
            if name_el is not None and not (name_el.text or "").strip():
                levels.unnamed[el] = f"default_{len(levels.unnamed)}"
    level = levels.level(top, 0)
    for sub in order:
        if sub is not top and sub.owner is None:
            r.error("E103", f"sub-automaton {sub.uid} is not reached from the root "
                    f"sub-automaton: no reached state names it in `<hijo>`", r.span(sub.el))
    interfaces: list[Interface] = []
    if libraries or levels.uses_control:
        at = next(iter(libraries.values()), r.span(root))
        names = " ".join(libraries)
        interfaces.append(Interface(
            ("control",), "ice", None,
            {"interface": "VisualHFSM 3 controller", **({"libraries": names} if names else {})},
            at, "the JdeRobot controller `control`" + (f" ({names})" if names else "")))
    return Legacy(level, [glob], interfaces, [], True, (), dropped, language="cpp",
                  language_why="VisualHFSM 3 generated C++ only")


def _declarations(r: Reader, m: Mapped) -> list[Mapped]:
    """The declarations of a ``<variables_aux>``; its other statements are W207: VisualHFSM
    ran the whole text at the start of every iteration, before the state's code, which no
    part of a version-1 model does."""
    out: list[Mapped] = []
    for a, b in cpp_statements(m.text):
        stmt = m.cut(a, b).strip()
        if cpp_declaration(stmt.text) is not None:
            out.append(stmt)
        else:
            r.warn("W207", f"`{stmt.text}` in `<variables_aux>` is not carried over: "
                   "VisualHFSM ran it before the state's code at every iteration; put it in "
                   "the `during` of the states that need it", r.to_span(stmt.start))
    return out


class _Levels(SubAutomata):
    """The tree of sub-automata, from the root, through each state's ``<hijo>``."""

    period_tag = "tiempoIteracion"
    initial_attr = "estado_inicial"

    def __init__(self, r: Reader, glob: Space) -> None:
        super().__init__(r, glob)
        self.unnamed: dict[Element, str] = {}  # an unnamed state -> default_N
        self.uses_control = False
        self.groups: dict[LState, dict[str, list[Element]]] = {}  # a state's elements

    def state(self, el: Element, sub: Sub) -> tuple[LState, Span, tuple[str, Span] | None]:
        r = self.r
        g = r.children(el, ("id", "nombre", "hijo", "codigo", "transiciones"), (), _LAYOUT)
        uid_el = r.required(g, "id", el, "this `<Estado>`")
        uid = norm_id(r.value(uid_el)[0]) if uid_el is not None else ""
        name_el = r.required(g, "nombre", el, "this `<Estado>`")
        written, span = r.value(name_el) if name_el is not None else ("", r.span(el))
        if not written:
            written = self.unnamed.get(el, "default")
            r.warn("W206", f"state {uid or '?'} of sub-automaton {sub.uid} has no name: named "
                   f"`{written}`, as VisualHFSM's code generator named it", span)
        code_el = r.required(g, "codigo", el, f"state `{written}`")
        code = r.text(code_el) if code_el is not None else None
        if code is not None and re.search(r"\bcontrol\s*->", code.text):
            self.uses_control = True
        assert self.glob.ctx is not None
        s = LState(uid, written, span, code, self.glob.ctx)
        self.groups[s] = g
        son_el = r.first(g, "hijo")
        son = norm_id(r.value(son_el)[0]) if son_el is not None else "0"
        if son in ("", "0"):
            return s, span, None
        assert son_el is not None
        return s, span, (son, r.value(son_el)[1])

    def transitions(self, sub: Sub, level: Level, states: dict[str, LState]) -> None:
        r = self.r
        for s in level.states:
            trans = r.first(self.groups[s], "transiciones")
            if trans is None:
                continue
            for t_el in r.children(trans, (), ("transicion",)).get("transicion", []):
                t = self.transition(t_el, s, states, sub)
                if t is not None:
                    s.transitions.append(t)

    def adopted(self, s: LState, child: Sub, sub: Sub) -> None:
        """Nothing: a VisualHFSM 3 sub-automaton takes nothing from the state that holds it."""

    def finish(self, sub: Sub, level: Level) -> None:
        r = self.r
        if not level.states:
            r.error("E102", f"sub-automaton {sub.uid} has no `<Estado>`", r.span(sub.el))
        elif level.initial is None:
            level.initial, level.initial_span = level.states[0], r.span(sub.el)
            r.warn("W208", f"no state of sub-automaton {sub.uid} is initial: it starts at its "
                   f"first state, `{level.states[0].written}` (VisualHFSM's generated code named "
                   "no state to start in)", r.span(sub.el))

    def transition(self, el: Element, source: LState, states: dict[str, LState],
                   sub: Sub) -> Transition | None:
        r = self.r
        g = r.children(el, ("nombre", "destino", "tiempo", "codigo"), (), _LAYOUT)
        dest_el = r.required(g, "destino", el, "this `<transicion>`")
        if dest_el is None:
            return None
        dest, dest_span = r.value(dest_el)
        target = find_target(r, source, dest, dest_span, states, unknown=f"to state {dest}: "
                             f"sub-automaton {sub.uid} has no state with that `<id>`")
        if target is None:
            return None
        name_el = r.first(g, "nombre")
        t = Transition(r.span(el), (r.value(name_el)[0] or None) if name_el is not None else None,
                       target, dest_span)
        time_el, cond_el = r.first(g, "tiempo"), r.first(g, "codigo")
        if time_el is not None:
            t.after_ms, t.after_span = r.milliseconds(time_el, "tiempo")
        elif cond_el is not None and r.text(cond_el).text.strip():
            t.cond = r.text(cond_el)
            if re.search(r"\bcontrol\s*->", t.cond.text):
                self.uses_control = True
        else:
            t.cond = Mapped.synth("false", r.pos(r.span(el)))
            r.warn("W208", f"the transition of `{source.written}` to `{target.written}` has "
                   "neither `<tiempo>` nor a `<codigo>` condition: VisualHFSM generated no test "
                   "for it, so it never fired; kept as `when: false`", r.span(el))
        return t
