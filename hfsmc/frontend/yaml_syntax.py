"""YAML syntax errors in words, at the line where the indentation or the quoting
went wrong, with ruamel.yaml's own text kept as a note (docs/quoting.md)."""

from __future__ import annotations

import re
from typing import Any

from ruamel.yaml.error import MarkedYAMLError

from hfsmc.errors import Diagnostic, Span
from hfsmc.frontend.yaml_traps import SNIPPET_KEYS, quoted

_SNIPPET_START = re.compile(
    r"(?:^\s*(?:-\s+)?|[{,]\s*)(?P<key>" + "|".join(sorted(SNIPPET_KEYS)) + r")\s*:\s+(?P<c>[!&*])")
_NO_SPACE = re.compile(r"^(?P<lead>\s*(?:-\s+)?)(?P<key>[A-Za-z_][A-Za-z0-9_]*):(?P<rest>[^\s:/\\'\"])")
COLON_IN_VALUE = ("`: ` inside a value that is not quoted: YAML reads it as a key and a value; "
                  "quote the whole value (docs/quoting.md)")
_KEY_AT = re.compile(r"(?P<key>[^\s#'\"{}\[\],:][^#:]*?)\s*:(?:\s|$)")
_PLAIN_VALUE = re.compile(r"^\s*(?:-\s+)?(?P<key>[^\s#'\"{}\[\],:-][^#:]*?)\s*:\s+(?P<v>[^\s#'\"|>{\[&*!].*)$")
_QUOTE_OPEN = re.compile(r"(?:^\s*(?:-\s+)?[^\s#'\"{\[][^#]*?:\s+|^\s*(?:-\s+)?)(?P<q>['\"])")


def explain(file: str, lines: list[str], e: MarkedYAMLError) -> Diagnostic | None:
    """A message about the real mistake behind a ruamel syntax error, or None.

    Cases: a tag/anchor/alias starting a snippet, a tab, a quote never closed,
    a missing space after `:`, a value's line indented too far (read as more
    of the value above), `: ` inside an unquoted value, a key indented to no
    level above it.
    """
    mark = e.problem_mark or e.context_mark
    if mark is None:
        return None
    problem = (e.problem or e.context or "").strip()
    ctx = (e.context or "").strip()
    raw = f"the YAML parser says: {problem}" + (f" ({ctx})" if ctx and ctx != problem else "")
    line, col = mark.line, mark.column  # 0-based
    cmark = e.context_mark
    first = min(line, cmark.line) if cmark is not None else line
    for ln in _content_lines_back(lines, line, first):
        found = _snippet_property(file, lines, ln, raw)
        if found is not None:
            return found
    if "'\\t'" in problem or "tab" in problem:
        return _tab(file, lines, line, col, raw)
    if problem.startswith("found character") and "cannot start any token" in problem:
        c = _at(lines, line, col)
        if _in_flow(lines, line, col):
            return _flow_char(file, line, col, c, "", raw)
        return Diagnostic("E002", f"`{c}` cannot start a value or a key in YAML: quote the whole "
                          "value (docs/quoting.md)", Span(file, line + 1, col + 1), "error", (raw,))
    indicator = _indicator_at_start(file, lines, problem, ctx, mark, cmark, raw)
    if indicator is not None:
        return indicator
    if ctx.startswith("while scanning a quoted scalar") and cmark is not None:
        q = _at(lines, cmark.line, cmark.column) or "quote"
        return Diagnostic("E002", f"this `{q}` is never closed: the quoted value runs on to the end "
                          "of the file", Span(file, cmark.line + 1, cmark.column + 1), "error",
                          (f"close it with a `{q}` on the same line", raw))
    open_quote = _open_quote_before(file, lines, line, raw)
    if open_quote is not None:
        return open_quote
    for ln in _content_lines_back(lines, line, first, extra=1):
        found = _missing_space(file, lines, ln, raw)
        if found is not None:
            return found
    if problem.startswith("mapping values are not allowed"):
        return _colon_in_value(file, lines, line, col, raw)
    if problem.startswith("expected ',' or ") and cmark is not None and cmark.line == line:
        closer = "}" if "'}'" in problem else "]"
        return _flow_char(file, line, col, _at(lines, line, col), f" that ends with `{closer}`", raw)
    if problem.startswith("expected <block end>") or problem.startswith("did not find expected") \
            or problem.startswith("expected '<document start>'"):
        return _after_quote(file, lines, line, col, raw) or _misaligned(file, lines, line, col, raw)
    return None


_INDICATORS = {"-": "a list entry", "?": "a complex mapping key", "|": "a literal block",
               ">": "a folded block"}


def _indicator_at_start(file: str, lines: list[str], problem: str, ctx: str, mark: Any,
                        cmark: Any, raw: str) -> Diagnostic | None:
    """`when: - x`, `when: ? x`, `when: > 3`: an indicator YAML reads before the code."""
    if problem in ("sequence entries are not allowed here", "mapping keys are not allowed here"):
        at = mark
    elif ctx.startswith("while scanning a block scalar") and cmark is not None:
        at = cmark
    else:
        return None
    c = _at(lines, at.line, at.column)
    if c not in _INDICATORS:
        return None
    return Diagnostic("E002", f"`{c}` at the start of a value begins {_INDICATORS[c]} in YAML, not "
                      "code: quote the whole value (docs/quoting.md)",
                      Span(file, at.line + 1, at.column + 1), "error", (raw,))


def _flow_char(file: str, line: int, col: int, c: str, ends: str, raw: str) -> Diagnostic:
    return Diagnostic("E002", f"YAML cannot read `{c}` here, inside a `{{...}}` or `[...]`{ends}: "
                      "quote code that holds `,` `[` `]` `{` `}` or `: `", Span(file, line + 1, col + 1),
                      "error", ("or write the mapping as a block, one key per line (docs/quoting.md)", raw))


def _in_flow(lines: list[str], line: int, col: int) -> bool:
    """Is ``col`` inside a `{...}` or `[...]` opened on its line (quotes ignored)?"""
    text = lines[line][:col] if 0 <= line < len(lines) else ""
    return text.count("{") + text.count("[") > text.count("}") + text.count("]")


def _at(lines: list[str], line: int, col: int) -> str:
    return lines[line][col] if 0 <= line < len(lines) and 0 <= col < len(lines[line]) else ""


def _is_content(text: str) -> bool:
    s = text.strip()
    return bool(s) and not s.startswith("#")


def _content_lines_back(lines: list[str], line: int, first: int, extra: int = 0) -> list[int]:
    """Line ``line`` and the content lines before it down to ``first``, plus ``extra`` more
    (at most four lines)."""
    out: list[int] = []
    ln = min(line, len(lines) - 1)
    while ln >= 0 and len(out) < 4:
        if _is_content(lines[ln]):
            if ln < first:
                if extra <= 0:
                    break
                extra -= 1
            out.append(ln)
        ln -= 1
    return out


def _snippet_property(file: str, lines: list[str], ln: int, raw: str) -> Diagnostic | None:
    m = _SNIPPET_START.search(lines[ln]) if 0 <= ln < len(lines) else None
    if m is None:
        return None
    c = m["c"]
    what = {"!": "a tag", "&": "an anchor", "*": "an alias"}[c]
    value = lines[ln][m.start("c"):].rstrip()
    flow = m.group(0).lstrip()[:1] in ("{", ",")
    hint = ("in a `{...}` mapping, put the value in quotes (docs/quoting.md)" if flow else
            f"write: {m['key']}: {quoted(value)}   (docs/quoting.md)")
    return Diagnostic("E105", f"YAML reads `{c}` at the start of a value as {what}, not as code: "
                      f"quote the whole `{m['key']}` value", Span(file, ln + 1, m.start("c") + 1),
                      "error", (hint, raw))


def _tab(file: str, lines: list[str], line: int, col: int, raw: str) -> Diagnostic:
    text = lines[line] if 0 <= line < len(lines) else ""
    tab = text.find("\t")
    leading = tab >= 0 and not text[:tab].strip()
    where = Span(file, line + 1, (tab if tab >= 0 else col) + 1)
    if leading:
        return Diagnostic("E002", "a tab in the indentation: YAML indents with spaces only",
                          where, "error", ("replace the tab with spaces (set your editor to "
                                           "insert spaces for YAML)", raw))
    return Diagnostic("E002", "a tab where YAML expects a value or a key: use spaces",
                      where, "error", (raw,))


def _open_quote_before(file: str, lines: list[str], line: int, raw: str) -> Diagnostic | None:
    """A quoted value a few lines up whose quote closes only at the error's line."""
    for ln in range(line - 1, max(-1, line - 6), -1):
        text = lines[ln] if ln < len(lines) else ""
        m = _QUOTE_OPEN.match(text)
        if m is None:
            continue
        q = m["q"]
        if _closes(text[m.end("q"):], q):
            return None  # the nearest quoted value is closed: not this mistake
        closing = next((k for k in range(ln + 1, min(line + 1, len(lines)))
                        if _closes(lines[k], q)), None)
        if closing is None or closing < line:
            return None
        return Diagnostic("E002", f"this `{q}` is not closed on its line: YAML reads on to the "
                          f"`{q}` on line {closing + 1}", Span(file, ln + 1, m.start("q") + 1),
                          "error", (f"close the value with a `{q}` on line {ln + 1}", raw))
    return None


def _closes(text: str, q: str) -> bool:
    """Does ``text`` (after an opening quote) contain the closing quote?"""
    i = 0
    while i < len(text):
        ch = text[i]
        if q == '"' and ch == "\\":
            i += 2
            continue
        if ch == q:
            if q == "'" and text[i + 1:i + 2] == "'":
                i += 2
                continue
            return True
        i += 1
    return False


def _missing_space(file: str, lines: list[str], ln: int, raw: str) -> Diagnostic | None:
    text = lines[ln] if 0 <= ln < len(lines) else ""
    m = _NO_SPACE.match(text)
    if m is None:
        return None
    word = text[m.start("key"):].split()[0]
    fixed = f"{m['key']}: {text[m.end('key') + 1:].strip()}"
    return Diagnostic("E002", f"no space after the `:` of `{m['key']}`: YAML reads `{word}` as one "
                      "word, not as a key and its value", Span(file, ln + 1, m.end("key") + 1),
                      "error", (f"write: {fixed}", raw))


def _indent(text: str) -> int:
    return len(text) - len(text.lstrip(" "))


def _key_start(text: str) -> int:
    """Column (0-based) of a line's first key or value, after any `- `."""
    i = _indent(text)
    while text[i:i + 2] in ("- ", "-\t"):
        i += 2
        while i < len(text) and text[i] == " ":
            i += 1
    return i


def _previous_content(lines: list[str], line: int) -> int | None:
    ln = line - 1
    while ln >= 0 and not _is_content(lines[ln]):
        ln -= 1
    return ln if ln >= 0 else None


def _colon_in_value(file: str, lines: list[str], line: int, col: int, raw: str) -> Diagnostic | None:
    if not 0 <= line < len(lines):
        return None
    text = lines[line]
    start = _key_start(text)
    km = _KEY_AT.match(text, start)
    if km is not None and km.end("key") <= col <= km.end():
        # `key:` starts this line: the line above's value swallowed it
        prev = _previous_content(lines, line)
        pm = _PLAIN_VALUE.match(lines[prev]) if prev is not None else None
        if pm is not None and prev is not None:
            above = pm.start("key")
            return Diagnostic(
                "E002", f"`{km['key']}` is indented more than `{pm['key']}` on line {prev + 1}, so "
                f"YAML reads it as more of the value of `{pm['key']}`", Span(file, line + 1, start + 1),
                "error", (f"start `{km['key']}` at column {above + 1}, under `{pm['key']}`", raw))
        return None
    vm = _PLAIN_VALUE.match(text)
    notes = [raw]
    if vm is not None and vm.start("v") <= col:
        value = vm["v"].rstrip()
        notes.insert(0, f"write: {vm['key']}: {quoted(value)}")
    return Diagnostic("E002", COLON_IN_VALUE, Span(file, line + 1, col + 1), "error", tuple(notes))


def quote_colon_value(lines: list[str], diag: Diagnostic) -> list[str] | None:
    """``lines`` with the value that ``diag`` (an unquoted `: `) names quoted, so that the
    parser can go on and find the next one; None when ``diag`` is another error."""
    line = diag.span.line - 1
    if diag.message != COLON_IN_VALUE or not 0 <= line < len(lines):
        return None
    vm = _PLAIN_VALUE.match(lines[line])
    if vm is None:
        return None
    return [*lines[:line], lines[line][:vm.start("v")] + quoted(vm["v"].rstrip()), *lines[line + 1:]]


_QUOTED_START = re.compile(r"^\s*(?:-\s+)?(?P<key>[^\s#'\"{}\[\],:-][^#:]*?)\s*:\s+(?P<v>(['\"]).*)$")


def _after_quote(file: str, lines: list[str], line: int, col: int, raw: str) -> Diagnostic | None:
    """`when: 'x' in names`: a value that starts with a quote ends at the closing quote."""
    m = _QUOTED_START.match(lines[line]) if 0 <= line < len(lines) else None
    if m is None or col <= m.start("v"):
        return None
    value = m["v"].rstrip()
    return Diagnostic("E002", f"the value of `{m['key']}` starts with a quote, so YAML ends it at the "
                      "closing quote and cannot read the rest: quote the whole value",
                      Span(file, line + 1, m.start("v") + 1), "error",
                      (f"write: {m['key']}: {quoted(value)}   (docs/quoting.md)", raw))


_BLOCK_START = re.compile(r"^(?P<head>\s*(?:-\s+)?(?:[^#'\"\s][^#]*?:\s+)?)[|>][-+0-9]*\s*(?:#.*)?$")


def _misaligned(file: str, lines: list[str], line: int, col: int, raw: str) -> Diagnostic | None:
    if not 0 <= line < len(lines):
        return None
    text = lines[line]
    start = _key_start(text)
    if col != start and col != _indent(text):
        return None  # not about where the line starts
    here = _indent(text)
    blocks = _block_lines(lines, line)
    if line in blocks:  # a line of a `|` block indented less than the block's first line
        head, first = blocks[line]
        key = _first_word(lines[head][_key_start(lines[head]):])
        col0 = _indent(lines[first]) + 1
        return Diagnostic(
            "E002", f"this line is indented less than the first line of the `{key}` block "
            f"(line {first + 1}, column {col0}), so the block ends above it", Span(file, line + 1, here + 1),
            "error", (f"indent every line of the block to column {col0} at least; if this line is a "
                      "key, line it up with the keys above", raw))
    levels = [lv for lv in _levels_above(lines, line) if lv[1] not in blocks]
    same = next((lv for lv in levels if lv[0] == here), None)
    if same is not None:
        item = lines[same[1]]
        if same[2] != "-" or text[here:here + 1] == "-" \
                or any(lv[0] == here and lv[2] != "-" for lv in levels):  # `key:` then `- ` at its column
            return None
        under = _key_start(item)
        return Diagnostic(
            "E002", f"`{_first_word(text[start:])}` lines up with the `-` of the list item on line "
            f"{same[1] + 1}: a key of that item starts at column {under + 1}, a new item with `- `",
            Span(file, line + 1, here + 1), "error", (raw,))
    if here == 0 and levels and levels[-1][0] > 0:  # the document's first key is indented
        c, n, w = levels[-1]
        return Diagnostic("E002", f"`{w}` is indented, so the keys after it at column 1 cannot "
                          "belong to the same mapping: top-level keys start at column 1",
                          Span(file, n + 1, c + 1), "error", (raw,))
    near = [lv for lv in levels if lv[0] > here][-1:] + [lv for lv in levels if lv[0] < here][:1]
    what = "this list item" if text[here:here + 1] == "-" else f"`{_first_word(text[start:])}`"
    shown = ", ".join(f"column {c + 1} (`{w}`, line {n + 1})" for c, n, w in near)
    notes = (f"the keys and items above start at {shown}: line it up with one of them",) if near else ()
    return Diagnostic("E002", f"{what} at column {here + 1} lines up with no key or list item "
                      "above it: its indentation is wrong", Span(file, line + 1, here + 1), "error",
                      (*notes, raw))


def _block_lines(lines: list[str], upto: int) -> dict[int, tuple[int, int]]:
    """Lines (up to ``upto``) inside `|`/`>` blocks, loosely: indented more than the
    block's key.  Each maps to (the key's line, the block's first content line)."""
    out: dict[int, tuple[int, int]] = {}
    head: int | None = None
    first: int | None = None
    for ln in range(min(upto + 1, len(lines))):
        text = lines[ln]
        if head is not None:
            if not text.strip():
                continue
            if _indent(text) > _indent(lines[head]):
                first = ln if first is None else first
                out[ln] = (head, first)
                continue
            head = first = None
        if _BLOCK_START.match(text) and "{" not in text and "[" not in text:
            head = ln
    return out


def _first_word(text: str) -> str:
    m = re.match(r"-|[^\s:]+", text)
    return m.group(0) if m else text.strip()[:20]


def _levels_above(lines: list[str], line: int) -> list[tuple[int, int, str]]:
    """(indentation, line, first word) of the blocks that enclose ``line``, innermost first."""
    out: list[tuple[int, int, str]] = []
    limit: int | None = None
    for ln in range(line - 1, -1, -1):
        text = lines[ln]
        if not _is_content(text):
            continue
        i = _indent(text)
        if limit is None or i < limit:
            out.append((i, ln, _first_word(text[i:])))
            limit = i
            if i == 0:
                break
    return out

