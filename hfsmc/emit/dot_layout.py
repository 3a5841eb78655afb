"""The direction of a diagram: how large would ``dot`` draw it left to right or top to bottom?

``hfsmc diagram`` picks ``rankdir`` (LR or TB) from the model's shape before
any Graphviz runs, so that the DOT source (and the golden files) stay the same
whether Graphviz is installed or not.  The estimate imitates what ``dot``
does with a graph: it breaks cycles by a depth-first walk in declaration
order, puts every node on a rank (longest path; every edge spans two ranks
because the graph has labels, the label on the rank between), then adds up
the ranks' depths along the direction of the arrows and takes the widest
rank across it.  Text is measured with average glyph widths of the sans
font.  It is meant to be within some tens of percent of the real drawing,
which is enough to choose a direction (docs/diagrams.md says how).
"""

from __future__ import annotations

from dataclasses import dataclass, field

# The screen a diagram should read on at 100 %, in pixels, and dot's pixels
# per point in PNG output (96 dpi).
SCREEN_W, SCREEN_H = 1920, 1080
PX_PER_PT = 96 / 72


@dataclass
class Plan:
    """What a diagram holds, for the estimate: boxes (points) and arrows.

    ``nodes`` maps node ids, in the order they are declared, to their size;
    ``clusters`` maps a node id to the ids of the clusters holding it
    (outermost first); an edge carries the size of its label, if any.
    """

    nodes: dict[str, tuple[float, float]] = field(default_factory=dict)
    clusters: dict[str, tuple[str, ...]] = field(default_factory=dict)
    edges: list[tuple[str, str, tuple[float, float] | None]] = field(default_factory=list)
    cluster_label: dict[str, tuple[float, float]] = field(default_factory=dict)
    # Node ids that share a rank when drawn top to bottom (rank=same).
    rows: list[tuple[str, ...]] = field(default_factory=list)
    # Node ids that share a rank in both directions: the initial states of
    # parallel regions, drawn side by side.
    aligned: list[tuple[str, ...]] = field(default_factory=list)

    def node(self, node_id: str, size: tuple[float, float], clusters: tuple[str, ...]) -> None:
        self.nodes[node_id] = size
        self.clusters[node_id] = clusters

    def edge(self, tail: str, head: str, label: tuple[float, float] | None = None) -> None:
        self.edges.append((tail, head, label))


@dataclass(frozen=True)
class Spacing:
    """The graph attributes the estimate depends on, in points."""

    ranksep: float
    nodesep: float
    cluster_margin: float
    title_height: float
    pad: float


def text_size(lines: list[str], fontsize: float, em: float = 0.5) -> tuple[float, float]:
    """Width and height (points) of text lines: ``em`` is the mean glyph width
    as a fraction of the font size (about 0.5, a little more than Liberation
    Sans's mean: the estimate errs on the wide side)."""
    width = max((len(line) for line in lines), default=0) * fontsize * em
    return width, len(lines) * fontsize * 1.2


def choose_rankdir(plan: Plan, spacing: Spacing) -> str:
    """``LR`` when the left-to-right drawing fits the screen, else the
    direction that overflows it least, overflowing sideways counting twice
    (a wheel scrolls down, not across)."""
    lr = estimate(plan, spacing, "LR")
    if fits(lr):
        return "LR"
    tb = estimate(plan, spacing, "TB")
    return "TB" if fits(tb) or overflow(tb) < overflow(lr) else "LR"


def fits(size: tuple[float, float]) -> bool:
    return size[0] <= SCREEN_W and size[1] <= SCREEN_H


def overflow(size: tuple[float, float]) -> float:
    """Screens needed to see the whole drawing, sideways screens squared."""
    return max(1.0, size[0] / SCREEN_W) ** 2 * max(1.0, size[1] / SCREEN_H)


def estimate(plan: Plan, spacing: Spacing, rankdir: str) -> tuple[float, float]:
    """The drawing's estimated width and height in PNG pixels."""
    lr = rankdir == "LR"
    ranks = _ranks(plan, rows=not lr)
    depth: dict[int, float] = {}  # along the arrows
    across: dict[int, float] = {}
    count: dict[int, int] = {}

    def put(rank: int, size: tuple[float, float]) -> None:
        along, side = (size[0], size[1]) if lr else (size[1], size[0])
        depth[rank] = max(depth.get(rank, 0.0), along)
        across[rank] = across.get(rank, 0.0) + side
        count[rank] = count.get(rank, 0) + 1

    for node_id, size in plan.nodes.items():
        put(ranks[node_id], size)
    for tail, head, label in plan.edges:
        lo, hi = sorted((ranks[tail], ranks[head]))
        if lo == hi and tail != head and label is not None:  # in a row: the label goes between
            across[lo] = across.get(lo, 0.0) + label[0]
        for r in range(lo + 1, hi):  # a long edge takes room on every rank it crosses
            put(r, label if label is not None and r == lo + 1 else (4.0, 4.0))
    if not depth:
        return (0.0, 0.0)
    first, last = min(depth), max(depth)
    along = sum(depth.values()) + (last - first) * (spacing.ranksep + 1) / 2
    along += _cluster_depth(plan, ranks, spacing, lr)
    side = max(across[r] + spacing.nodesep * (count[r] - 1) for r in across)
    nesting = max((len(c) for c in plan.clusters.values()), default=0)
    side += nesting * 2 * spacing.cluster_margin
    if lr:  # cluster labels sit at the top, across the arrows
        side += nesting * max((h for _, h in plan.cluster_label.values()), default=0.0)
    width, height = (along, side) if lr else (side, along)
    height += spacing.title_height
    return ((width + 2 * spacing.pad) * PX_PER_PT, (height + 2 * spacing.pad) * PX_PER_PT)


def _ranks(plan: Plan, rows: bool) -> dict[str, int]:
    """Each node's rank: cycles broken depth first in declaration order, then
    the longest path from the sources, two ranks per edge; the nodes of an
    aligned group, and with ``rows`` of a row, count as one."""
    rep = _groups(plan.nodes, [*(plan.rows if rows else []), *plan.aligned])
    nodes = dict.fromkeys(rep[n] for n in plan.nodes)
    out_edges: dict[str, list[str]] = {n: [] for n in nodes}
    for tail, head, _ in plan.edges:
        if rep[tail] != rep[head]:
            out_edges[rep[tail]].append(rep[head])
    state: dict[str, int] = {}  # 1 on the walk's stack, 2 done
    kept: dict[str, list[str]] = {n: [] for n in nodes}
    for root in nodes:
        if root in state:
            continue
        state[root] = 1
        stack = [(root, iter(out_edges[root]))]
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                state[node] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                kept[nxt].append(node)  # a back edge: dot reverses it
            else:
                kept[node].append(nxt)
                if nxt not in state:
                    state[nxt] = 1
                    stack.append((nxt, iter(out_edges[nxt])))
    rank = {n: 0 for n in nodes}
    for node in _topological(nodes, kept):
        for nxt in kept[node]:
            rank[nxt] = max(rank[nxt], rank[node] + 2)
    return {n: rank[rep[n]] for n in plan.nodes}


def _groups(nodes: dict[str, tuple[float, float]], groups: list[tuple[str, ...]]
            ) -> dict[str, str]:
    """Each node's representative: groups that share a node merge (a row of
    a region holding its initial state is aligned with the other regions)."""
    rep = {n: n for n in nodes}

    def find(n: str) -> str:
        while rep[n] != n:
            n = rep[n]
        return n

    for group in groups:
        first = find(group[0])
        for n in group[1:]:
            rep[find(n)] = first
    return {n: find(n) for n in nodes}


def _topological(nodes: dict[str, None], succ: dict[str, list[str]]) -> list[str]:
    indegree = {n: 0 for n in nodes}
    for n in nodes:
        for m in succ[n]:
            indegree[m] += 1
    ready = [n for n in nodes if indegree[n] == 0]
    order: list[str] = []
    while ready:
        n = ready.pop()
        order.append(n)
        for m in succ[n]:
            indegree[m] -= 1
            if indegree[m] == 0:
                ready.append(m)
    return order


def _cluster_depth(plan: Plan, ranks: dict[str, int], spacing: Spacing, lr: bool) -> float:
    """Room that clusters take along the arrows: margins at both ends, and
    (top to bottom) the label above the first rank; clusters that start or
    end on the same rank share it."""
    first: dict[str, int] = {}
    last: dict[str, int] = {}
    for node_id, holders in plan.clusters.items():
        for c in holders:
            first[c] = min(first.get(c, ranks[node_id]), ranks[node_id])
            last[c] = max(last.get(c, ranks[node_id]), ranks[node_id])
    starts: dict[int, float] = {}
    ends: dict[int, float] = {}
    for c in first:
        head = spacing.cluster_margin + (0.0 if lr else plan.cluster_label.get(c, (0.0, 0.0))[1])
        starts[first[c]] = starts.get(first[c], 0.0) + head
        ends[last[c]] = ends.get(last[c], 0.0) + spacing.cluster_margin
    return sum(starts.values()) + sum(ends.values())
