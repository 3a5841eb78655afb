"""The structure a component tells its observers (the monitor's ``hello``,
schemas/monitor.schema.json), written from its model: what ``hfsmc view`` and
the web view show when they are given the model instead of the component's own.
"""

from __future__ import annotations

from typing import Any

from hfsmc.emit.data import thaw
from hfsmc.ir import Model


def structure_of(model: Model) -> dict[str, Any]:
    """The structure a component gives its observers (``Observer.start``), from its model."""

    def sibling(path: str, name: str) -> str:
        parent = path.rpartition("/")[0]
        return f"{parent}/{name}" if parent else name

    return {
        "name": model.name,
        "automata": [{"owner": a.owner, "region": a.region,
                      "use": a.instance.written if a.instance is not None else None,
                      "period_ms": a.period_ms,
                      "initial": a.initial,
                      "history": a.history} for a in model.automata()],
        "states": [{"path": s.path, "final": s.final, "composite": s.composite}
                   for s in model.states()],
        "transitions": [{"from": s.path, "to": sibling(s.path, t.target), "index": t.index,
                         "name": t.name} for s in model.states() for t in s.transitions],
        "variables": [v.name for v in model.variables],
        "parameters": {p.name: repr(thaw(p.default)) for p in model.parameters},
    }
