"""Checks of Python snippets: syntax, undefined names, assignments to parameters,
and the helpers' arguments (a literal ``active()`` path, ``done()``) of both languages.

Every snippet is parsed on its own (exact syntax error positions).  For
undefined names, the snippets are then joined into synthetic modules, each
snippet a function body with its line numbers moved to a range of its own,
and pyflakes checks those modules with the model's names as extra builtins.
Each message is mapped back to its snippet, and from there to the model file.

Most snippets cannot give pyflakes anything to report, and pyflakes walks a
tree in Python.  So each snippet first goes through CPython's own symbol
table pass (:mod:`symtable`, at C speed, which parses it as well): a snippet
whose every name is either known or bound where no use can come before its
binding (a parameter, a comprehension's single loop) is clean; pyflakes only
checks the modules holding a snippet that is not.  The ast tree of a snippet
is built only where a check needs it.
"""

from __future__ import annotations

import ast
import builtins
import importlib
import json
import re
import textwrap
from bisect import bisect_right
from dataclasses import dataclass
from typing import Any

from pyflakes import messages as pyflakes_messages
from pyflakes.checker import Checker

from hfsmc.drivers import CPP_NAMES, Driver, Method, driver, option_names
from hfsmc.errors import Diagnostics, Span, did_you_mean
from hfsmc.ir import HELPERS, Code, Model

_symtable: Any
try:  # CPython's symbol table pass; the plain `symtable` module wraps it in Python objects
    _symtable = importlib.import_module("_symtable")
except ImportError:  # pragma: no cover - another interpreter: every snippet goes to pyflakes
    _symtable = None

_DEFINED = re.compile(r"^(?:def|class)\s+([A-Za-z_]\w*)|^([A-Za-z_]\w*)\s*=", re.M)
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_INDENT = "    "
_CHUNK = 100  # snippets per module handed to pyflakes
_REPORTED = (pyflakes_messages.UndefinedName, pyflakes_messages.UndefinedLocal)
# Text that sends a snippet to pyflakes whatever its symbol table says: statements that
# unbind or rebind names across scopes, typing helpers and postponed annotations (pyflakes
# reads names inside their strings), private names in classes (mangled in the table).
_PYFLAKES_TEXT = re.compile(r"\b(?:del|global|nonlocal)\b|typing|__future__|__")
# With a quote in the snippet: anything that may be an annotation (a string annotation's
# names are checked too): `->`, `def`, a line continuation, a line starting with a closing
# bracket, or a name, attribute or subscript followed by `:` where a statement starts.
_ANNOTATION = re.compile(r"->|\bdef\b|\\\r?\n|^[ \t]*[\])]|(?:^|[;:])[ \t]*\(*[ \t]*"
                         r"(?!(?:else|try|finally|lambda)\b)[A-Za-z_][\w.]*[ \t]*(?:\[.*)?:(?!=)",
                         re.M)
_FOR = re.compile(r"\bfor\b")
_KNOWN: frozenset[str] = frozenset()  # a clean snippet's unknown names
# An augmented assignment reads its target first; the symbol table records only the binding.
_AUGMENTED = re.compile(r"(?:[-+*/%@&|^]|<<|>>)=")
_COMPREHENSIONS = frozenset({"listcomp", "genexpr", "setcomp", "dictcomp"})
if _symtable is not None:
    _USE = _symtable.USE
    _BOUND = _symtable.DEF_LOCAL | _symtable.DEF_PARAM | _symtable.DEF_IMPORT
    _PARAM = _symtable.DEF_PARAM
    # Declared elsewhere: `global`, `nonlocal`, or an assignment expression in a
    # comprehension, which binds in the scope around it.
    _ELSEWHERE = _symtable.DEF_GLOBAL | _symtable.DEF_NONLOCAL
    _ASSIGNED = _symtable.DEF_LOCAL | _ELSEWHERE


@dataclass(frozen=True, slots=True)
class Snippet:
    kind: str  # entry | during | exit | when | do | functions | on_shutdown
    where: str  # state path, or "" for the root's snippets
    code: Code

    @property
    def mode(self) -> str:
        return "eval" if self.kind == "when" else "exec"


def snippets(model: Model) -> list[Snippet]:
    """Every snippet of the model in model order (functions first)."""
    out: list[Snippet] = []
    if model.functions is not None:
        out.append(Snippet("functions", "", model.functions))
    for s in model.own_states():  # a used file's snippets are checked with its own names
        for kind in ("entry", "during", "exit"):
            code = getattr(s, kind)
            if code is not None:
                out.append(Snippet(kind, s.path, code))
        for t in s.transitions:
            if t.when is not None:
                out.append(Snippet("when", s.path, t.when))
            if t.do is not None:
                out.append(Snippet("do", s.path, t.do))
    if model.on_shutdown is not None:
        out.append(Snippet("on_shutdown", "", model.on_shutdown))
    return out


def import_statement(text: str) -> str:
    """``numpy as np`` → ``import numpy as np``; full statements are kept."""
    t = text.strip()
    return t if t.startswith(("import ", "from ")) else f"import {t}"


def _parse(sn: Snippet, diags: Diagnostics) -> ast.AST | None:
    try:
        # Not the model's file name: CPython re-reads that file to place the caret of a
        # syntax error, which would give columns from the wrong line.
        return ast.parse(sn.code.text, filename="<snippet>", mode=sn.mode)
    except SyntaxError as e:
        line, col = e.lineno or 1, e.offset or 1
        where = f" of `{sn.where}`" if sn.where else ""
        diags.error("E140", f"syntax error in {sn.kind}{where}: {e.msg}", sn.code.position(line, col))
    except (ValueError, MemoryError, RecursionError) as e:  # NUL bytes, absurd nesting
        diags.error("E140", f"cannot parse {sn.kind}: {e}", sn.code.span)
    return None


def _imported_names(model: Model, diags: Diagnostics) -> set[str]:
    names: set[str] = set()
    for imp in model.imports:
        try:
            tree = ast.parse(import_statement(imp.text))
        except SyntaxError:
            tree = None
        stmt = tree.body[0] if tree is not None and len(tree.body) == 1 else None
        if not isinstance(stmt, (ast.Import, ast.ImportFrom)):
            diags.error("E143", f"`{imp.text}` is not an import: write `math`, `numpy as np` "
                        "or `from math import pi`", imp.span)
            continue
        for alias in stmt.names:
            if alias.name == "*":
                diags.error("E143", "`import *` hides which names a snippet uses", imp.span)
            names.add(alias.asname or alias.name.split(".")[0])
    return names


def _module_names(tree: ast.AST) -> set[str]:
    """Names bound at the top level of the `functions` code."""
    out: set[str] = set()
    for node in getattr(tree, "body", []):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            out.update((a.asname or a.name.split(".")[0]) for a in node.names)
        else:
            for sub in ast.walk(node):
                if isinstance(sub, ast.Name) and isinstance(sub.ctx, ast.Store):
                    out.add(sub.id)
    return out


def check_python_snippets(model: Model, diags: Diagnostics, prefilter: bool = True) -> None:
    """E140-E143, E146, E148, E149 and W215 for every Python snippet of the model.

    Without ``prefilter`` every snippet gets its ast tree and every chunk
    goes to pyflakes (the tests compare both ways)."""
    variables = [v.name for v in model.variables]
    params = {p.name for p in model.parameters}
    known = (set(HELPERS) | set(variables) | params | {i.name for i in model.interfaces}
             | _imported_names(model, diags))
    # Each snippet that parses, with the names it uses unbound that are not known so far
    # (None: pyflakes must look).  Trees and sets are dropped at once: a big model has
    # 100,000s of snippets, and `known` only grows (from `functions`, the first).
    parsed: list[tuple[Snippet, frozenset[str] | set[str] | None]] = []
    builtin_names = set(dir(builtins))
    names = known | builtin_names
    drivers = _drivers(model)
    listed = _listed(model)
    uses = (re.compile(r"\b(?:" + "|".join(map(re.escape, drivers)) + r")\s*\.") if drivers
            else None)
    for sn in snippets(model):
        text = sn.code.text
        table = _table(sn) if prefilter else None
        tree = _parse(sn, diags) if table is None else None
        if table is None and tree is None:
            if sn.kind == "functions":  # still know what it meant to define: no E141 cascade
                known |= {a or b for a, b in _DEFINED.findall(text)}
                names = known | builtin_names
            continue
        writes = not ((sn.mode == "eval" and ":=" not in text)
                      or params.isdisjoint(_IDENTIFIER.findall(text)))
        if table is not None and writes:
            writes = _assigns(table, params)  # no table binds a parameter: nothing to say
        helpers = "active" in text or "done" in text
        calls = uses is not None and uses.search(text) is not None
        if tree is None and (writes or helpers or calls or sn.kind == "functions"):
            tree = _parse(sn, diags)
            if tree is None:  # pragma: no cover - the symbol table pass parsed it
                continue
        free = None if table is None else _unbound(sn, table, variables)
        parsed.append((sn, _KNOWN if free is not None and free <= names else free))
        if tree is None:
            continue
        if sn.kind == "functions":
            known |= _module_names(tree)
            names = known | builtin_names
        if writes:
            _check_param_writes(sn, tree, params, diags)
        if helpers:
            _check_helper_calls(model, sn, tree, diags)
        if calls:
            _check_interface_uses(sn, tree, drivers, diags, listed)
    _check_undefined(model.file, parsed, variables, params, known, diags)


def _table(sn: Snippet) -> object | None:
    """The snippet's symbol table; None when it does not compile there (the ast parse then
    says why, or gives the tree: the table pass refuses more than the parser)."""
    if _symtable is None:
        return None  # pragma: no cover
    try:
        table: object = _symtable.symtable(sn.code.text, "<snippet>", sn.mode)
        return table
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        return None


def _assigns(table: object, names: set[str]) -> bool:
    """Whether any scope of the table binds one of ``names``."""
    symbols: dict[str, int] = table.symbols  # type: ignore[attr-defined]
    if any(symbols[n] & _ASSIGNED for n in names & symbols.keys()):
        return True
    return any(_assigns(child, names) for child in table.children)  # type: ignore[attr-defined]


def _unbound(sn: Snippet, table: object, variables: list[str]) -> set[str] | None:
    """The names the snippet uses without binding them, or None when pyflakes could still
    report something however known those names are.

    pyflakes sees the snippet as a function's body: a name bound there and used anywhere
    in it might be used before its binding (or after an ``except`` clause unbinds it), so
    such a snippet goes to pyflakes, unless the name is a parameter of a nested function
    or lambda or the target of a comprehension in a snippet with a single ``for``.
    """
    text = sn.code.text
    if _PYFLAKES_TEXT.search(text) or (("'" in text or '"' in text) and _ANNOTATION.search(text)):
        return None
    one_for = len(_FOR.findall(text)) <= 1
    augmented = _AUGMENTED.search(text) is not None
    top: dict[str, int] = table.symbols  # type: ignore[attr-defined]
    used = {n for n, f in top.items() if f & _USE or (augmented and f & _BOUND)}
    for child in table.children:  # type: ignore[attr-defined]
        inner = _scope_uses(child, one_for, augmented)
        if inner is None:
            return None
        used |= inner
    if sn.kind == "functions":
        return used  # module level: what it binds is known (``_module_names``), or looked at
    bound = {n for n, f in top.items() if f & (_BOUND | _ELSEWHERE)}
    if not bound.isdisjoint(used) and not (bound & used) <= set(variables):
        return None  # variables are declared `global` in the function pyflakes sees
    return used


def _scope_uses(table: object, one_for: bool, augmented: bool) -> set[str] | None:
    """What a nested scope and those inside it use without binding (None: see _unbound)."""
    symbols: dict[str, int] = table.symbols  # type: ignore[attr-defined]
    bound = {n for n, f in symbols.items() if f & _BOUND and not f & _ELSEWHERE}
    used = {n for n, f in symbols.items() if f & _USE}
    if augmented:
        used |= bound
    for child in table.children:  # type: ignore[attr-defined]
        inner = _scope_uses(child, one_for, augmented)
        if inner is None:
            return None
        used |= inner
    exempt = one_for and table.name in _COMPREHENSIONS  # type: ignore[attr-defined]
    if not exempt and any(not symbols[n] & _PARAM for n in bound & used):
        return None
    return used - bound


def _check_undefined(file: str, parsed: list[tuple[Snippet, frozenset[str] | set[str] | None]],
                     variables: list[str], params: set[str], known: set[str],
                     diags: Diagnostics) -> None:
    """pyflakes over the snippets in chunks: one module each, a snippet a function.

    Each chunk is assembled as text and parsed at C speed.  Chunks, not one
    module: CPython's parser slows down per function as a module grows, and
    names from `functions` reach pyflakes as builtins anyway.  A chunk whose
    snippets are all clean (each uses only names pyflakes knows, see
    :func:`_unbound`) is not checked.  Should a chunk not parse (it always
    should: each snippet parsed alone), its snippets are checked one by one
    instead.
    """
    names = known | set(dir(builtins))
    groups = [parsed[i:i + _CHUNK] for i in range(0, len(parsed), _CHUNK)]
    while groups:
        members = groups.pop()
        if all(free is not None and free <= names for _, free in members):
            continue
        group = [sn for sn, _ in members]
        joined = _joined(group, variables)
        if joined is None:
            if len(members) > 1:
                groups.extend([item] for item in members)
            continue
        try:
            checker = Checker(joined[0], filename=file, builtins=names)
        except RecursionError:
            continue  # absurdly nested code: the syntax check has already had its say
        _report_undefined(checker, group, joined[1], params, known, diags)


def _joined(group: list[Snippet], variables: list[str]) -> tuple[ast.Module, list[int]] | None:
    """The group's snippets as one parsed module and the first line of each snippet."""
    parts: list[str] = []
    bases: list[int] = []
    line = 1
    for n, sn in enumerate(group):
        text = sn.code.text if sn.code.text.endswith("\n") else sn.code.text + "\n"
        if sn.kind == "functions":
            head, body, tail = "", text, ""
        else:
            used = set(_IDENTIFIER.findall(text))
            declared = [v for v in variables if v in used]  # a `global` per variable it names
            glob = f"    global {', '.join(declared)}\n" if declared else ""
            head = f"def _snippet_{n}():\n{glob}" + ("    return (\n" if sn.mode == "eval" else "")
            body = textwrap.indent(text, _INDENT, lambda _line: True)
            tail = "    )\n" if sn.mode == "eval" else "    pass\n"
        line += head.count("\n")
        bases.append(line)
        parts += (head, body, tail)
        line += body.count("\n") + tail.count("\n")
    try:
        return ast.parse("".join(parts)), bases
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        return None


def _report_undefined(checker: Checker, group: list[Snippet], bases: list[int],
                      params: set[str], known: set[str], diags: Diagnostics) -> None:
    seen: set[tuple[int, int, str]] = set()
    for msg in sorted(checker.messages, key=lambda m: (m.lineno, m.col)):
        if not isinstance(msg, _REPORTED):
            continue
        i = bisect_right(bases, msg.lineno) - 1
        sn = group[max(i, 0)]
        shift = 0 if sn.kind == "functions" else len(_INDENT)
        pos = sn.code.position(msg.lineno - bases[i] + 1, msg.col - shift + 1)
        args = msg.message_args
        name = args if isinstance(args, str) else args[0]
        if isinstance(msg, pyflakes_messages.UndefinedLocal) and name in params:
            continue  # an assignment to a parameter: E142 says it better
        if (pos.line, pos.col, name) in seen:
            continue
        seen.add((pos.line, pos.col, name))
        where = f" of `{sn.where}`" if sn.where else ""
        note = did_you_mean(name, known) or ("not a variable, parameter, interface, function, "
                                             "import, helper or builtin")
        diags.error("E141", f"undefined name `{name}` in {sn.kind}{where}", pos, note)


def _check_param_writes(sn: Snippet, tree: ast.AST, params: set[str], diags: Diagnostics) -> None:
    if (sn.mode == "eval" and ":=" not in sn.code.text) or params.isdisjoint(
            _IDENTIFIER.findall(sn.code.text)):
        return  # cheap: most snippets never assign (or even name) a parameter

    def visit(nodes: list[ast.AST], globals_: set[str], top: bool) -> None:
        for node in nodes:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                declared = {n for g in ast.walk(node) if isinstance(g, ast.Global) for n in g.names}
                visit(list(node.body), declared, False)
                continue
            if isinstance(node, (ast.Lambda, ast.ClassDef)):
                continue
            if isinstance(node, ast.comprehension):  # its target is local to it
                visit([node.iter, *node.ifs], globals_, top)
                continue
            if (isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store)
                    and node.id in params and (top or node.id in globals_)):
                diags.error("E142", f"parameter `{node.id}` is read-only; make it a variable to "
                                "change it", sn.code.position(node.lineno, node.col_offset + 1))
            visit(list(ast.iter_child_nodes(node)), globals_, top)

    visit(list(ast.iter_child_nodes(tree)), set(), True)


# ---------------------------------------------------------------------------
# helper calls (both languages: hfsmc/cppsnippets.py finds them in C++)


def check_active_path(model: Model, sn: Snippet, path: str, where: Span,
                      diags: Diagnostics) -> None:
    """E146 when ``active(path)``'s literal names no state (the component would fail
    at run time); ``where`` is the string literal's position."""
    if sn.code.span.file != model.file:
        return  # a snippet of a used file: its paths are relative to where it is used
    wanted = path.strip("/")  # as the runtimes read it
    if wanted and model.find(wanted) is not None:
        return
    if any(wanted.startswith(f"{u}/") for u in model.unresolved_uses):
        return  # below a `use` that failed: its error says why
    paths = [s.path for s in model.states()]
    last = wanted.rpartition("/")[2]
    note = did_you_mean(wanted, paths)
    elsewhere = [p for p in paths if last and p.rpartition("/")[2] == last]
    if note is None and elsewhere:
        note = f"`{last}` is at {', '.join(f'`{p}`' for p in elsewhere[:5])}"
    if note is None:
        example = max(paths, key=lambda p: p.count("/"), default="A/B")
        note = f"a path names states from the root down, joined by `/`: `{example}`"
    diags.error("E146", f"active({json.dumps(path, ensure_ascii=False)}): no state has this path",
                where, note)


def check_done(model: Model, sn: Snippet, where: Span, diags: Diagnostics) -> None:
    """W215 for ``done()`` in the snippets of a state without a sub-automaton."""
    if not sn.where:
        return  # functions and on_shutdown: the caller's state decides
    state = model.find(sn.where)
    if state is not None and not state.automata and state.path not in model.unresolved_uses:
        diags.warning("W215", f"done() in {sn.kind} of `{sn.where}` is always false: the state "
                      "has no sub-automaton", where,
                      "done() says whether the owning state's sub-automaton (every one of its "
                      "regions) is in a final state")


def _check_helper_calls(model: Model, sn: Snippet, tree: ast.AST, diags: Diagnostics) -> None:
    rows = sn.code.text.split("\n")
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
            continue
        if node.func.id == "active" and len(node.args) == 1 and not node.keywords:
            arg = node.args[0]
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                check_active_path(model, sn, arg.value, _where(sn, rows, arg), diags)
        elif node.func.id == "done" and not node.args and not node.keywords:
            check_done(model, sn, _where(sn, rows, node), diags)


def _where(sn: Snippet, rows: list[str], node: ast.expr) -> Span:
    """The model position of a node (ast's columns count UTF-8 bytes, ours characters)."""
    row = rows[node.lineno - 1] if 0 < node.lineno <= len(rows) else ""
    col = len(row.encode("utf-8")[:node.col_offset].decode("utf-8", "replace")) + 1
    return sn.code.position(node.lineno, col)


# ---------------------------------------------------------------------------
# interface methods (C++ snippets: the compiler knows them)


def _drivers(model: Model) -> dict[str, Driver]:
    """The model's interfaces that have a driver, by name."""
    out = {}
    for i in model.interfaces:
        d = i.declaration if i.type == "driver" else driver(i.type)
        if d is not None:
            out[i.name] = d
    return out


def _listed(model: Model) -> dict[str, dict[str, tuple[str, ...]]]:
    """Per interface, the names each of its options lists (a driver's `names`; a ros2
    interface's subscriptions and publications)."""
    return {i.name: ({"subscribe": tuple(t.name for t in i.ros2.subscribe),
                      "publish": tuple(t.name for t in i.ros2.publish),
                      "actions": tuple(t.name for t in i.ros2.actions),
                      "services": tuple(t.name for t in i.ros2.services)}
                     if i.ros2 is not None
                     else {k: option_names(v) for k, v in i.options})
            for i in model.interfaces}


def _check_interface_uses(sn: Snippet, tree: ast.AST, drivers: dict[str, Driver],
                          diags: Diagnostics,
                          listed_names: dict[str, dict[str, tuple[str, ...]]] | None = None
                          ) -> None:
    """E148 for ``drone.fly_to`` (no such method or attribute), E149 for a call of a
    method with arguments its parameters do not take. A snippet that binds an
    interface's name itself (a parameter, an assignment) is not checked for that name."""
    bound = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and not isinstance(n.ctx, ast.Load)}
    bound |= {a.arg for n in ast.walk(tree) if isinstance(n, ast.arguments)
              for a in (*n.posonlyargs, *n.args, *n.kwonlyargs, n.vararg, n.kwarg) if a is not None}
    bound |= {(a.asname or a.name).split(".")[0] for n in ast.walk(tree)
              if isinstance(n, (ast.Import, ast.ImportFrom)) for a in n.names}
    bound |= {n.name for n in ast.walk(tree)
              if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))}
    rows = sn.code.text.split("\n")
    called = {id(n.func): n for n in ast.walk(tree) if isinstance(n, ast.Call)}
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in drivers and node.value.id not in bound
                and not node.attr.startswith("_")):  # private: the driver's, not the interface's
            continue
        iface, d = node.value.id, drivers[node.value.id]
        where = _attr_where(sn, rows, node)
        method = d.methods.get(node.attr)
        listed = (listed_names or {}).get(iface, {})
        if method is None and any(node.attr in listed.get(o, ()) for o in d.attributes_from):
            continue  # an attribute per listed name (a subscription's latest message)
        if method is None and node.attr not in d.names:
            attributes = tuple(n for o in d.attributes_from for n in listed.get(o, ()))
            _unknown_member(sn, iface, d, node.attr, where, diags, attributes)
        elif method is None and id(node) in called:  # name, url: called as C++ has them
            diags.error("E148", f"`{iface}.{node.attr}` is an attribute in Python, not a "
                        f"method: write `{iface}.{node.attr}` (C++: `{iface}.{node.attr}()`)",
                        where)
        elif method is not None and id(node) in called:
            _check_arguments(sn, iface, method, called[id(node)], where, diags)
            _check_names(sn, iface, method, called[id(node)], listed, diags)


def _unknown_member(sn: Snippet, iface: str, d: Driver, attr: str, where: Span,
                    diags: Diagnostics, attributes: tuple[str, ...] = ()) -> None:
    python = {v: k for k, v in CPP_NAMES.items()}.get(attr)
    note = (f"`{attr}` is the C++ name; in Python the method is `{python}`" if python
            else did_you_mean(attr, (*attributes, *d.names)))
    if note is None:
        listed = ", ".join(m.signature() for m in d.methods.values())
        note = f"{d.type} methods: {listed}; attributes: {', '.join((*attributes, 'name', 'url'))}"
    what = (f"has no {' or '.join(d.attributes_from)} entry or method" if d.attributes_from
            else "has no method")
    diags.error("E148", f"`{iface}` ({d.type} interface) {what} `{attr}`", where, note)


def _check_arguments(sn: Snippet, iface: str, m: Method, call: ast.Call, where: Span,
                     diags: Diagnostics) -> None:
    if any(isinstance(a, ast.Starred) for a in call.args) or any(k.arg is None for k in call.keywords):
        return  # *args or **kwargs: the count is known at run time only
    given = len(call.args)
    keywords = [k.arg for k in call.keywords if k.arg is not None]
    problem = None
    if given > len(m.params):
        problem = f"{given} given"
    else:
        unknown = [k for k in keywords if k not in m.params]
        twice = [k for k in keywords if k in m.params[:given]]
        missing = [p for p in m.params[given:m.required] if p not in keywords]
        if unknown:
            problem = f"no parameter `{unknown[0]}`"
        elif twice:
            problem = f"`{twice[0]}` given twice"
        elif missing:
            problem = f"missing {', '.join(f'`{p}`' for p in missing)}"
    if problem is None:
        return
    count = len(m.params)
    takes = ("no arguments" if count == 0 else
             f"{count} argument{'s' if count > 1 else ''} ({', '.join(m.params)})")
    diags.error("E149", f"`{iface}.{m.name}` takes {takes}: {problem}", where,
                f"{m.signature()}: {m.doc.replace('``', '`')}")


def _check_names(sn: Snippet, iface: str, m: Method, call: ast.Call,
                 listed: dict[str, tuple[str, ...]], diags: Diagnostics) -> None:
    """E148 for a literal argument that must name an entry of an option and does not
    (``robot.age("scn")`` when the subscriptions are scan and odom)."""
    for param, option in m.names:
        k = m.params.index(param)
        arg = (call.args[k] if k < len(call.args) and not isinstance(call.args[k], ast.Starred)
               else next((kw.value for kw in call.keywords if kw.arg == param), None))
        if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
            continue  # computed: the driver says so when called
        names = listed.get(option, ())
        if arg.value not in names:
            line = arg.lineno
            rows = sn.code.text.split("\n")
            row = rows[line - 1] if 0 < line <= len(rows) else ""
            col = len(row.encode("utf-8")[:arg.col_offset].decode("utf-8", "replace")) + 1
            diags.error("E148", f"`{iface}.{m.name}`: `{arg.value}` is not one of the "
                        f"interface's `{option}` ({', '.join(names) or 'none declared'})",
                        sn.code.position(line, col), did_you_mean(arg.value, names) or
                        f"declare it in the interface's `{option}`")


def _attr_where(sn: Snippet, rows: list[str], node: ast.Attribute) -> Span:
    """The model position of the attribute's name (after the dot), as E145 gives it."""
    line = node.end_lineno or node.lineno
    end = node.end_col_offset if node.end_col_offset is not None else node.col_offset
    row = rows[line - 1] if 0 < line <= len(rows) else ""
    col = len(row.encode("utf-8")[:end].decode("utf-8", "replace")) - len(node.attr) + 1
    return sn.code.position(line, max(col, 1))
