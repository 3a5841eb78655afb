"""What ``hfsmc diagram --state PATH`` draws: a state's sub-automaton or regions, or a region.

A wrong path gets the nearest valid ones: the path with the regions it
left out put back (``Mission/Follow`` -> ``Mission/Nav/Follow``), else the
paths spelt most alike, else the list of what can be drawn.
"""

from __future__ import annotations

import difflib

from hfsmc.durations import format_us
from hfsmc.emit.dot_text import automaton_note, name_line, state_note
from hfsmc.errors import UsageError
from hfsmc.ir import Automaton, Model


def select(model: Model, state_path: str | None) -> tuple[tuple[Automaton, ...], str]:
    """The sub-automaton (or the regions) to draw and the diagram's title."""
    root_period = format_us(model.root.period_ms * 1000)
    if state_path is None:
        return (model.root,), f"{model.name} · period {root_period}"
    state = model.find(state_path)
    if state is not None and state.automata:
        name = name_line(state.path, state.automaton)
        return state.automata, f"{model.name}: {name} · {state_note(state)}"
    region = model.automaton_at(state_path) if state is None else None
    if region is not None and region.region is not None:
        # A region alone is drawn as a sub-automaton is: its states, no dashed box.
        return (region,), f"{model.name}: {region.path} · region · {automaton_note(region)}"
    drawable = _drawable(model)
    if state is None:
        msg = f"--state {state_path}: no such state or region in model `{model.name}`"
        near = _nearest(state_path, drawable)
        raise UsageError(f"{msg} (did you mean {near}?)" if near else msg + _listing(drawable))
    raise UsageError(
        f"--state {state_path}: state `{state.path}` has no sub-automaton to draw"
        + _listing(drawable)
    )


def _drawable(model: Model) -> dict[str, bool]:
    """What ``--state`` takes, in model order: the paths of composite states
    (False) and of regions (True)."""
    out: dict[str, bool] = {}
    for s in model.states():
        if s.automata:
            out[s.path] = False
            if s.parallel:
                out.update(dict.fromkeys((a.path for a in s.automata), True))
    return out


def _nearest(path: str, drawable: dict[str, bool]) -> str | None:
    """The valid paths nearest a wrong one, quoted: a composite state's path
    that is ``path`` with region names added (``Mission/Nav/Go`` for
    ``Mission/Go``), else up to three spelt alike."""
    regions = sorted((p for p, is_region in drawable.items() if is_region), key=len, reverse=True)

    def without_regions(p: str) -> str:
        for r in regions:  # innermost first
            if p.startswith(r + "/"):
                return without_regions(r.rpartition("/")[0] + p[len(r):])
        return p

    close = [p for p, is_region in drawable.items()
             if not is_region and p != path and without_regions(p) == path]
    if not close:  # the best match, and those nearly as good
        ratios = {p: difflib.SequenceMatcher(None, path, p).ratio() for p in drawable}
        best = max(ratios.values(), default=0.0)
        close = sorted((p for p, r in ratios.items() if r >= max(0.6, best - 0.05)),
                       key=lambda p: -ratios[p])[:3]
    return " or ".join(f"`{p}`" for p in close) or None


def _listing(drawable: dict[str, bool]) -> str:
    if not drawable:
        return "; this model has no composite state"
    if not any(drawable.values()):
        return "; composite states: " + ", ".join(drawable)
    return "; composite states and regions: " + ", ".join(
        f"{p} (region)" if is_region else p for p, is_region in drawable.items())
