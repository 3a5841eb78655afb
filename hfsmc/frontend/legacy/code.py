"""Code of legacy files: text that knows where each character came from, and the rewrites.

A :class:`Mapped` text carries, for every character, its line and column in the
legacy file.  Every rewrite the import makes (dedenting, dropping
``self.globalNamespace.`` prefixes, renaming, wrapping a condition in a helper
function, adding a ``global`` line) is an edit of a Mapped text, so the result
still knows, character by character, where it came from.  Its
:meth:`Mapped.segments` are what :class:`hfsmc.ir.Code` needs to put a
diagnostic, or a traceback of the running component, at the right line:col of
the legacy file.  Inserted text (a ``def`` line, a ``global``) is placed at the
legacy text it stands for.

Code is never parsed beyond need: references are found in the text with
strings and comments blanked out, so that code which does not even compile is
still carried over (its syntax error is then reported at its legacy position).
"""

from __future__ import annotations

import ast
import builtins
import io
import keyword
import re
import tokenize
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

Pos = tuple[int, int]  # (line, col), 1-based
Language = Literal["python", "cpp"]


@dataclass(frozen=True, slots=True)
class Mapped:
    """Text with the legacy position of each character, and one more for its end."""

    text: str
    pos: tuple[Pos, ...]

    @classmethod
    def synth(cls, text: str, at: Pos) -> Mapped:
        """Text the import writes, placed at ``at`` (columns run on from there)."""
        line, col = at
        return cls(text, tuple((line, col + i) for i in range(len(text) + 1)))

    def __len__(self) -> int:
        return len(self.text)

    @property
    def start(self) -> Pos:
        return self.pos[0]

    def at(self, i: int) -> Pos:
        return self.pos[max(0, min(i, len(self.text)))]

    def cut(self, a: int, b: int) -> Mapped:
        return Mapped(self.text[a:b], self.pos[a:b + 1])

    def strip(self) -> Mapped:
        a = len(self.text) - len(self.text.lstrip())
        b = len(self.text.rstrip())
        return self.cut(a, max(a, b))

    def segments(self) -> tuple[tuple[int, int, int], ...]:
        """(offset, line, col) wherever the mapping does not run on from the previous character."""
        out: list[tuple[int, int, int]] = []
        prev: Pos | None = None
        for i, (line, col) in enumerate(self.pos):
            if prev is None or line != prev[0] or col != prev[1] + 1:
                out.append((i, line, col))
            prev = (line, col)
        return tuple(out)


def join(parts: Iterable[Mapped], at: Pos) -> Mapped:
    """The parts one after the other (an empty text at ``at`` when there are none)."""
    texts: list[str] = []
    pos: list[Pos] = []
    end: Pos = at
    for p in parts:
        texts.append(p.text)
        pos.extend(p.pos[:-1])
        end = p.pos[-1]
    pos.append(end)
    return Mapped("".join(texts), tuple(pos))


Edit = tuple[int, int, Mapped]  # replace [start, end) with the text


def edit(m: Mapped, edits: Iterable[Edit]) -> Mapped:
    """``m`` with non-overlapping edits applied (later ones that overlap are dropped)."""
    parts: list[Mapped] = []
    i = 0
    for a, b, new in sorted(edits, key=lambda e: (e[0], e[1])):
        if a < i:
            continue
        parts.append(m.cut(i, a))
        parts.append(new)
        i = b
    parts.append(m.cut(i, len(m.text)))
    return join(parts, m.start)


def _lines(text: str) -> list[tuple[int, int]]:
    """(start, end) offsets of each line, without its line break."""
    out: list[tuple[int, int]] = []
    i = 0
    for line in text.split("\n"):
        out.append((i, i + len(line)))
        i += len(line) + 1
    return out


def block(m: Mapped) -> Mapped:
    """Code as written inside an element: blank lines around it and trailing blanks
    dropped, common indentation removed (as :func:`textwrap.dedent` does)."""
    lines = _lines(m.text)
    full = [k for k, (a, b) in enumerate(lines) if m.text[a:b].strip()]
    if not full:
        return m.cut(0, 0)
    first, last = full[0], full[-1]
    indents = [_indent(m.text[lines[k][0]:lines[k][1]]) for k in full]
    margin = indents[0]
    for ind in indents[1:]:
        while not ind.startswith(margin):
            margin = margin[:-1]
    edits: list[Edit] = [(0, lines[first][0] + len(margin), Mapped.synth("", m.at(0)))]
    for k in range(first + 1, last + 1):
        a, b = lines[k]
        cut = len(margin) if k in full else b - a
        if cut:
            edits.append((a, a + cut, Mapped.synth("", m.at(a))))
    end = lines[last][0] + len(m.text[lines[last][0]:lines[last][1]].rstrip())
    edits.append((end, len(m.text), Mapped.synth("", m.at(end))))
    return edit(m, edits)


def _indent(line: str) -> str:
    return line[:len(line) - len(line.lstrip(" \t"))]


def indent_lines(m: Mapped, prefix: str, language: Language) -> Mapped:
    """Every line indented by ``prefix``, except lines that continue a Python string."""
    keep = python_string_rows(m.text) if language == "python" else set()
    edits: list[Edit] = []
    for k, (a, b) in enumerate(_lines(m.text)):
        if k not in keep and m.text[a:b].strip():
            edits.append((a, a, Mapped.synth(prefix, m.at(a))))
    return edit(m, edits)


def python_string_rows(text: str) -> set[int]:
    """0-based rows that continue a multi-line string: indenting them would change it."""
    out: set[int] = set()
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text + "\n").readline):
            if tok.start[0] != tok.end[0] and tok.type not in (tokenize.NEWLINE, tokenize.NL):
                out.update(range(tok.start[0], tok.end[0]))
    except (tokenize.TokenError, SyntaxError, IndentationError):
        pass
    return out


# ---------------------------------------------------------------------------
# strings and comments blanked out


# Strings (one-line, or triple-quoted; an unterminated one runs to its end) and comments.
_ONE_LINE = [r"'(?:\\.|[^\\'\n])*'?", r'"(?:\\.|[^\\"\n])*"?']
_TRIPLE = [r"'{3}(?:\\.|[^\\])*?(?:'{3}|\Z)", r'"{3}(?:\\.|[^\\])*?(?:"{3}|\Z)']
_PY_HIDDEN = re.compile("|".join([r"#[^\n]*", *_TRIPLE, *_ONE_LINE]), re.S)
_CPP_HIDDEN = re.compile("|".join([r"//[^\n]*", r"/\*.*?(?:\*/|\Z)", *_ONE_LINE]), re.S)
_NOT_BREAK = re.compile(r"[^\n]")


def mask(text: str, language: Language) -> str:
    """``text`` with strings and comments turned into spaces (line breaks kept)."""
    hidden = _PY_HIDDEN if language == "python" else _CPP_HIDDEN
    return hidden.sub(lambda m: _NOT_BREAK.sub(" ", m.group()), text)


# ---------------------------------------------------------------------------
# references to legacy namespaces

# How legacy code names the members of its namespaces, and which namespace each means.
PY_SCOPES = {"globalNamespace": "global", "interfaces": "global", "rosNode": "global",
             "namespace": "local", "localNamespace": "local"}
CPP_SCOPES = {"globalNamespace": "global", "interfaces": "global", "rosNode": "global",
              "stateNamespace": "local", "localNamespace": "local", "namespace": "local",
              "node": "global"}
# A prefix a user's own C++ may spell too (`node->next`): dropped only before a member.
WEAK_PREFIXES = frozenset({"node"})

_PY_SELF = re.compile(r"(?<![\w.])self[ \t]*\.[ \t]*((?!\d)\w+)")
_PY_MEMBER = re.compile(r"[ \t]*\.[ \t]*((?!\d)\w+)")
_CPP_REF = re.compile(r"(?<![\w.>:])(" + "|".join(CPP_SCOPES) + r")[ \t]*->[ \t]*((?!\d)\w+)")
_STORE = re.compile(r"[ \t]*(?:(=)(?!=)|(?:\*\*|//|>>|<<|[-+*/%&|^@])=)")
_IDENT = re.compile(r"(?<![\w.])(?<!->)(?<!::)((?!\d)\w+)")


@dataclass(frozen=True, slots=True)
class Ref:
    """``self.globalNamespace.x`` (scope "global"), ``self.namespace.x`` ("local"),
    ``self.x`` ("self"), or a bare name (C++, "bare")."""

    start: int
    end: int
    name: str
    scope: str
    store: bool  # assigned (``=`` or an augmented assignment such as ``+=``)
    plain: bool = False  # assigned with a plain ``=``: it may bring a new name to life


def references(text: str, language: Language, bare: frozenset[str] = frozenset()) -> list[Ref]:
    """Every reference to a legacy namespace member in ``text``, in order.

    ``bare`` names the members a C++ text may use without a prefix (its own
    namespace's), which renaming must reach too.
    """
    masked = mask(text, language)
    out: list[Ref] = []
    if language == "python":
        for m in _PY_SELF.finditer(masked):
            name, scope, end = m.group(1), "self", m.end()
            if name in PY_SCOPES:
                member = _PY_MEMBER.match(masked, end)
                if member is None:
                    continue  # the namespace object itself: nothing to map it to
                name, scope, end = member.group(1), PY_SCOPES[m.group(1)], member.end()
            store = _STORE.match(masked, end)
            out.append(Ref(m.start(), end, name, scope, store is not None,
                           store is not None and store.group(1) is not None))
        return out
    taken: list[tuple[int, int]] = []
    for m in _CPP_REF.finditer(masked):
        out.append(Ref(m.start(), m.end(), m.group(2), CPP_SCOPES[m.group(1)],
                       _STORE.match(masked, m.end()) is not None))
        taken.append((m.start(), m.end()))
    if bare:
        for m in _IDENT.finditer(masked):
            if m.group(1) in bare and not any(a <= m.start() < b for a, b in taken):
                out.append(Ref(m.start(), m.end(), m.group(1), "bare",
                               _STORE.match(masked, m.end()) is not None))
    return sorted(out, key=lambda r: r.start)


def rename(m: Mapped, refs: Iterable[tuple[Ref, str]]) -> Mapped:
    """Each reference replaced by its new name; a kept name keeps its own positions."""
    edits: list[Edit] = []
    for ref, new in refs:
        written = m.text[ref.start:ref.end]
        tail = len(written) - len(ref.name)
        if written.endswith(ref.name) and new == ref.name:
            edits.append((ref.start, ref.end, m.cut(ref.start + tail, ref.end)))
        else:
            edits.append((ref.start, ref.end, Mapped.synth(new, m.at(ref.start + tail))))
    return edit(m, edits)


# ---------------------------------------------------------------------------
# Python specifics

PY_RESERVED = frozenset(keyword.kwlist) | frozenset(dir(builtins)) | {"self"}
_PY_DEF = re.compile(r"^def[ \t]+((?!\d)\w+)[ \t]*\(", re.M)
_PY_SELF_PARAM = re.compile(r"[ \t]*self[ \t]*(?:,[ \t]*|(?=\)))")
_PY_TOP_ASSIGN = re.compile(r"^((?!\d)\w+)[ \t]*=(?!=)", re.M)


def python_defs(text: str) -> list[tuple[str, int, str]]:
    """Top-level functions ("function") and assigned names ("init"), with their offsets."""
    masked = mask(text, "python")
    found = [(m.group(1), m.start(1), "function") for m in _PY_DEF.finditer(masked)]
    found += [(m.group(1), m.start(1), "init") for m in _PY_TOP_ASSIGN.finditer(masked)]
    return sorted(found, key=lambda f: f[1])


def drop_self_params(m: Mapped) -> Mapped:
    """``def f(self, a):`` → ``def f(a):`` for every top-level function."""
    masked = mask(m.text, "python")
    edits: list[Edit] = []
    for d in _PY_DEF.finditer(masked):
        s = _PY_SELF_PARAM.match(masked, d.end())
        if s is not None and s.end() > s.start():
            edits.append((s.start(), s.end(), Mapped.synth("", m.at(s.start()))))
    return edit(m, edits)


def add_globals(m: Mapped, stores: dict[int, str]) -> Mapped:
    """A ``global`` line in each top-level function that assigns one of ``stores``
    (offset in ``m`` → name), after its docstring.  Code that does not parse is
    left as it is: its syntax error is what the user will be shown."""
    try:
        tree = ast.parse(m.text)
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        return m
    lines = _lines(m.text)
    edits: list[Edit] = []
    for node in tree.body:
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        first, last = lines[node.lineno - 1][0], lines[(node.end_lineno or node.lineno) - 1][1]
        names = sorted({n for off, n in stores.items() if first <= off <= last})
        body = node.body
        doc = isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str)
        stmt = body[1] if doc and len(body) > 1 else body[0]
        if not names or (stmt is body[0] and doc):
            continue
        line_start = lines[stmt.lineno - 1][0]
        line = m.text[line_start:lines[stmt.lineno - 1][1]]
        col = len(line.encode("utf-8")[:stmt.col_offset].decode("utf-8", "replace"))
        offset = line_start + col
        decl = f"global {', '.join(names)}"
        if line[:col].strip():  # the statement shares its line with the `def ...:`
            edits.append((offset, offset, Mapped.synth(f"{decl}; ", m.at(offset))))
        else:
            edits.append((line_start, line_start,
                          Mapped.synth(f"{line[:col]}{decl}\n", m.at(offset))))
    return edit(m, edits)


def literal(node: ast.expr) -> tuple[bool, object]:
    """The value of a literal a model variable can hold (bool, int, float, str, list, dict)."""
    try:
        value = ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return False, None
    return _plain(value), value


def _plain(value: object, depth: int = 0) -> bool:
    if depth > 50:
        return False
    if isinstance(value, bool | str):
        return True
    if isinstance(value, int):
        return -(2**63) <= value < 2**63
    if isinstance(value, float):
        return value == value and value not in (float("inf"), float("-inf"))
    if isinstance(value, list):
        return all(_plain(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v, depth + 1) for k, v in value.items())
    return False


def parses(text: str, mode: Literal["exec", "eval"] = "exec") -> bool:
    try:
        ast.parse(text, mode=mode)
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        return False
    return True


def as_function_body(text: str) -> str:
    return "def _f():\n" + "\n".join("    " + line for line in text.split("\n")) + "\n    pass\n"


_RETURN = re.compile(r"return\b")


def single_return(m: Mapped, language: Language) -> Mapped | None:
    """The expression of a body that is only ``return EXPR`` (``return EXPR;`` in C++)."""
    masked = mask(m.text, language)
    lead = len(masked) - len(masked.lstrip())
    r = _RETURN.match(masked, lead)
    if r is None:
        return None
    if language == "python":
        expr = m.cut(r.end(), len(m.text)).strip()
        return expr if expr.text and parses(expr.text, "eval") else None
    body = masked[r.end():].rstrip()
    if not body.endswith(";") or ";" in body[:-1] or "{" in body:
        return None
    end = len(masked[:r.end()]) + len(body) - 1
    expr = m.cut(r.end(), end).strip()
    return expr if expr.text else None


def cpp_is_expression(m: Mapped) -> bool:
    masked = mask(m.text, "cpp")
    return bool(masked.strip()) and ";" not in masked and "{" not in masked \
        and _RETURN.search(masked) is None


# ---------------------------------------------------------------------------
# C++ specifics

_CPP_DECL = re.compile(
    r"^\s*(?P<type>(?:const\s+|unsigned\s+|signed\s+|long\s+|short\s+|static\s+)*"
    r"[A-Za-z_][\w:]*(?:\s*<[^;{}]*>)?[\s*&]*?)\s*(?<![\w:])(?P<name>[A-Za-z_]\w*)\s*"
    r"(?:=\s*(?P<init>[^;]+?)|\{(?P<brace>[^;]*)\}|\((?P<paren>[^;]*)\))?\s*$", re.S)
_CPP_FUNC = re.compile(r"([A-Za-z_]\w*)\s*\([^;{}]*\)\s*(?:const\s*)?(?:noexcept\s*)?\{")
_NOT_TYPES = frozenset({"return", "if", "while", "for", "switch", "else", "do", "case", "goto",
                        "delete", "throw", "new", "using", "typedef", "namespace", "template",
                        "class", "struct", "enum", "union"})


@dataclass(frozen=True, slots=True)
class CppDecl:
    type: str
    name: str
    name_at: int  # offset of the name in the statement's text
    init: str | None


def cpp_statements(text: str) -> list[tuple[int, int]]:
    """(start, end) of each top-level statement ending in `;` (end includes the `;`)."""
    masked = mask(text, "cpp")
    out: list[tuple[int, int]] = []
    depth, start = 0, 0
    for i, ch in enumerate(masked):
        if ch in "({[":
            depth += 1
        elif ch in ")}]":
            depth = max(0, depth - 1)
            if depth == 0 and ch == "}":
                start = i + 1
        elif ch == ";" and depth == 0:
            if masked[start:i].strip():
                out.append((start, i + 1))
            start = i + 1
        elif ch == "\n" and depth == 0 and masked[start:i].lstrip().startswith("#"):
            start = i + 1  # a preprocessor line is not a declaration
    return out


def cpp_declaration(stmt: str) -> CppDecl | None:
    """``float x = 0.4;``, ``bool b;``, ``int n{3};`` as (type, name, init)."""
    body = mask(stmt, "cpp").rstrip().removesuffix(";")
    m = _CPP_DECL.match(body)
    if m is None or not m.group("type").strip() or m.group("type").split()[0] in _NOT_TYPES:
        return None
    typ = " ".join(stmt[m.start("type"):m.end("type")].split())
    init_group = next((g for g in ("init", "brace", "paren") if m.group(g) is not None), None)
    init = stmt[m.start(init_group):m.end(init_group)].strip() if init_group else None
    return CppDecl(typ, m.group("name"), m.start("name"), init)


def cpp_members(text: str) -> list[tuple[str, int, str]]:
    """Top-level functions ("function") and declared variables ("init") of C++ code, with
    their offsets."""
    masked = mask(text, "cpp")
    out: list[tuple[str, int, str]] = []
    depth = 0
    i = 0
    while i < len(masked):
        ch = masked[i]
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth = max(0, depth - 1)
        elif depth == 0 and (ch.isalpha() or ch == "_") and (i == 0 or not (
                masked[i - 1].isalnum() or masked[i - 1] == "_")):
            f = _CPP_FUNC.match(masked, i)
            if f is not None and f.group(1) not in _NOT_TYPES:
                out.append((f.group(1), i, "function"))
                i = f.end() - 1
                continue
        i += 1
    for a, b in cpp_statements(text):
        d = cpp_declaration(text[a:b])
        if d is not None:
            out.append((d.name, a + d.name_at, "init"))
    return sorted(out, key=lambda x: x[1])


_CPP_INT = re.compile(r"^[+-]?\d+[uUlL]*$")
_CPP_FLOAT = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?[fFlL]?$")


def cpp_value(typ: str, init: str | None) -> tuple[bool, object]:
    """A plain value for a bool/int/float declaration, when its initializer is a literal."""
    if typ == "bool":
        table: dict[str | None, bool] = {None: False, "true": True, "false": False}
        return (True, table[init]) if init in table else (False, None)
    if typ == "int":
        if init is None:
            return True, 0
        if _CPP_INT.match(init):
            value = int(init.rstrip("uUlL"))
            return (True, value) if -(2**63) <= value < 2**63 else (False, None)
        return False, None
    if typ in ("float", "double"):
        if init is None:
            return True, 0.0
        if _CPP_FLOAT.match(init):
            return True, float(init.rstrip("fFlL"))
    return False, None


# ---------------------------------------------------------------------------
# which language


_CPP_SIGNS = re.compile(r"->|::|;\s*$|^\s*#\s*(?:include|define)\b|^\s*//|/\*|[{}]", re.M)


def guess_language(texts: Iterable[tuple[str, bool]]) -> tuple[Language, str]:
    """Python or C++, from the code texts (each with whether it is a function body),
    and the reason, for the report.  A text counts for Python when it parses as
    Python and shows no C++ sign, for C++ when it does not parse and shows one."""
    py = cpp = 0
    for text, body in texts:
        if not text.strip():
            continue
        ok = parses(as_function_body(text) if body else text) or (
            not body and parses(text, "eval"))
        signs = _CPP_SIGNS.search(mask(text, "cpp")) is not None
        if ok and not signs:
            py += 1
        elif not ok and signs:
            cpp += 1
    total = py + cpp
    if total == 0:
        return "python", "no code tells which: python assumed"
    if cpp > py:
        return "cpp", f"{cpp} code texts are C++, not Python" + (
            f"; {py} are valid in both" if py else "")
    return "python", f"{py} code texts parse as Python" + (
        f"; {cpp} look like C++" if cpp else "")


def identifier(text: str, fallback: str) -> str:
    """``text`` made an identifier: other characters become `_`, a leading digit gets `_`."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", text.strip())
    if not name:
        return fallback
    return f"_{name}" if name[0].isdigit() else name


def python_import_names(text: str) -> set[str]:
    """Names an import line (``numpy as np``, ``from x import y``) binds."""
    t = text.strip()
    stmt = t if t.startswith(("import ", "from ")) else f"import {t}"
    try:
        tree = ast.parse(stmt)
    except (SyntaxError, ValueError):
        return set()
    out: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Import | ast.ImportFrom):
            out.update((a.asname or a.name.split(".")[0]) for a in node.names)
    return out


_PY_PREFIX = re.compile(r"(?<![\w.])self[ \t]*\.[ \t]*(?:(?:" + "|".join(PY_SCOPES)
                        + r")[ \t]*\.[ \t]*)?")
_CPP_PREFIX = re.compile(r"(?<![\w.>:])(?:" + "|".join(CPP_SCOPES) + r")[ \t]*->[ \t]*")


def uses(texts: Iterable[str], name: str, language: Language) -> bool:
    """Whether any text uses ``name`` as an identifier of its own or of a legacy namespace
    (``self.name``, ``globalNamespace->name``), not as some object's member."""
    pattern = re.compile(r"(?<![\w.])(?<!->)" + re.escape(name) + r"(?!\w)")
    prefix = _PY_PREFIX if language == "python" else _CPP_PREFIX
    return any(pattern.search(prefix.sub("", mask(t, language))) for t in texts)
