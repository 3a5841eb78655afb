"""Graphviz diagrams of a model: states as circles, sub-automata as nested clusters.

The drawing follows the VisualStates paper: a state is a circle with its name
inside, the initial state of each sub-automaton a double circle; final states
are filled grey (an initial final state is a grey double circle).  A composite
state is a cluster labelled with its name, period and ``history`` (and, as a
cluster cannot be a double circle, ``initial`` and a bold border when it is
the initial state).  A transition is an arrow labelled with its name,
``[when]`` and ``after``; long lines are cut with an ellipsis.

Node ids are the states' full paths, always quoted, so they cannot collide
whatever the names; helper nodes carry a ``#``, which no path contains.  An
edge to or from a composite state is drawn between anchor nodes inside the
clusters (a leaf reached through initial children going in, one far from the
initial child going out) and clipped at the cluster's border with ``lhead`` /
``ltail`` (``compound=true``); its label is a text node the arrow runs
through, so that it always sits outside the clusters.

Labels are Graphviz escStrings: backslashes are doubled (no ``\\N``, ``\\l``
surprises), ``&`` becomes ``&amp;`` (Graphviz decodes entities even in plain
labels), ``<...>`` is never taken for an HTML label and quotes are escaped by
the ``graphviz`` package.  The same model always gives the same DOT bytes.
"""

from __future__ import annotations

import unicodedata
from pathlib import Path

import graphviz

from hfsmc.durations import format_us
from hfsmc.errors import UsageError, did_you_mean
from hfsmc.fsutil import write_atomic
from hfsmc.ir import Automaton, Code, Model, State, Transition

# Longest line of a label (conditions, names), in characters, before "…".
LABEL_LIMIT = 40
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
    _draw_automaton(g, auto, depth=0)
    source: str = g.source
    return source if source.endswith("\n") else source + "\n"


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
        raise UsageError(
            f"Graphviz `dot` failed (exit status {e.returncode}): {_stderr_text(e.stderr)}"
            " (write the diagram as .dot to see its source)"
        ) from None
    except OSError as e:
        raise UsageError(f"cannot run Graphviz `dot`: {e}") from None
    if not data:
        raise UsageError(f"Graphviz `dot` produced no {fmt.upper()} output")
    return data


def _stderr_text(stderr: bytes | str | None) -> str:
    """The last lines dot wrote on stderr, on one line."""
    if isinstance(stderr, bytes):
        stderr = stderr.decode("utf-8", errors="replace")
    lines = [ln.strip() for ln in (stderr or "").splitlines() if ln.strip()]
    return _shorten(" / ".join(lines[-3:]), 300) if lines else "no message"


# ---------------------------------------------------------------------------
# selection


def _select(model: Model, state_path: str | None) -> tuple[Automaton, str]:
    """The sub-automaton to draw and the diagram's title."""
    root_period = format_us(model.root.period_ms * 1000)
    if state_path is None:
        return model.root, f"{model.name} · period {root_period}"
    state = model.find(state_path)
    composites = [s.path for s in model.states() if s.automaton is not None]
    if state is None:
        msg = f"--state {state_path}: no such state in model `{model.name}`"
        hint = did_you_mean(state_path, composites)
        raise UsageError(f"{msg} ({hint})" if hint else msg + _listing(composites))
    if state.automaton is None:
        raise UsageError(
            f"--state {state_path}: state `{state.path}` has no sub-automaton to draw"
            + _listing(composites)
        )
    return state.automaton, f"{model.name}: {state.path} · {_automaton_note(state.automaton)}"


def _listing(composites: list[str]) -> str:
    if not composites:
        return "; this model has no composite state"
    return "; composite states: " + ", ".join(composites)


# ---------------------------------------------------------------------------
# states


def _draw_automaton(g: graphviz.Digraph, auto: Automaton, depth: int) -> None:
    """The states of ``auto`` (clusters for composite ones), then its transitions.

    Everything goes in ``auto``'s own cluster: the label nodes of transitions
    must sit in the cluster of the sub-automaton they belong to.
    """
    for s in auto.states:
        initial = s.name == auto.initial
        if s.automaton is None:
            g.node(_node_id(s), **_state_attrs(s, initial))
            continue
        with g.subgraph(name=_cluster_id(s)) as c:
            c.attr(
                label=_esc_lines([s.name, _automaton_note(s.automaton, initial)], left=True),
                style="rounded,filled" + (",bold" if initial else ""),
                fillcolor=CLUSTER_FILLS[depth % len(CLUSTER_FILLS)],
                color="#4a5a70",
                penwidth="2" if initial else "1.2",
                fontsize="13",
                labeljust="l",
                margin="12",
                tooltip=s.path,
            )
            _draw_automaton(c, s.automaton, depth + 1)
    for s in auto.states:
        for t in s.transitions:
            _draw_transition(g, s, t, auto)


def _state_attrs(s: State, initial: bool) -> dict[str, str]:
    attrs = {
        "label": _esc_lines([s.name]),  # never shortened: names tell states apart
        "tooltip": s.path,  # identifiers and `/`: nothing to escape
    }
    if initial:
        attrs["shape"] = "doublecircle"
    if s.final:
        attrs["fillcolor"] = FINAL_FILL
        attrs["penwidth"] = "2"
    return attrs


def _automaton_note(auto: Automaton, initial: bool = False) -> str:
    """``period 100ms``, with `` · history`` when on; a composite initial state
    (a cluster cannot be a double circle) says ``initial`` first."""
    note = f"period {format_us(auto.period_ms * 1000)}"
    if auto.history:
        note += " · history"
    return "initial · " + note if initial else note


def _node_id(s: State) -> str:
    # The path itself: unique, and quoted by the graphviz package whenever
    # needed (a `/`, a DOT keyword such as `node`); it never holds a `:`,
    # which graphviz would read as a port.
    return s.path


def _cluster_id(s: State) -> str:
    return f"cluster_{s.path}"


def _entry_anchor(s: State) -> State:
    """The node an edge into ``s`` attaches to: ``s``, or its initial leaf.

    The initial child is what the layout puts first in a cluster, so edges
    come in where the sub-automaton starts.
    """
    while s.automaton is not None:
        child = s.automaton.state(s.automaton.initial)
        if child is None:  # cannot happen in a checked model
            break
        s = child
    return s


def _exit_anchor(s: State) -> State:
    """The node an edge out of ``s`` attaches to: ``s``, or a leaf far from the start.

    With ``rankdir=LR`` and ``newrank`` an edge's tail node sets the rank of its
    head; leaving from the child farthest (in transitions) from the initial one
    puts the target to the right of the whole cluster, not beside it.
    """
    while s.automaton is not None:
        s = _farthest(s.automaton)
    return s


def _farthest(auto: Automaton) -> State:
    """The child of ``auto`` with the longest shortest path from the initial child
    (the last such in model order); unreachable children do not count."""
    start = auto.state(auto.initial) or auto.states[0]
    dist = {start.name: 0}
    queue = [start]
    for s in queue:  # breadth first: the list grows while it is walked
        for t in s.transitions:
            nxt = auto.state(t.target)
            if nxt is not None and nxt.name not in dist:
                dist[nxt.name] = dist[s.name] + 1
                queue.append(nxt)
    best = start
    for s in auto.states:
        if s.name in dist and dist[s.name] >= dist[best.name]:
            best = s
    return best


# ---------------------------------------------------------------------------
# transitions


def _draw_transition(g: graphviz.Digraph, src: State, t: Transition, parent: Automaton) -> None:
    dst = parent.state(t.target)
    if dst is None:  # cannot happen in a checked model
        raise UsageError(f"transition of `{src.path}` to unknown state `{t.target}`")
    label = _esc_lines(_label_lines(t))
    tail, head = _node_id(_exit_anchor(src)), _node_id(_entry_anchor(dst))
    if src.automaton is None and dst.automaton is None:
        g.edge(tail, head, label=label)
        return
    # To or from a composite state: the edge runs between anchor nodes and is
    # clipped at the cluster's border.  dot would place an ordinary label at
    # the middle of the unclipped edge, possibly inside the cluster (and an
    # xlabel gets no room and overlaps nodes), so the label is a small text
    # node of its own, outside the clusters, that the arrow runs through.  It
    # also lets a composite state's self-transition leave the cluster and come
    # back, which a single edge clipped twice by one cluster cannot do.
    via = f"#{src.path} {t.index}"  # `#` and spaces never occur in a path
    g.node(via, label=label, shape="plaintext", style="", width="0", height="0",
           margin="0.04,0.02", fontsize=EDGE_ATTRS["fontsize"])
    out = {"ltail": _cluster_id(src)} if src.automaton is not None else {}
    into = {"lhead": _cluster_id(dst)} if dst.automaton is not None else {}
    g.edge(tail, via, arrowhead="none", **out)
    g.edge(via, head, **into)


def _label_lines(t: Transition) -> list[str]:
    lines: list[str] = []
    if t.name:
        lines.append(_shorten(_one_line(t.name), LABEL_LIMIT))
    if t.when is not None:
        lines.append("[" + _shorten(_code_line(t.when), LABEL_LIMIT - 2) + "]")
    if t.after_us is not None:
        lines.append(f"after {format_us(t.after_us)}")
    return lines


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
        elif unicodedata.category(ch) in ("Cc", "Cs") or ch in "\u2028\u2029\ufffe\uffff":
            # Control characters (and the like) are invalid in SVG's XML or
            # break lines: show them as Python would spell them.
            out.append(ascii(ch)[1:-1].replace("\\", "\\\\"))
        else:
            out.append(ch)
    return "".join(out)


def _esc_lines(lines: list[str], left: bool = False) -> str:
    """Label lines, centred (or left-justified), never taken for an HTML label."""
    if left:
        text = "".join(_esc(line) + "\\l" for line in lines)
    else:
        text = "\\n".join(_esc(line) for line in lines)
    label: str = graphviz.nohtml(text)
    return label
