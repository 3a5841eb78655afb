"""Graphviz diagrams of a model: states as circles, sub-automata as nested clusters.

The drawing follows the VisualStates paper: a state is a circle with its name
inside, the initial state of each sub-automaton a double circle; final states
are filled grey (an initial final state is a grey double circle).  A composite
state is a cluster labelled with its name, period and ``history`` (and, as a
cluster cannot be a double circle, ``initial`` and a bold border when it is
the initial state); below ``depth`` levels it is one tinted circle saying how
many states it holds.  A state with parallel regions is such a cluster split
into dashed clusters, one per region (its name and period), side by side in
the order written: their initial states share a rank.  A sub-automaton taken
from another file (``use``) has the file's name in its cluster's label.  A
transition is an arrow labelled with its name,
``[when]`` and ``after``, numbered when its state has several (the order they
are tried); long lines are wrapped, not cut.  The ``on_interrupt`` state gets
a dashed arrow from an ``interrupt`` marker.  The direction (``rankdir``) is
chosen from the model's shape unless given (hfsmc/emit/dot_layout.py); top
to bottom, a nested pair of states is drawn in a row and a chain of states in
rows of CHAIN_ROW.  The choices are explained in docs/diagrams.md.

Node ids are the states' full paths, always quoted, so they cannot collide
whatever the names; helper nodes carry a ``#``, which no path contains.  An
edge to or from a composite state is drawn between anchor nodes inside the
clusters (a leaf reached through initial children going in, one far from the
initial child going out) and clipped at the cluster's border with ``lhead`` /
``ltail`` (``compound=true``); its label is a text node the arrow runs
through, so that it always sits outside the clusters (inside a cluster too,
so that the cluster grows around it).  In SVG, a state's element (node or
cluster) has its path as ``id`` and a transition ``PATH#N`` (its source and
index, as a trace's ``fire`` record names it), for views that colour them.

Label text is wrapped and escaped by hfsmc/emit/dot_text.py; what
``--state`` draws is chosen by hfsmc/emit/dot_select.py.  The same model
always gives the same DOT bytes: the direction is estimated, not measured by
running Graphviz.
"""

from __future__ import annotations

import functools
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import graphviz

from hfsmc.durations import format_us
from hfsmc.emit.dot_layout import Plan, Spacing, choose_rankdir, text_size
from hfsmc.emit.dot_select import select
from hfsmc.emit.dot_text import (
    WRAP,
    automaton_note,
    esc_lines,
    name_line,
    one_line,
    shorten,
    state_note,
    wrap,
)
from hfsmc.errors import UsageError
from hfsmc.fsutil import write_atomic
from hfsmc.ir import Automaton, Model, State, Transition

RANKDIRS = ("auto", "LR", "TB")
# Sub-automata of at most this many simple states are drawn in a row (one
# rank) top to bottom: a column of them would make tall drawings taller.  Not
# more: dot routes an edge between the ends of a longer row over the row's
# cluster label.
ROW_MAX = 2
# A chain of states (each leading only to the next) is drawn top to bottom in
# rows of this many, like lines of text, instead of one long column.
CHAIN_ROW = 4

# Diagrams are drawn in Liberation Sans (Debian's fonts-liberation, which `make deps`
# installs): it has Helvetica's and Arial's metrics, so dot measures every label the same way
# on every machine, and a viewer that draws the SVG in Arial or Helvetica sees the same widths
# (docs/diagrams.md).  Without it fontconfig gives another font (DejaVu Sans, wider): labels
# drift from their arrows, and `hfsmc diagram` says so (font_warning).
FONT_FAMILY = "Liberation Sans"
FONT = f"{FONT_FAMILY},Arial,Helvetica,sans-serif"
FINAL_FILL = "#c8c8c8"
BORDER = "#4a5a70"
INTERRUPT_COLOR = "#b03a2e"
# Cluster fills by nesting depth: light tints, so that nesting shows at a glance.
CLUSTER_FILLS = ("#eef3fa", "#f7f3e8", "#eef7ee", "#f6eef6")

GRAPH_ATTRS: dict[str, str] = {
    "newrank": "true",
    "compound": "true",
    "fontname": FONT,
    "fontsize": "14",
    "labelloc": "t",
    "labeljust": "l",
    "nodesep": "0.35",
    "ranksep": "0.25",
    "pad": "0.3",
}
NODE_ATTRS: dict[str, str] = {
    "shape": "circle",
    "fontname": FONT,
    "fontsize": "12",
    "width": "0.8",
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
CLUSTER_MARGIN = 12
CLUSTER_FONTSIZE = 13


def _inches(attr: str) -> float:
    return float(attr) * 72


SPACING = Spacing(ranksep=_inches(GRAPH_ATTRS["ranksep"]), nodesep=_inches(GRAPH_ATTRS["nodesep"]),
                  cluster_margin=CLUSTER_MARGIN, title_height=24.0, pad=_inches(GRAPH_ATTRS["pad"]))


def to_dot(model: Model, state_path: str | None = None, *, rankdir: str = "auto",
           depth: int | None = None) -> str:
    """The DOT source of ``model``'s diagram, or of one state's sub-automaton
    or regions, or of one region (``state_path``: ``Mission``, ``Mission/Watch``).

    ``rankdir`` is ``LR``, ``TB`` or ``auto`` (chosen from the drawing's
    estimated size); composite states more than ``depth`` levels below the
    drawn sub-automaton are drawn as one node (``depth=0``: its own states
    only; None: every level).  A region is a level as a sub-automaton is: the
    states of a state's regions are one level below it.

    Raises UsageError when ``state_path`` names neither a state nor a region,
    or a state without a sub-automaton, or for a bad ``rankdir`` / ``depth``.
    """
    if rankdir not in RANKDIRS:
        raise UsageError(f"rankdir must be one of {', '.join(RANKDIRS)}, not {rankdir!r}")
    if depth is not None and depth < 0:
        raise UsageError(f"depth must be 0 or more, not {depth}")
    autos, title = select(model, state_path)
    g = graphviz.Digraph(
        name=model.name,
        graph_attr={**GRAPH_ATTRS, "label": esc_lines([title])},
        node_attr=NODE_ATTRS,
        edge_attr=EDGE_ATTRS,
    )
    expanded = _expanded(autos, depth)
    if rankdir == "auto":
        trial = _Drawing(expanded, rows=False)
        trial.top(graphviz.Digraph(), autos)
        rankdir = choose_rankdir(trial.plan, SPACING)
    g.graph_attr["rankdir"] = rankdir
    # A first pass finds the groups of states drawn on one rank (rows, the
    # regions' initial states); dot keeps one such group per state, so groups
    # that share a state are written as one.
    first = _Drawing(expanded, rows=rankdir == "TB")
    first.top(graphviz.Digraph(), autos)
    drawing = _Drawing(expanded, rows=rankdir == "TB", merged=_merge(first.same))
    drawing.top(g, autos)
    if state_path is None and model.on_interrupt:
        drawing.interrupt(g, model)
    source: str = g.source
    return source if source.endswith("\n") else source + "\n"


def write_diagram(model: Model, out: Path, state_path: str | None, *, rankdir: str = "auto",
                  depth: int | None = None) -> None:
    """Write the diagram to ``out``: ``.dot`` source, or ``.svg`` / ``.png`` drawn by ``dot``.

    The file is written atomically: on any failure no partial file is left and
    an existing file is untouched.
    """
    source = to_dot(model, state_path, rankdir=rankdir, depth=depth)
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


@functools.cache
def font_warning() -> str | None:
    """What to tell the user when fontconfig has no FONT_FAMILY to draw with (None when it
    has, or when fontconfig's ``fc-match`` is not there to ask)."""
    try:
        got = subprocess.run(["fc-match", "-f", "%{family}", FONT_FAMILY], capture_output=True,
                             text=True, timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    if FONT_FAMILY in got.split(","):
        return None
    return (f"diagrams are drawn in {FONT_FAMILY}, which this machine lacks (fontconfig gives "
            f"{got.split(',')[0] or 'no font'}): labels may sit off their arrows; install "
            "fonts-liberation (apt-get install fonts-liberation)")


def _stderr_text(stderr: bytes | str | None) -> str:
    """The last lines dot wrote on stderr, on one line."""
    if isinstance(stderr, bytes):
        stderr = stderr.decode("utf-8", errors="replace")
    lines = [ln.strip() for ln in (stderr or "").splitlines() if ln.strip()]
    return shorten(" / ".join(lines[-3:]), 300) if lines else "no message"


# ---------------------------------------------------------------------------
# selection


def _expanded(autos: Automaton | tuple[Automaton, ...], depth: int | None,
              level: int = 1) -> frozenset[str]:
    """Paths of the composite states under ``autos`` drawn as clusters: those
    at most ``depth`` levels down (the states of ``autos`` are level 1, those
    of a state's sub-automaton or regions one more)."""
    out: set[str] = set()
    for a in (autos,) if isinstance(autos, Automaton) else autos:
        for s in a.states:
            if s.automata and (depth is None or level <= depth):
                out.add(s.path)
                out |= _expanded(s.automata, depth, level + 1)
    return frozenset(out)


# ---------------------------------------------------------------------------
# states


@dataclass
class _Drawing:
    """Draws into a graphviz graph and records the same boxes and arrows in a
    Plan, from which the direction is chosen."""

    expanded: frozenset[str]
    rows: bool  # small flat sub-automata in one row (top-to-bottom drawings)
    plan: Plan = field(default_factory=Plan)
    # Groups of node ids on one rank, in the order met; with ``merged`` (from a
    # first pass), the k-th group is written as merged[k], or not at all.
    same: list[tuple[str, ...]] = field(default_factory=list)
    merged: dict[int, tuple[str, ...]] | None = None

    def top(self, g: graphviz.Digraph, autos: tuple[Automaton, ...]) -> None:
        """What is drawn: one sub-automaton, or a state's regions side by side."""
        if len(autos) == 1:
            self.automaton(g, autos[0], level=1, clusters=())
            return
        # In an unseen cluster: dot orders clusters at the top level otherwise
        # than inside another (regions.__doc__).
        with g.subgraph(name="cluster_#regions") as c:
            c.attr(label="", peripheries="0", margin="0", id="#regions")
            self.regions(c, autos, level=1, clusters=("cluster_#regions",), fill=None)

    def automaton(self, g: graphviz.Digraph, auto: Automaton, level: int,
                  clusters: tuple[str, ...]) -> None:
        """The states of ``auto`` (clusters for composite ones), then its transitions.

        Everything goes in ``auto``'s own cluster: the label nodes of
        transitions must sit in the cluster of the sub-automaton they belong to.
        """
        for s in auto.states:
            initial = s.name == auto.initial
            if not s.automata or s.path not in self.expanded:
                attrs = _state_attrs(s, initial, level)
                g.node(_node_id(s), **attrs)
                self.plan.node(_node_id(s), _circle_size(attrs["label"]), clusters)
                continue
            cluster = _cluster_id(s.path)
            label = [name_line(s.name, s.automaton), state_note(s, initial)]
            self.plan.cluster_label[cluster] = text_size(label, CLUSTER_FONTSIZE)
            fill = CLUSTER_FILLS[(level - 1) % len(CLUSTER_FILLS)]
            with g.subgraph(name=cluster) as c:
                c.attr(
                    label=esc_lines(label, left=True),
                    style="rounded,filled" + (",bold" if initial else ""),
                    fillcolor=fill,
                    color=BORDER,
                    penwidth="2" if initial else "1.2",
                    fontsize=str(CLUSTER_FONTSIZE),
                    labeljust="l",
                    margin=str(CLUSTER_MARGIN),
                    tooltip=s.path,
                    id=s.path,
                )
                if s.automaton is not None:
                    self.automaton(c, s.automaton, level + 1, (*clusters, cluster))
                else:
                    self.regions(c, s.automata, level + 1, (*clusters, cluster), fill)
        row_of: dict[str, int] = {}
        for i, ids in enumerate(self.row_groups(auto, level)):
            self.row(g, ids)
            row_of.update(dict.fromkeys(ids, i))
        for s in auto.states:
            for t in s.transitions:
                self.transition(g, s, t, auto, clusters, row_of)

    def regions(self, g: graphviz.Digraph, regions: tuple[Automaton, ...], level: int,
                clusters: tuple[str, ...], fill: str | None) -> None:
        """Each region a dashed cluster (tinted as its state's, ``fill``) labelled
        with its name and period, in the order written; their initial states on
        one rank, so that the regions stand side by side, not one after another.

        Of clusters that share ranks, dot puts the one declared last first (a
        left-to-right drawing flips that to the order declared, top to bottom),
        so top to bottom the regions are declared last first.  It is what dot
        starts from; to cross fewer arrows it may still swap regions."""
        for a in reversed(regions) if self.rows else regions:
            cluster = _cluster_id(a.path)
            label = [name_line(a.region or "", a), automaton_note(a)]
            self.plan.cluster_label[cluster] = text_size(label, CLUSTER_FONTSIZE)
            with g.subgraph(name=cluster) as c:
                c.attr(
                    label=esc_lines(label, left=True),
                    style="rounded,dashed" + (",filled" if fill else ""),
                    color=BORDER,
                    penwidth="1.5",
                    fontsize=str(CLUSTER_FONTSIZE),
                    labeljust="l",
                    margin=str(CLUSTER_MARGIN),
                    tooltip=a.path,
                    id=a.path,
                    **({"fillcolor": fill} if fill else {}),
                )
                self.automaton(c, a, level, (*clusters, cluster))
        starts = [_node_id(self.entry_anchor(s)) for a in regions
                  if (s := a.state(a.initial)) is not None]
        self.plan.aligned.append(tuple(starts))
        self.same_rank(g, starts)

    def same_rank(self, g: graphviz.Digraph, ids: list[str]) -> None:
        """``ids`` on one rank (``rank=same``), merged with the groups that share a node."""
        k = len(self.same)
        self.same.append(tuple(ids))
        written = ids if self.merged is None else self.merged.get(k, ())
        if written:
            with g.subgraph() as same:
                same.attr(rank="same")
                for node_id in written:
                    same.node(node_id)

    def is_pair(self, auto: Automaton) -> bool:
        """Whether a nested sub-automaton is a pair of simple states (or one)."""
        return len(auto.states) <= ROW_MAX and not any(s.path in self.expanded
                                                       for s in auto.states)

    def row_groups(self, auto: Automaton, level: int) -> list[list[str]]:
        """The rows ``auto``'s states are drawn in top to bottom: a nested pair
        in one row; a chain (each state's arrows only to the next one, from
        the initial state on) wrapped in rows of CHAIN_ROW states, read like
        text; else none."""
        if level > 1 and self.is_pair(auto):
            return [[_node_id(s) for s in auto.states]]
        ids = [_node_id(s) for s in _chain(auto, self.expanded)]
        return [ids[i:i + CHAIN_ROW] for i in range(0, len(ids), CHAIN_ROW)]

    def row(self, g: graphviz.Digraph, ids: list[str]) -> None:
        """States on one rank, when drawn top to bottom: they then take the
        height of one state, not of a column."""
        self.plan.rows.append(tuple(ids))
        if self.rows:
            self.same_rank(g, ids)

    def transition(self, g: graphviz.Digraph, src: State, t: Transition, parent: Automaton,
                   clusters: tuple[str, ...], row_of: dict[str, int]) -> None:
        dst = parent.state(t.target)
        if dst is None:  # cannot happen in a checked model
            raise UsageError(f"transition of `{src.path}` to unknown state `{t.target}`")
        lines = _label_lines(t, numbered=len(src.transitions) > 1)
        label = esc_lines(lines, left=True)
        size = text_size(lines, float(EDGE_ATTRS["fontsize"]), em=0.48)
        tail, head = _node_id(self.exit_anchor(src)), _node_id(self.entry_anchor(dst))
        out_of = src.path in self.expanded
        into = dst.path in self.expanded
        ident = _transition_id(src, t)
        in_row = row_of.get(tail, -1) == row_of.get(head, -2)  # both in one row
        # A self-transition in a row runs through a label node on the row's rank: dot puts
        # an ordinary self-loop's label beside it, over the label of the arrow to the row's
        # next state.
        loop_in_row = in_row and tail == head and bool(clusters)
        if not out_of and not into and (not clusters or in_row) and not loop_in_row:
            g.edge(tail, head, label=label, id=ident)
            self.plan.edge(tail, head, size)
            return
        # To or from a composite state: the edge runs between anchor nodes and
        # is clipped at the cluster's border.  dot would place an ordinary
        # label at the middle of the unclipped edge, possibly inside the
        # cluster (and an xlabel gets no room and overlaps nodes), so the
        # label is a small text node of its own, outside the clusters, that
        # the arrow runs through.  It also lets a composite state's
        # self-transition leave the cluster and come back, which a single
        # edge clipped twice by one cluster cannot do.  Inside a cluster too,
        # the label is a node: dot does not grow a cluster around an
        # ordinary label, which then sticks out of its border.  Arrows within
        # a row are the exception: their labels sit between its states.
        via = f"#{src.path} {t.index}"  # `#` and spaces never occur in a path
        g.node(via, label=label, shape="plaintext", style="", width="0", height="0",
               margin="0.04,0.02", fontsize=EDGE_ATTRS["fontsize"], id=f"{ident}:label")
        self.plan.node(via, size, clusters)
        if loop_in_row and self.rows:
            self.same_rank(g, [tail, via])
        g.edge(tail, via, arrowhead="none", id=ident,
               **({"ltail": _cluster_id(src.path)} if out_of else {}))
        g.edge(via, head, id=f"{ident}:head", **({"lhead": _cluster_id(dst.path)} if into else {}))
        self.plan.edge(tail, via)
        self.plan.edge(via, head)

    def interrupt(self, g: graphviz.Digraph, model: Model) -> None:
        """A dashed arrow from an ``interrupt`` marker to the ``on_interrupt``
        state (dot puts the marker, whose only edge is this one, just before
        the state, not at the start)."""
        target = model.root.state(model.on_interrupt or "")
        if target is None:  # cannot happen in a checked model
            return
        lines = ["interrupt"]
        if model.interrupt_timeout_us is not None:
            lines.append(f"timeout {format_us(model.interrupt_timeout_us)}")
        if model.time_limit_us is not None:
            lines.append(f"time limit {format_us(model.time_limit_us)}")
        marker = "#interrupt"
        head = _node_id(self.entry_anchor(target))
        g.node(marker, label=esc_lines(lines), shape="octagon", style="filled",
               fillcolor="#fbe9e7", color=INTERRUPT_COLOR, fontcolor=INTERRUPT_COLOR,
               fontsize=EDGE_ATTRS["fontsize"], width="0", height="0", margin="0.06,0.03",
               tooltip=f"on_interrupt: {target.path}", id=marker)
        into = {"lhead": _cluster_id(target.path)} if target.path in self.expanded else {}
        g.edge(marker, head, style="dashed", color=INTERRUPT_COLOR, id=f"{marker}:head", **into)

    def entry_anchor(self, s: State) -> State:
        """The node an edge into ``s`` attaches to: ``s``, or its initial leaf.

        The initial child is what the layout puts first in a cluster, so edges
        come in where the sub-automaton starts (the first region's, for regions).
        """
        while s.automata and s.path in self.expanded:
            child = s.automata[0].state(s.automata[0].initial)
            if child is None:  # cannot happen in a checked model
                break
            s = child
        return s

    def exit_anchor(self, s: State) -> State:
        """The node an edge out of ``s`` attaches to: ``s``, or a leaf far from the start.

        With ``newrank`` an edge's tail node sets the rank of its head;
        leaving from the child farthest (in transitions) from the initial one
        puts the target after the whole cluster, not beside it.  A row is on
        one rank: arrows leave where they come in, from the initial state, so
        that clusters in a chain stay in line instead of stepping sideways.
        Of regions, the one whose farthest child is farthest is left from.
        """
        while s.automata and s.path in self.expanded:
            if self.rows and all(self.is_pair(a) for a in s.automata):
                return self.entry_anchor(s)
            s = max((_farthest(a) for a in s.automata), key=lambda far: far[1])[0]
        return s


def _merge(groups: list[tuple[str, ...]]) -> dict[int, tuple[str, ...]]:
    """Groups that share a node, joined: each written where the last of them
    is (the outermost: inner sub-automata are drawn first); others nowhere."""
    owner = list(range(len(groups)))

    def find(k: int) -> int:
        while owner[k] != k:
            k = owner[k]
        return k

    first_with: dict[str, int] = {}
    for k, group in enumerate(groups):
        for node_id in group:
            if node_id in first_with:
                owner[find(first_with[node_id])] = find(k)
            else:
                first_with[node_id] = k
    joined: dict[int, list[str]] = {}
    last: dict[int, int] = {}
    for k, group in enumerate(groups):
        root = find(k)
        joined.setdefault(root, []).extend(n for n in group if n not in joined[root])
        last[root] = k
    return {last[root]: tuple(ids) for root, ids in joined.items()}


def _state_attrs(s: State, initial: bool, level: int) -> dict[str, str]:
    attrs = {
        "label": esc_lines([s.name]),  # never shortened: names tell states apart
        "tooltip": s.path,  # identifiers and `/`: nothing to escape
        "id": s.path,
    }
    if initial:
        attrs["shape"] = "doublecircle"
    if s.final:
        attrs["fillcolor"] = FINAL_FILL
        attrs["penwidth"] = "2"
    if s.automata:  # a composite state below the depth drawn
        count, what = (len(s.automata), "region") if s.parallel else (
            len(s.automata[0].states), "state")
        attrs["label"] = esc_lines([s.name, f"({count} {what}{'s' * (count != 1)})"])
        attrs["fillcolor"] = CLUSTER_FILLS[(level - 1) % len(CLUSTER_FILLS)]
        attrs["color"] = BORDER
        attrs["penwidth"] = "2"
    return attrs


def _circle_size(label: str) -> tuple[float, float]:
    """A state circle's diameter (points) for its escaped label, as dot sizes it."""
    lines = label.split("\\n")
    width, height = text_size(lines, float(NODE_ATTRS["fontsize"]))
    d = max(_inches(NODE_ATTRS["width"]), 1.36 * max(width, height) + 8)
    return d, d


def _node_id(s: State) -> str:
    # The path itself: unique, and quoted by the graphviz package whenever
    # needed (a `/`, a DOT keyword such as `node`); it never holds a `:`,
    # which graphviz would read as a port.
    return s.path


def _cluster_id(path: str) -> str:
    """A composite state's or a region's cluster: ``cluster_`` and its path."""
    return f"cluster_{path}"


def _transition_id(src: State, t: Transition) -> str:
    """``PATH#N``: the SVG id of a transition, as a trace's ``fire`` record
    names it (``from``, ``index``); ``#`` occurs in no path."""
    return f"{src.path}#{t.index}"


def _chain(auto: Automaton, expanded: frozenset[str]) -> list[State]:
    """``auto``'s states in order when they form a chain: three or more
    simple states, from the initial one each with arrows to one next state
    only (and to itself), every state on the way; else nothing."""
    if len(auto.states) < 3 or any(s.path in expanded for s in auto.states):
        return []
    order: list[State] = []
    s = auto.state(auto.initial)
    while s is not None and s not in order:
        order.append(s)
        targets = {t.target for t in s.transitions} - {s.name}
        if len(targets) > 1:
            return []
        s = auto.state(targets.pop()) if targets else None
    return order if s is None and len(order) == len(auto.states) else []


def _farthest(auto: Automaton) -> tuple[State, int]:
    """The child of ``auto`` with the longest shortest path from the initial child
    (the last such in model order), and that length; unreachable children do
    not count."""
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
    return best, dist[best.name]


# ---------------------------------------------------------------------------
# transition labels


def _label_lines(t: Transition, numbered: bool) -> list[str]:
    """Name, ``[when]`` and ``after`` lines, wrapped; ``N.`` first when the
    state has several transitions (N: the order in which they are tried)."""
    lines: list[str] = []
    if t.name:
        lines += wrap(one_line(t.name), WRAP)
    if t.when is not None:
        lines += wrap("[" + one_line(t.when.text) + "]", WRAP, indent=" ")
    if t.after_us is not None:
        lines.append(f"after {format_us(t.after_us)}")
    if numbered:
        lines[0] = f"{t.index + 1}. {lines[0]}"
    return lines
