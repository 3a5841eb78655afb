"""Model text (names, descriptions, file names) inside comments of generated code."""

from __future__ import annotations

import re

# Characters that end a comment line or that a compiler refuses in source text:
# ASCII controls (NUL, CR, LF, ...), DEL, and Unicode's line separators.
_BREAKING = re.compile("[\x00-\x08\x0a-\x1f\x7f\x85\u2028\u2029]")


def comment_text(text: str) -> str:
    """``text`` safe inside a one-line comment of Python or C++: line breaks and control
    characters written as escapes, and no backslash at the end (in C++ it would splice
    the next line of code into the comment)."""
    out = _BREAKING.sub(lambda m: f"\\x{ord(m.group(0)):02x}" if ord(m.group(0)) < 0x100
                        else f"\\u{ord(m.group(0)):04x}", text)
    return out.rstrip().rstrip("\\").rstrip()
