"""Positions as LSP counts them: 0-based lines and UTF-16 code units."""

from __future__ import annotations

import re

from lsprotocol import types


def utf16_col(line: str, chars: int) -> int:
    """The UTF-16 column of the character column ``chars`` of ``line``."""
    head = line[:chars]
    return len(head) + sum(1 for c in head if ord(c) > 0xFFFF)


def char_col(line: str, units: int) -> int:
    """The character column of the UTF-16 column ``units`` of ``line``."""
    n = 0
    for i, c in enumerate(line):
        if n >= units:
            return i
        n += 2 if ord(c) > 0xFFFF else 1
    return len(line)


class Lines:
    """A text's lines, to turn offsets and (line, char) into LSP positions and back."""

    def __init__(self, text: str) -> None:
        self.text = text

        self.starts = [0] + [m.end() for m in re.finditer(r"\r\n|\r|\n", text)]

    def line(self, n: int) -> str:
        if n >= len(self.starts):
            return ""
        end = self.starts[n + 1] if n + 1 < len(self.starts) else len(self.text)
        return self.text[self.starts[n]:end].rstrip("\r\n")

    def position(self, offset: int) -> types.Position:
        lo, hi = 0, len(self.starts) - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if self.starts[mid] <= offset:
                lo = mid
            else:
                hi = mid - 1
        return types.Position(lo, utf16_col(self.line(lo), offset - self.starts[lo]))

    def offset(self, pos: types.Position) -> int:
        if pos.line >= len(self.starts):
            return len(self.text)
        return self.starts[pos.line] + char_col(self.line(pos.line), pos.character)

    def range(self, start: int, end: int) -> types.Range:
        return types.Range(self.position(start), self.position(end))

    def span_position(self, line: int, col: int) -> types.Position:
        """The LSP position of a diagnostic's 1-based line and character column."""
        return types.Position(max(line - 1, 0), utf16_col(self.line(line - 1), max(col - 1, 0)))
