"""Text edits: a splice of the text between two offsets, and their application."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


class EditError(Exception):
    """An operation that cannot be made on this text (the message says why, in one line)."""


@dataclass(frozen=True, slots=True)
class TextEdit:
    """Replace ``text[start:end]`` with ``new`` (offsets into the text before any edit)."""

    start: int
    end: int
    new: str


def apply_edits(text: str, edits: Iterable[TextEdit]) -> str:
    """``text`` with ``edits`` made; they may not overlap (an insertion at one offset is
    made in the order given)."""
    ordered = sorted(enumerate(edits), key=lambda ie: (ie[1].start, ie[1].end, ie[0]))
    out: list[str] = []
    pos = 0
    for _, e in ordered:
        if e.start < pos or e.end < e.start or e.end > len(text):
            raise EditError(f"overlapping or out-of-range edits at offset {e.start}")
        out.append(text[pos:e.start])
        out.append(e.new)
        pos = e.end
    out.append(text[pos:])
    return "".join(out)


def insert_into(chunk: str, base: int, inserts: Iterable[tuple[int, str]],
                keep: list[tuple[int, int]] | None = None) -> tuple[str, list[tuple[int, int]]]:
    """``chunk`` (the text from offset ``base``) with each ``(offset, text)`` of ``inserts``
    that falls inside it inserted, and ``keep``'s ranges (offsets into the chunk) moved
    with the text around them."""
    ranges = list(keep or [])
    out, pos = [], 0
    for off, new in sorted(i for i in inserts if base <= i[0] < base + len(chunk)):
        at = off - base
        out += [chunk[pos:at], new]
        pos = at
        ranges = [(s + (len(new) if at <= s else 0), e + (len(new) if at <= e else 0))
                  for s, e in ranges]
    out.append(chunk[pos:])
    return "".join(out), ranges


def line_start(text: str, off: int) -> int:
    """The offset where the line holding ``off`` starts."""
    return max(text.rfind("\n", 0, off), text.rfind("\r", 0, off)) + 1


def line_end(text: str, off: int) -> int:
    """The offset of the line break ending the line holding ``off`` (or the text's end)."""
    n = text.find("\n", off)
    r = text.find("\r", off)
    ends = [e for e in (n, r) if e >= 0]
    return min(ends) if ends else len(text)


def after_break(text: str, off: int) -> int:
    """``off`` (at a line break) moved past that break."""
    if text.startswith("\r\n", off):
        return off + 2
    if off < len(text) and text[off] in "\r\n":
        return off + 1
    return off


def newline_of(text: str) -> str:
    """The line break the text uses."""
    i = text.find("\n")
    if i > 0 and text[i - 1] == "\r":
        return "\r\n"
    return "\n" if i >= 0 or "\r" not in text else "\r"
