"""Graphviz diagrams of a model: states as circles, sub-automata as nested clusters.

The drawing follows the VisualStates paper: a state is a circle with its name
inside, the initial state of each sub-automaton a double circle; final states
are filled grey (an initial final state is a grey double circle).  A composite
state is a cluster labelled with its name, period and ``history``.  A
transition is an arrow labelled with its name, ``[when]`` and ``after``.

Node ids are the states' full paths, always quoted, so they cannot collide
whatever the names; helper nodes carry a ``#``, which no path contains.  An
edge to or from a composite state is drawn between anchor nodes inside the
clusters (the initial child, recursively) and clipped at the cluster's border
with ``lhead`` / ``ltail`` (``compound=true``).

Labels are Graphviz escStrings: backslashes are doubled (no ``\\N``, ``\\l``
surprises), ``&`` becomes ``&amp;`` (Graphviz decodes entities even in plain
labels), ``<...>`` is never taken for an HTML label and quotes are escaped by
the ``graphviz`` package.  The same model always gives the same DOT bytes.
"""

from __future__ import annotations

import unicodedata
from collections.abc import Iterator
from pathlib import Path

import graphviz

from hfsmc.durations import format_us
from hfsmc.errors import UsageError, did_you_mean
from hfsmc.fsutil import write_atomic
from hfsmc.ir import Automaton, Code, Model, State, Transition

# Longest line of a label (conditions, names), in characters, before "…".
LABEL_LIMIT = 40
# Longest tooltip (the full, unshortened text shown on hover in SVG).
TOOLTIP_LIMIT = 1000
ELLIPSIS = "…"

FONT = "Helvetica,Arial,sans-serif"
FINAL_FILL = "#c8c8c8"
# Cluster fills by nesting depth: light tints, so that nesting shows at a glance.
CLUSTER_FILLS = ("#eef3fa", "#f7f3e8", "#eef7ee", "#f6eef6")

GRAPH_ATTRS: dict[str, str] = {
    "rankdir": "LR",
    "newrank": "true",
    "compound": "true",
    "fontname": FONT,
    "fontsize": "14",
    "labelloc": "t",
    "labeljust": "l",
    "nodesep": "0.5",
    "ranksep": "0.6",
    "pad": "0.3",
}
NODE_ATTRS: dict[str, str] = {
    "shape": "circle",
    "fontname": FONT,
    "fontsize": "12",
    "width": "0.9",
    "margin": "0.04",
    "style": "filled",
    "fillcolor": "white",
    "penwidth": "1.2",
}
EDGE_ATTRS: dict[str, str] = {
    "fontname": FONT,
    "fontsize": "10",
    "arrowsize": "0.8",
}


def to_dot(model: Model, state_path: str | None = None) -> str:
    """The DOT source of ``model``'s diagram, or of one state's sub-automaton.

    Raises UsageError when ``state_path`` names no state, or a state without a
    sub-automaton.
    """
    auto, title = _select(model, state_path)
    g = graphviz.Digraph(
        name=model.name,
        graph_attr={**GRAPH_ATTRS, "label": _esc_lines([title])},
        node_attr=NODE_ATTRS,
        edge_attr=EDGE_ATTRS,
    )
    _draw_states(g, auto, depth=0)
    for parent, state in _states_in(auto):
        for t in state.transitions:
            _draw_transition(g, state, t, parent)
    return g.source


def write_diagram(model: Model, out: Path, state_path: str | None) -> None:
    """Write the diagram to ``out``: ``.dot`` source, or ``.svg`` / ``.png`` drawn by ``dot``.

    The file is written atomically: on any failure no partial file is left and
    an existing file is untouched.
    """
    source = to_dot(model, state_path)
    fmt = out.suffix.lower().lstrip(".")
    if fmt == "dot":
        data = source.encode("utf-8")
    elif fmt in ("svg", "png"):
        data = render(source, fmt)
    else:
        raise UsageError(f"{out}: the diagram's file name must end in .svg, .png or .dot")
    write_atomic(out, data)


def render(source: str, fmt: str) -> bytes:
    """``source`` drawn by Graphviz ``dot`` in format ``fmt`` (``svg``, ``png``)."""
    try:
        data: bytes = graphviz.Source(source).pipe(format=fmt, quiet=True)
    except graphviz.ExecutableNotFound:
        raise UsageError(
            "Graphviz `dot` not found: install the graphviz package (apt-get install graphviz)"
        ) from None
    except graphviz.CalledProcessError as e:
        detail = _stderr_text(e.stderr) or "no message"
        raise UsageError(
            f"Graphviz `dot` failed (exit status {e.returncode}): {detail}"
            " (write the diagram as .dot to see its source)"
        ) from None
    if not data:
        raise UsageError(f"Graphviz `dot` produced no {fmt.upper()} output")
    return data


# ---------------------------------------------------------------------------
# selection


def _select(model: Model, state_path: str | None) -> tuple[Automaton, str]:
    """The sub-automaton to draw and the diagram's title."""
    root_period = format_us(model.root.period_ms * 1000)
    if state_path is None:
        return model.root, f"{model.name}  (period {root_period})"
    state = model.find(state_path)
    composites = [s.path for s in model.states() if s.automaton is not None]
    if state is None:
        msg = f"--state {state_path}: no such state in model `{model.name}`"
        hint = did_you_mean(state_path, [s.path for s in model.states()])
        raise UsageError(f"{msg} ({hint})" if hint else msg + _listing(composites))
    if state.automaton is None:
        raise UsageError(
            f"--state {state_path}: state `{state.path}` has no sub-automaton to draw"
            + _listing(composites)
        )
    return state.automaton, f"{model.name}: {state.path}  ({_automaton_note(state.automaton)})"


def _listing(composites: list[str]) -> str:
    if not composites:
        return "; this model has no composite state"
    return "; composite states: " + ", ".join(composites)


def _states_in(auto: Automaton) -> Iterator[tuple[Automaton, State]]:
    """Every state of ``auto`` and its nested sub-automata, parents first, with
    the sub-automaton that holds it."""
    for s in auto.states:
        yield auto, s
        if s.automaton is not None:
            yield from _states_in(s.automaton)


# ---------------------------------------------------------------------------
# states


def _draw_states(g: graphviz.Digraph, auto: Automaton, depth: int) -> None:
    for s in auto.states:
        initial = s.name == auto.initial
        if s.automaton is None:
            g.node(_node_id(s), **_state_attrs(s, initial))
            continue
        with g.subgraph(name=_cluster_id(s)) as c:
            c.attr(
                label=_esc_lines([s.name, _automaton_note(s.automaton)]),
                style="rounded,filled" + (",bold" if initial else ""),
                fillcolor=CLUSTER_FILLS[depth % len(CLUSTER_FILLS)],
                color="#4a5a70",
                penwidth="2" if initial else "1.2",
                fontsize="13",
                labeljust="l",
                margin="12",
                tooltip=_esc_lines([s.path + (" (initial)" if initial else "")]),
            )
            _draw_states(c, s.automaton, depth + 1)


def _state_attrs(s: State, initial: bool) -> dict[str, str]:
    attrs = {
        "label": _esc_lines([_shorten(s.name, LABEL_LIMIT)]),
        "tooltip": _esc_lines([s.path]),
    }
    if initial:
        attrs["shape"] = "doublecircle"
    if s.final:
        attrs["fillcolor"] = FINAL_FILL
        attrs["penwidth"] = "2"
    return attrs


def _automaton_note(auto: Automaton) -> str:
    note = f"period {format_us(auto.period_ms * 1000)}"
    return note + " · history" if auto.history else note


def _node_id(s: State) -> str:
    # Always quoted by the graphviz package (a path is never a bare DOT keyword
    # problem: `node`, `edge`... are quoted too); a path contains no `:`.
    return s.path


def _cluster_id(s: State) -> str:
    return f"cluster_{s.path}"


def _anchor(s: State) -> State:
    """The node an edge to or from ``s`` attaches to: ``s``, or its initial leaf."""
    while s.automaton is not None:
        child = s.automaton.state(s.automaton.initial)
        if child is None:  # cannot happen in a checked model
            break
        s = child
    return s


# ---------------------------------------------------------------------------
# transitions


def _draw_transition(g: graphviz.Digraph, src: State, t: Transition, parent: Automaton) -> None:
    dst = parent.state(t.target)
    if dst is None:  # cannot happen in a checked model
        raise UsageError(f"transition of `{src.path}` to unknown state `{t.target}`")
    label = _esc_lines(_label_lines(t))
    tooltip = _tooltip(src, dst, t)
    if dst is src and src.automaton is not None:
        _draw_composite_loop(g, src, t, label, tooltip)
        return
    attrs: dict[str, str] = {"label": label, "tooltip": tooltip}
    if src.automaton is not None:
        attrs["ltail"] = _cluster_id(src)
    if dst.automaton is not None:
        attrs["lhead"] = _cluster_id(dst)
    g.edge(_node_id(_anchor(src)), _node_id(_anchor(dst)), **attrs)


def _draw_composite_loop(
    g: graphviz.Digraph, s: State, t: Transition, label: str, tooltip: str
) -> None:
    """A self-transition of a composite state: out of the cluster and back into it.

    Graphviz cannot draw a loop on a cluster (an edge clipped at both ends by
    the same cluster is refused), so the loop goes through a tiny helper node
    just outside the cluster.
    """
    via = f"#loop {s.path} {t.index}"  # `#` and spaces never occur in a path
    g.node(via, label="", shape="point", width="0.03", style="invis")
    anchor = _node_id(_anchor(s))
    cluster = _cluster_id(s)
    g.edge(anchor, via, label=label, tooltip=tooltip, ltail=cluster, arrowhead="none")
    g.edge(via, anchor, tooltip=tooltip, lhead=cluster)


def _label_lines(t: Transition) -> list[str]:
    lines: list[str] = []
    if t.name:
        lines.append(_shorten(_one_line(t.name), LABEL_LIMIT))
    if t.when is not None:
        lines.append("[" + _shorten(_code_line(t.when), LABEL_LIMIT - 2) + "]")
    if t.after_us is not None:
        lines.append(f"after {format_us(t.after_us)}")
    return lines


def _tooltip(src: State, dst: State, t: Transition) -> str:
    """The full transition (nothing shortened), shown on hover in SVG."""
    parts = [f"{src.path} → {dst.path}"]
    if t.name:
        parts.append(_one_line(t.name))
    if t.when is not None:
        parts.append(f"[{_code_line(t.when)}]")
    if t.after_us is not None:
        parts.append(f"after {format_us(t.after_us)}")
    return _esc_lines([_shorten(p, TOOLTIP_LIMIT) for p in parts])


# ---------------------------------------------------------------------------
# text


def _code_line(code: Code) -> str:
    """A snippet on one line: its lines stripped and joined by spaces."""
    return _one_line(code.text)


def _one_line(text: str) -> str:
    return " ".join(part for part in (ln.strip() for ln in text.splitlines()) if part)


def _shorten(text: str, limit: int) -> str:
    """``text`` cut to ``limit`` characters, the cut marked with an ellipsis."""
    if len(text) <= limit:
        return text
    return text[: limit - 1].rstrip() + ELLIPSIS


def _esc(text: str) -> str:
    """One label line as a Graphviz escString body (quotes are left to ``graphviz``)."""
    out = []
    for ch in text:
        if ch == "\\":
            out.append("\\\\")
        elif ch == "&":
            out.append("&amp;")
        elif ch == "\t":
            out.append(" ")
        elif unicodedata.category(ch) in ("Cc", "Cs") or ch in "\u2028\u2029":
            # Control characters (and lone surrogates) are invalid in SVG's
            # XML: show them as Python would spell them.
            out.append(ascii(ch)[1:-1].replace("\\", "\\\\"))
        else:
            out.append(ch)
    return "".join(out)


def _esc_lines(lines: list[str]) -> str:
    """Label lines joined by centred line breaks, never taken for an HTML label."""
    return graphviz.nohtml("\\n".join(_esc(line) for line in lines))
