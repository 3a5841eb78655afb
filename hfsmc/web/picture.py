"""The web view's picture: the model's diagram as SVG, drawn by ``dot`` here.

The drawing is hfsmc's own (hfsmc/emit/dot.py), so a state's SVG element has
its path as ``id`` and a transition ``PATH#N``, as the trace names them
(docs/diagrams.md). It is drawn from the model file when ``--model`` is given
(conditions and timers on the arrows), else from the structure the component
sends in its ``hello`` (states and arrows, with the transitions' names only).
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

from hfsmc.emit.dot import render, to_dot
from hfsmc.errors import Span
from hfsmc.ir import Automaton, Instance, Model, State, Transition

_NOWHERE = Span("<monitor>", 1, 1)


def svg_of(model: Model, state_path: str | None = None) -> str:
    """The diagram of ``model`` (or of the sub-automaton of its composite state
    ``state_path`` alone, as ``hfsmc diagram --state``) as an SVG element to put in
    a page (no XML prologue).

    Raises UsageError when ``dot`` is missing or fails, or ``state_path`` names no
    composite state.
    """
    text = render(to_dot(model, state_path), "svg").decode("utf-8")
    start = text.find("<svg")
    return text[start:] if start >= 0 else text


def model_from_structure(structure: dict[str, Any]) -> Model:
    """A model with the states, sub-automata and transitions a ``hello`` gives, and no code.

    Enough for the diagram: it lacks the conditions and timers of the arrows
    and the ``on_interrupt`` mark, which the monitor protocol does not carry.
    A state's regions are the automata that name it as owner with a ``region``
    (their states' paths are OWNER/REGION/NAME). An automaton with a ``use`` is an
    instance of that file (see ``_instance``), whose cluster the diagram names after it.
    Raises ValueError when the structure does not hold together.
    """
    states = [st for st in structure.get("states", ()) if isinstance(st, dict)]
    autos: dict[str, dict[str, Any]] = {}  # an automaton's path (OWNER, OWNER/REGION) -> it
    regions: dict[str, list[str]] = {}  # a parallel state's path -> its regions' names, in order
    for a in structure.get("automata", ()):
        if not isinstance(a, dict):
            continue
        owner, region = str(a["owner"]), a.get("region")
        if region:
            if not owner or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", str(region)):
                raise ValueError(f"bad region {region!r} of {owner!r}")
            regions.setdefault(owner, []).append(str(region))
            autos[f"{owner}/{region}"] = a
        else:
            autos[owner] = a
    children: dict[str, list[dict[str, Any]]] = {"": []}
    for st in states:
        path = str(st["path"])
        children.setdefault(path.rpartition("/")[0], []).append(st)
        children.setdefault(path, [])
    moves: dict[str, list[dict[str, Any]]] = {}
    for tr in structure.get("transitions", ()):
        if isinstance(tr, dict):
            moves.setdefault(str(tr["from"]), []).append(tr)

    def automaton(owner: str, period: int, region: str | None = None) -> Automaton:
        where = f"{owner}/{region}" if region else owner
        info = autos.get(where, {})
        period = int(info.get("period_ms", period))
        kids = tuple(state(st, period) for st in children.get(where, ()))
        if not kids:
            raise ValueError(f"the structure has no states under {repr(where) if where else 'the root'}")
        initial = str(info.get("initial") or kids[0].name)
        auto = Automaton(owner=owner, region=region, period_ms=period, period_written=True,
                         initial=initial, history=bool(info.get("history")), states=kids,
                         span=_NOWHERE, initial_span=_NOWHERE)
        use = info.get("use")
        return dataclasses.replace(auto, instance=_instance(str(use), auto)) if use else auto

    def state(st: dict[str, Any], period: int) -> State:
        path = str(st["path"])
        name = path.rpartition("/")[2]
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise ValueError(f"bad state path {path!r}")
        composite = bool(st.get("composite")) and bool(children.get(path) or regions.get(path))
        held: tuple[Automaton, ...] = ()
        if composite:
            held = tuple(automaton(path, period, r) for r in regions[path]) if path in regions \
                else (automaton(path, period),)
        trs = tuple(
            Transition(index=int(tr["index"]), target=str(tr["to"]).rpartition("/")[2], when=None,
                       after_us=None, do=None,
                       name=None if tr.get("name") is None else str(tr["name"]),
                       span=_NOWHERE, target_span=_NOWHERE)
            for tr in sorted(moves.get(path, ()), key=lambda tr: int(tr["index"])))
        return State(name=name, path=path, entry=None, during=None, exit=None, transitions=trs,
                     final=bool(st.get("final")),
                     automata=held, span=_NOWHERE)

    root = automaton("", 100)
    return Model(name=str(structure.get("name") or "component"), language="python",
                 description=None, imports=(), interfaces=(), parameters=(), variables=(),
                 functions=None, on_shutdown=None, on_interrupt=None, interrupt_timeout_us=None,
                 root=root, file="<monitor>", span=_NOWHERE)


def _instance(written: str, auto: Automaton) -> Instance:
    """What a structure tells of a used file where ``auto`` takes it: its name as the
    using model writes it, and its states, which make the used file's model again (paths
    from its own root, as ``Instance.model`` has them). No bindings and no code: the
    monitor protocol carries neither."""
    root = _rerooted(auto, auto.owner + "/")
    model = Model(name=written.rpartition("/")[2].partition(".")[0] or written, language="python",
                  description=None, imports=(), interfaces=(), parameters=(), variables=(),
                  functions=None, on_shutdown=None, on_interrupt=None, interrupt_timeout_us=None,
                  root=root, file=written, span=_NOWHERE)
    return Instance(file=written, written=written, model=model, bindings=(), span=_NOWHERE)


def _rerooted(auto: Automaton, prefix: str) -> Automaton:
    """``auto`` with ``prefix`` taken off every path in it, and made a root (no instance:
    an instance inside keeps its own)."""

    def cut(path: str) -> str:
        return path[len(prefix):] if path.startswith(prefix) else ""

    def below(a: Automaton) -> Automaton:
        return dataclasses.replace(a, owner=cut(a.owner), states=tuple(
            dataclasses.replace(s, path=cut(s.path), automata=tuple(below(x) for x in s.automata))
            for s in a.states))

    return dataclasses.replace(below(auto), owner="", instance=None)
