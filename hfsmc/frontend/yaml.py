"""YAML front end: libyaml's C parser where it reads the document as ruamel.yaml
would (:mod:`hfsmc.frontend.yaml_c`), ruamel.yaml's round-trip loader, which keeps
positions, for everything else."""

from __future__ import annotations

import warnings
from typing import Any, Literal, NoReturn

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import MarkedYAMLError, ReusedAnchorWarning, YAMLError
from ruamel.yaml.scalarstring import (
    DoubleQuotedScalarString,
    FoldedScalarString,
    LiteralScalarString,
    SingleQuotedScalarString,
)

from hfsmc.errors import Diagnostic, Diagnostics, ParseError, Span, fail
from hfsmc.frontend.source import MAX_DEPTH, MAX_NODES, Document, PathKey, split_lines
from hfsmc.frontend.yaml_c import load_c
from hfsmc.frontend.yaml_syntax import COLON_IN_VALUE, explain, quote_colon_value
from hfsmc.frontend.yaml_traps import PropertyScan, WatchedParser, may_have_properties
from hfsmc.frontend.yaml_values import record_value, scalar

Parser = Literal["auto", "libyaml", "ruamel"]


# How many unquoted `: ` one run reports (each costs a parse of the document).
MAX_COLONS = 50


def _yaml() -> YAML:
    y = YAML(typ="rt")
    y.preserve_quotes = True  # so that a quoted scalar's content column is known
    y.allow_duplicate_keys = False
    return y


def load_yaml(file: str, text: str, diags: Diagnostics) -> Document:
    """Parse ``text`` and return its neutral :class:`Document`.

    Raises :class:`ParseError` for malformed YAML (position of the problem).
    Non-fatal oddities (non-string keys) go to ``diags``.
    """
    return load_yaml_with(file, text, diags)[0]


def load_yaml_with(file: str, text: str, diags: Diagnostics,
                   parser: Parser = "auto") -> tuple[Document, str]:
    """:func:`load_yaml`, saying which parser read the document ("libyaml" or
    "ruamel: " and why libyaml did not).  ``parser`` forces one: "libyaml" raises
    RuntimeError where the C path would hand the document to ruamel.yaml."""
    lines = split_lines(text)
    doc = Document(file, "yaml", lines)
    if parser != "ruamel":
        why = load_c(doc, text)
        if why is None:
            return doc, "libyaml"
        if parser == "libyaml":
            raise RuntimeError(f"libyaml cannot take this document: {why}")
    else:
        why = "asked for"
    return _load_ruamel(doc, text, diags), f"ruamel: {why}"


def _load_ruamel(doc: Document, text: str, diags: Diagnostics) -> Document:
    file, lines = doc.file, doc.lines
    y = _yaml()
    scan: PropertyScan | None = None
    if may_have_properties(text):
        # tags, anchors and aliases that would eat a snippet's `!`, `&&` or `*`,
        # seen in the parser's events as the document loads (docs/quoting.md)
        scan = PropertyScan(file, lines)
        y.Parser = WatchedParser
        y.parser.watch = scan.feed
    try:
        with warnings.catch_warnings():
            # A redefined anchor is valid YAML (the latest definition wins): ruamel's
            # warning about it would reach the user with positions in `<unicode string>`.
            warnings.simplefilter("ignore", ReusedAnchorWarning)
            root = y.load(text)
    except MarkedYAMLError as e:
        _fail_marked(file, lines, e, scan.found() if scan else [])
    except YAMLError as e:  # reader errors (bad characters) and the like
        pos = getattr(e, "position", None)
        span = _offset_span(file, text, pos) if isinstance(pos, int) else Span(file, 1, 1)
        fail(ParseError, "E002", _first_line(str(e)), span)
    except RecursionError:
        fail(ParseError, "E006", f"the document nests deeper than {MAX_DEPTH} levels", Span(file, 1, 1))
    except Exception as e:  # an explicit tag whose value cannot be built (`!!int abc`)
        if scan is not None and scan.found():
            raise ParseError(scan.found()) from None
        fail(ParseError, "E002", f"a tagged value cannot be read: {_first_line(str(e)) or type(e).__name__}",
             _failing_node(file, text))
    if scan is not None and scan.found():
        raise ParseError(scan.found())
    doc.spans[()] = Span(file, 1, 1)
    if "&" in text:  # anchors exist: bound the expansion of their aliases first
        _check_expansion(file, root)
    doc.data = _Walker(doc, diags).walk(root)
    return doc


def _check_expansion(file: str, root: Any) -> None:
    """Refuse alias bombs and recursive aliases before anything expands them.

    Counts the values the document would have with every alias expanded, in
    one pass over the distinct nodes (sizes memoised by identity).
    """
    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        if not isinstance(node, (CommentedMap, CommentedSeq)):
            continue
        key = id(node)
        children = list(node.values()) if isinstance(node, CommentedMap) else list(node)
        if done:
            on_path.discard(key)
            size[key] = 1 + sum(size.get(id(c), 1) for c in children)
            if size[key] > MAX_NODES:
                fail(ParseError, "E006", f"aliases expand the document to more than {MAX_NODES} "
                     "values", Span(file, 1, 1))
            continue
        if key in on_path:
            fail(ParseError, "E006", "an alias refers to a mapping or list that contains it",
                 Span(file, 1, 1))
        if key in size:
            continue
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children)


def _fail_marked(file: str, lines: list[str], e: MarkedYAMLError, found: list[Diagnostic]) -> NoReturn:
    """Raise the syntax error, explained where hfsmc knows the mistake, after the
    tags and anchors found before it (the same spot is said once)."""
    diag = _marked_diagnostic(file, lines, e)
    diags = [diag, *_more_colons(file, lines, diag)]
    raise ParseError([*found, *(d for d in diags if all(f.span != d.span for f in found))])


def _more_colons(file: str, lines: list[str], diag: Diagnostic) -> list[Diagnostic]:
    """After an unquoted `: `, the others below it: the value is quoted and the document
    parsed again, until it parses or stops on another error (which may come from the
    first, so it is not said)."""
    more: list[Diagnostic] = []
    for _ in range(MAX_COLONS):
        fixed = quote_colon_value(lines, diag)
        if fixed is None:
            break
        lines = fixed
        try:
            _yaml().load("\n".join(lines))
            break
        except MarkedYAMLError as e:
            diag = _marked_diagnostic(file, lines, e)
        except Exception:
            break
        if diag.message != COLON_IN_VALUE:
            break
        more.append(diag)
    return more


def _marked_diagnostic(file: str, lines: list[str], e: MarkedYAMLError) -> Diagnostic:
    mark = e.problem_mark or e.context_mark
    span = Span(file, mark.line + 1, mark.column + 1) if mark else Span(file, 1, 1)
    code = "E003" if type(e).__name__ == "DuplicateKeyError" else "E002"
    if code == "E002" and type(e).__name__ in ("ScannerError", "ParserError"):
        explained = explain(file, lines, e)
        if explained is not None:
            return explained
    problem = (e.problem or e.context or "malformed YAML").strip()
    notes: tuple[str, ...] = ()
    if code == "E003":
        problem = _duplicate_message(e)
    ctx, cmark = (e.context or ""), e.context_mark
    if ctx.startswith("while parsing a flow") and cmark is not None and mark is not None \
            and mark.line > cmark.line and mark.column <= cmark.column:
        # The parser notices only at the next token; the unclosed bracket is the mistake.
        opener = "{" if "mapping" in ctx else "["
        notes = (f"the parser stopped at line {mark.line + 1}: {problem}",)
        problem = f"this `{opener}` is never closed"
        span = Span(file, cmark.line + 1, cmark.column + 1)
    return Diagnostic(code, problem, span, "error", notes)


def _failing_node(file: str, text: str) -> Span:
    """Position of the innermost node whose value cannot be constructed."""
    y = _yaml()
    try:
        root = y.compose(text)
    except Exception:
        return Span(file, 1, 1)
    order: list[Any] = []
    stack = [root] if root is not None else []
    while stack:  # pre-order, reversed below: children before parents
        node = stack.pop()
        order.append(node)
        value = getattr(node, "value", None)
        if isinstance(value, list):
            for item in value:
                stack.extend(item if isinstance(item, tuple) else (item,))
    for node in reversed(order):
        try:
            y.constructor.construct_object(node, deep=True)
        except Exception:
            return Span(file, node.start_mark.line + 1, node.start_mark.column + 1)
    return Span(file, 1, 1)


def _duplicate_message(e: MarkedYAMLError) -> str:
    problem = (e.problem or "").strip()
    # ruamel says: 'found duplicate key "X" with value "..." (original value: "...")'
    if problem.startswith("found duplicate key"):
        head = problem.split(" with value", 1)[0]
        return head.replace("found duplicate key", "duplicate key") + " in this mapping"
    return problem or "duplicate key"


def _first_line(s: str) -> str:
    return s.strip().splitlines()[0] if s.strip() else "malformed YAML"


def _offset_span(file: str, text: str, offset: int) -> Span:
    before = text[:offset]
    line = before.count("\n") + 1
    col = offset - (before.rfind("\n") + 1) + 1
    return Span(file, line, col)


class _Walker:
    """Copies ruamel's tree into plain data and records every position.

    Iterative, so deep documents do not hit Python's recursion limit, and
    bounded, so alias bombs cannot blow up memory.
    """

    def __init__(self, doc: Document, diags: Diagnostics) -> None:
        self.doc = doc
        self.diags = diags
        self.nodes = 0

    def _span(self, line: int, col: int) -> Span:
        return Span(self.doc.file, line + 1, col + 1)

    def walk(self, root: Any) -> Any:
        out: list[Any] = [None]
        # stack of (source node, setter, path, depth)
        stack: list[tuple[Any, Any, PathKey, int]] = [(root, (out, 0), (), 0)]
        while stack:
            node, (holder, slot), path, depth = stack.pop()
            self.nodes += 1
            if self.nodes > MAX_NODES:
                fail(ParseError, "E006", f"the document expands to more than {MAX_NODES} values "
                     "(aliases?)", Span(self.doc.file, 1, 1))
            if depth > MAX_DEPTH:
                fail(ParseError, "E006", f"the document nests deeper than {MAX_DEPTH} levels",
                     self.doc.span(path))
            if isinstance(node, CommentedMap):
                m: dict[str, Any] = {}
                holder[slot] = m
                here = self.doc.span(path)
                # Keys brought in by `<<:` take their position in the merged mapping
                # (a mapping made only of merged keys has no position table of its own).
                positions = {}
                for merged in reversed(list(getattr(node, "merge", None) or ())):
                    if isinstance(merged, CommentedMap) and merged.lc.data:
                        positions.update(merged.lc.data)
                positions.update(node.lc.data or {})
                for k in node:
                    # keys brought in by a `<<:` merge have no position of their own
                    kl, kc = positions.get(k, (here.line - 1, here.col - 1))[:2]
                    key = k
                    if not isinstance(k, str):
                        key = str(k)
                        self.diags.error("E101", f"mapping keys must be strings, not `{k!r}`",
                                         self._span(kl, kc))
                    kp = (*path, key)
                    self.doc.key_spans[kp] = self._span(kl, kc)
                    pos = positions.get(k)
                    vl, vc = (pos[2], pos[3]) if pos else (kl, kc)
                    self._record_value(kp, node[k], vl, vc)
                    m[key] = None
                    stack.append((node[k], (m, key), kp, depth + 1))
            elif isinstance(node, CommentedSeq):
                seq: list[Any] = [None] * len(node)
                holder[slot] = seq
                for i, item in enumerate(node):
                    il, ic = node.lc.item(i)
                    ip = (*path, i)
                    self._record_value(ip, item, il, ic)
                    stack.append((item, (seq, i), ip, depth + 1))
            else:
                holder[slot] = scalar(node)
        return out[0]

    def _record_value(self, path: PathKey, value: Any, line: int, col: int) -> None:
        record_value(self.doc, path, value, _style(value), line, col)


def _style(value: Any) -> str | None:
    """The style a preserved-quotes scalar was written in (None: plain)."""
    if isinstance(value, LiteralScalarString):
        return "|"
    if isinstance(value, FoldedScalarString):
        return ">"
    if isinstance(value, DoubleQuotedScalarString):
        return '"'
    if isinstance(value, SingleQuotedScalarString):
        return "'"
    return None
