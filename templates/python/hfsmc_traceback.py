# hfsmc_traceback.py: a snippet's error, written at its model positions.
# Copied unchanged into every component folder; standard library only.
"""The report of an exception raised in a snippet (docs/semantics.md §9): the line
map of the generated modules turns each of their frames into a model position;
the runtime's own frames are left out, the others (a driver's, a library's) kept."""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable, Sequence
from typing import Any

# The runtime's own files (one file once): their frames are not the model's nor a driver's.
_HERE = os.path.dirname(os.path.abspath(__file__))
_RUNTIME = frozenset(os.path.join(_HERE, f) for f in (
    "hfsmc_runtime.py", "hfsmc_trace.py", "hfsmc_traceback.py", "hfsmc_load.py", "hfsmc_main.py"))


def reporter(sources: Sequence[tuple[str, str, int, int]], snippets: Sequence[tuple[Any, ...]],
             paths: Sequence[str]) -> Callable[[BaseException, int], str]:
    """The function that writes a snippet error as model positions (docs/semantics.md §9).

    ``snippets[sid]`` = (kind, state, first generated line, rows) with rows =
    ((model line, model col, generated indent), ...) for each line of the snippet;
    ``sources`` = (model file, generated file, first sid, number of snippets) of the
    component's own code, then of each instance of a used file (its file's module).
    """
    from bisect import bisect_right
    starts = [s[2] for s in sources]
    # Per source: its snippets' first generated lines, sorted, and their numbers.
    lines: list[list[int]] = []
    order: list[list[int]] = []
    for _model, _gen, sid0, n in sources:
        ids = sorted(range(sid0, sid0 + n), key=lambda s: snippets[s][2])
        order.append(ids)
        lines.append([snippets[s][2] for s in ids])

    def source_of(sid: int) -> int:
        return bisect_right(starts, sid) - 1

    def locate(src: int, fs: traceback.FrameSummary) -> tuple[int, int, int, int] | None:
        if os.path.abspath(fs.filename) != os.path.abspath(sources[src][1]) or fs.lineno is None:
            return None
        k = bisect_right(lines[src], fs.lineno) - 1
        if k < 0:
            return None
        sid = order[src][k]
        first, rows = snippets[sid][2], snippets[sid][3]
        row = fs.lineno - first
        if not 0 <= row < len(rows):
            return None
        line, col, indent = rows[row]
        colno = getattr(fs, "colno", None)
        return sid, line, col + max((colno or indent) - indent, 0), row

    def where(sid: int) -> str:
        kind, state = snippets[sid][0], snippets[sid][1]
        name = paths[state] if state < len(paths) else ""
        return f"{kind} of {name}" if name else kind

    def report(exc: BaseException, sid: int) -> str:
        src = source_of(sid)
        file = sources[src][0]
        frames = traceback.extract_tb(exc.__traceback__)
        head = (sid, snippets[sid][3][0][0], snippets[sid][3][0][1], -1)
        body: list[str] = []
        for fs in frames:
            hit = locate(src, fs)
            if hit is not None:
                head = hit
                body.append(f"  {file}:{hit[1]} in {where(hit[0])}\n    {(fs.line or '').strip()}\n")
            elif os.path.abspath(fs.filename) not in _RUNTIME and not (
                    fs.name == "__getattr__" and os.path.dirname(os.path.abspath(fs.filename))
                    == _HERE):  # a driver naming what it lacks: its own words
                body.append(f'  File "{fs.filename}", line {fs.lineno}, in {fs.name}\n'
                            f"    {(fs.line or '').strip()}\n")
        what = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        state = snippets[sid][1]
        name = paths[state] if state < len(paths) else ""
        context = f"  in {snippets[sid][0]} of state `{name}`\n" if name else \
            f"  in {snippets[sid][0]}\n"
        return (f"{file}:{head[1]}:{head[2]}: error: {what}\n{context}"
                "Traceback (most recent call last, model lines):\n" + "".join(body))

    return report
