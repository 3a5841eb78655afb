"""The text of diagram labels: wrapped over lines, escaped for Graphviz.

Labels are Graphviz escStrings: backslashes are doubled (no ``\\N``, ``\\l``
surprises), ``&`` becomes ``&amp;`` (Graphviz decodes entities even in plain
labels), ``<...>`` is never taken for an HTML label (``graphviz.nohtml``) and
quotes are escaped by the ``graphviz`` package.  Long lines are wrapped, not
cut (docs/diagrams.md).  The titles of boxes (a state's or a region's name,
the file a used sub-automaton comes from, periods) are written here too.
"""

from __future__ import annotations

import unicodedata

import graphviz

from hfsmc.durations import format_us
from hfsmc.ir import Automaton, State

# Label lines (names, conditions) are wrapped at this many characters, at
# spaces and preferably before `and` / `or`; a condition longer than
# MAX_LINES lines (a rare, unreadable thing on a diagram anyway) ends in "…".
WRAP = 30
MAX_LINES = 8
ELLIPSIS = "…"
# A long word's first part goes after a line's words when it has this many characters.
MIN_PART = 8
BREAK_BEFORE = frozenset({"and", "or", "&&", "||"})


def wrap(text: str, width: int, indent: str = "") -> list[str]:
    """``text`` over lines of at most ``width`` characters, broken at spaces,
    before ``and`` / ``or`` once a line is half full, and inside words only
    when one is longer than a line (after ``(``, before ``.`` and the like
    if it can); continuation lines start with ``indent``.
    Two or three lines are balanced (as narrow as their number allows: no
    lone ``0.3]`` on the last line); more than MAX_LINES lines end in an
    ellipsis.  Joining the lines (their indent removed) with spaces gives
    ``text`` back, but for words cut."""
    lines = _greedy(text, width, indent)
    longest = max(len(word) for word in text.split(" "))
    narrower = width - 1
    while 1 < len(lines) <= 3 and narrower - len(indent) >= longest:  # no new cuts in words
        tighter = _greedy(text, narrower, indent)
        if len(tighter) > len(lines) or _operator_starts(tighter) < _operator_starts(lines):
            break
        lines, narrower = tighter, narrower - 1
    if len(lines) > MAX_LINES:
        lines = lines[:MAX_LINES]
        lines[-1] = lines[-1][: width - 1].rstrip() + ELLIPSIS
    return lines


def _operator_starts(lines: list[str]) -> int:
    """How many continuation lines start with ``and`` / ``or``."""
    return sum(bool(ln.split()) and ln.split()[0] in BREAK_BEFORE for ln in lines[1:])


def _cut(word: str, room: int) -> int:
    """Where to cut a word too long for a line of ``room`` characters: after
    an opening parenthesis or a comma, else before ``.``, ``::`` or ``->``,
    else after ``[`` or ``/`` (a state's path), as far on as the line allows;
    else at the line's end, but never inside a name that fits on a line of
    its own (``LinkLost`` is not drawn as ``LinkLos`` / ``t``)."""
    tiers = (
        [i + 1 for i, ch in enumerate(word) if ch in "(,"],
        [i for i in range(1, len(word)) if word.startswith((".", "::", "->"), i)
         and not word.startswith("::", i - 1)],
        [i + 1 for i, ch in enumerate(word) if ch in "[/"],
    )
    for tier in tiers:
        fitting = [i for i in tier if room // 3 <= i <= room]
        if fitting:
            return max(fitting)
    start = room
    while start > 0 and _in_name(word[start - 1]) and _in_name(word[start]):
        start -= 1
    end = room
    while end < len(word) and _in_name(word[end]):
        end += 1
    return start if start > 0 and end - start <= room else room


def _in_name(ch: str) -> bool:
    return ch.isalnum() or ch == "_"


def _greedy(text: str, width: int, indent: str) -> list[str]:
    """``text`` wrapped greedily at ``width`` (see wrap)."""
    lines: list[str] = []
    line = ""
    for word in text.split(" "):
        while True:  # a word longer than a line: cut, its first part after the line's words
            room = width - (0 if not lines and not line else len(indent))
            if len(word) <= room:
                break
            if line:
                free = room - len(line) - 1
                cut = _cut(word, free) if free >= MIN_PART else 0
                if cut > 0 and not (_in_name(word[cut - 1]) and _in_name(word[cut])):
                    lines.append(f"{line} {word[:cut]}")
                    word = word[cut:]
                else:
                    lines.append(line)
                line = ""
                continue
            cut = _cut(word, room)
            lines.append(word[:cut])
            word = word[cut:]
        room = width - (len(indent) if lines else 0)
        if line and (len(line) + 1 + len(word) > room
                     or (word in BREAK_BEFORE and len(line) >= room // 2)):
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    lines.append(line)
    return [lines[0], *(indent + ln for ln in lines[1:])]


def one_line(text: str) -> str:
    """A name or snippet on one line: its lines stripped and joined by spaces."""
    return " ".join(part for part in (ln.strip() for ln in text.splitlines()) if part)


def shorten(text: str, limit: int) -> str:
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


def esc_lines(lines: list[str], left: bool = False) -> str:
    """Label lines, centred (or left-justified), never taken for an HTML label."""
    if left:
        text = "".join(_esc(line) + "\\l" for line in lines)
    else:
        text = "\\n".join(_esc(line) for line in lines)
    label: str = graphviz.nohtml(text)
    return label


def name_line(name: str, auto: Automaton | None) -> str:
    """A cluster's first line: the name, then the file a used sub-automaton
    comes from (``TakeOff · lib/takeoff.yaml``)."""
    if auto is None or auto.instance is None:
        return name
    return f"{name} · {auto.instance.written}"


def state_note(s: State, initial: bool = False) -> str:
    """A composite state's second line: its sub-automaton's period, or how
    many regions it has (each says its own period)."""
    if s.automaton is not None:
        return automaton_note(s.automaton, initial)
    note = f"{len(s.automata)} regions"
    return "initial · " + note if initial else note


def automaton_note(auto: Automaton, initial: bool = False) -> str:
    """``period 100ms``, with `` · history`` when on; a composite initial state
    (a cluster cannot be a double circle) says ``initial`` first."""
    note = f"period {format_us(auto.period_ms * 1000)}"
    if auto.history:
        note += " · history"
    return "initial · " + note if initial else note
