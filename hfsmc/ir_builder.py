"""The IR builder: a schema-valid neutral :class:`Document` becomes the IR.

It turns data into frozen dataclasses with spans and reports what is local to
one node (durations, duplicate names, value types).  Everything that needs
the whole tree (targets, initial states, periods) is done by the passes in
:mod:`hfsmc.lower`.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Callable
from typing import Any

from hfsmc.driverfiles import driver_files
from hfsmc.durations import has_unit, parse_us
from hfsmc.errors import Diagnostics
from hfsmc.frontend.source import YAML11_BOOLS, Document, PathKey
from hfsmc.ir import (
    DEFAULT_ROOT_PERIOD_MS,
    Automaton,
    Code,
    DictValue,
    Import,
    Interface,
    Model,
    Parameter,
    State,
    Transition,
    Value,
    Variable,
)
from hfsmc.ros2files import check_messages, misplaced_keys, ros2_settings

_LITERAL_TYPES: dict[type, str] = {bool: "bool", int: "int", float: "float", str: "str", list: "list"}
_PY_TYPES = {"bool": bool, "int": int, "float": float, "str": str, "list": list, "dict": dict}


# Builds the sub-automaton of a state that writes `use` (hfsmc/uses.py): given the using
# document, its diagnostics, the state's node, its document path, its state path and the
# period it inherits; None when the used file cannot give one (the hook said why).
UseHook = Callable[[Document, Diagnostics, dict[str, Any], PathKey, str, int], "Automaton | None"]
_USE_EXCLUDES = ("states", "regions", "initial", "period", "history")


def build_ir(doc: Document, diags: Diagnostics, uses: UseHook | None = None) -> Model:
    """The IR of one document; ``uses`` builds the states that `use` another file."""
    return _IrBuilder(doc, diags, uses).model()


def coerce_literal(doc: Document, diags: Diagnostics, value: Any, vtype: str, path: PathKey,
                   code: str = "E101") -> Value:
    """``value`` (at ``path``) checked against ``vtype``; text from XML is converted."""
    return _IrBuilder(doc, diags).coerce(value, vtype, path, code)


def _freeze(v: Any) -> Value:
    if isinstance(v, list):
        return tuple(_freeze(x) for x in v)
    if isinstance(v, dict):
        return DictValue(tuple((str(k), _freeze(x)) for k, x in v.items()))
    return v  # type: ignore[no-any-return]


class _IrBuilder:
    def __init__(self, doc: Document, diags: Diagnostics, uses: UseHook | None = None) -> None:
        self.doc = doc
        self.diags = diags
        self.uses = uses
        self.unresolved: list[str] = []  # states whose `use` gave no sub-automaton
        self.data: dict[str, Any] = doc.data

    # -- helpers -----------------------------------------------------------
    def code(self, node: dict[str, Any] | None, path: PathKey, key: str) -> Code | None:
        if not node or node.get(key) is None:
            return None
        text = node[key]
        if isinstance(text, bool):  # `when: true`
            text = "True" if text else "False"
        p = (*path, key)
        return Code(str(text), self.doc.span(p), self.doc.cont_col(p), self.doc.segments.get(p, ()))

    def duration(self, node: dict[str, Any], path: PathKey, key: str) -> int | None:
        if key not in node:
            return None
        us = parse_us(node[key])
        if us is None:
            self.diags.error("E110", f"`{node[key]}` is not a duration: write 250ms, 2s, 1.5s or 2m "
                             "(at most a year, whole microseconds)", self.doc.span((*path, key)))
        elif us and self.doc.format in ("yaml", "xml") and not has_unit(node[key]):
            # still milliseconds (docs: durations); legacy imports keep their bare numbers quietly
            n = str(node[key]).strip()
            shown = f'{key}="{node[key]}"' if self.doc.format == "xml" else f"{key}: {node[key]}"
            self.diags.warning("W212", f"`{shown}` has no unit: a bare number means "
                               "milliseconds", self.doc.span((*path, key)),
                               f"write `{n}ms`, or `{n}s` if you meant seconds")
        return us

    def period(self, node: dict[str, Any], path: PathKey) -> int | None:
        us = self.duration(node, path, "period")
        if us is None:
            return None
        if us % 1000 or us < 1000:
            self.diags.error("E111", f"period `{node['period']}` must be a whole number of "
                             "milliseconds, at least 1ms", self.doc.span((*path, "period")))
            return None
        return us // 1000

    # -- the model ---------------------------------------------------------
    def model(self) -> Model:
        d = self.data
        language = d.get("language", "python")
        root = self.automaton(d, (), "", DEFAULT_ROOT_PERIOD_MS)
        interrupt_us = self.duration(d, (), "interrupt_timeout")
        limit_us = self.duration(d, (), "time_limit")
        if limit_us is not None and limit_us <= 0:
            self.diags.error("E103", f"time_limit `{d['time_limit']}` must be more than 0",
                             self.doc.span(("time_limit",)))
            limit_us = None
        imports = tuple(Import(t, self.doc.span(("imports", i)))
                        for i, t in enumerate(d.get("imports", [])))
        interfaces = self.interfaces()
        check_messages(interfaces, imports, self.diags)
        return Model(
            name=d["name"],
            language=language,
            description=d.get("description"),
            imports=imports,
            interfaces=interfaces,
            parameters=self.parameters(),
            variables=self.variables(language),
            functions=self.code(d, (), "functions"),
            on_shutdown=self.code(d, (), "on_shutdown"),
            on_interrupt=d.get("on_interrupt"),
            interrupt_timeout_us=interrupt_us,
            root=root,
            file=self.doc.file,
            span=self.doc.span(()),
            on_interrupt_span=self.doc.span(("on_interrupt",)) if "on_interrupt" in d else None,
            unresolved_uses=tuple(self.unresolved),
            source=self.doc.text,
            interrupt_timeout_span=(self.doc.key_span(("interrupt_timeout",))
                                    if "interrupt_timeout" in d else None),
            time_limit_us=limit_us,
            time_limit_span=self.doc.key_span(("time_limit",)) if "time_limit" in d else None,
        )

    def interfaces(self) -> tuple[Interface, ...]:
        out = []
        for name, spec in (self.data.get("interfaces") or {}).items():
            opts = tuple(sorted((str(k), str(v)) for k, v in (spec.get("options") or {}).items()))
            span = self.doc.key_span(("interfaces", name))
            if spec["type"] == "ros2":
                settings = ros2_settings(self.doc, name, spec, self.data["name"],
                                         self.data.get("language", "python"), self.diags)
                out.append(Interface(name, "ros2", None, (), span, ros2=settings))
                continue
            misplaced_keys(self.doc, name, spec, self.diags)
            if spec["type"] != "driver":
                out.append(Interface(name, spec["type"], spec.get("url"), opts, span))
                continue
            spans = {k: self.doc.span(("interfaces", name, k)) for k in ("type", "python", "cpp")
                     if k in spec}
            spans.update({f"options.{k}": self.doc.key_span(("interfaces", name, "options", k))
                          for k in spec.get("options") or {}})
            py, cpp, decl = driver_files(self.doc.file, spec, self.data.get("language", "python"),
                                         spans, getattr(self.uses, "texts", None), self.diags)
            out.append(Interface(name, "driver", spec.get("url"), opts, span, py, cpp, decl))
        return tuple(out)

    def parameters(self) -> tuple[Parameter, ...]:
        out = []
        for name, spec in (self.data.get("parameters") or {}).items():
            path: PathKey = ("parameters", name)
            default = self.coerce(spec["default"], spec["type"], (*path, "default"))
            literal_traps(self.doc, (*path, "default"), spec["type"], self.diags)
            out.append(Parameter(name, spec["type"], default, self.doc.key_span(path),
                                 spec.get("description")))
        return tuple(out)

    def variables(self, language: str) -> tuple[Variable, ...]:
        out = []
        for name, spec in (self.data.get("variables") or {}).items():
            path: PathKey = ("variables", name)
            span = self.doc.key_span(path)
            if isinstance(spec, dict):
                vtype, init = spec["type"], spec["init"]
                if vtype in _PY_TYPES:
                    init = self.coerce(init, vtype, (*path, "init"))
                    literal_traps(self.doc, (*path, "init"), vtype, self.diags)
                elif language == "python":
                    self.diags.error("E103", f"variable type `{vtype}` is not one of "
                                     f"{', '.join(_PY_TYPES)} (a cpp model may name any C++ type)",
                                     self.doc.span((*path, "type")))
                else:  # a C++ type: its initializer is C++ code, kept as text in every format
                    init = _cpp_text(init)
                out.append(Variable(name, vtype, _freeze(init), True, span))
            else:
                vtype = _LITERAL_TYPES[type(spec)]
                literal_traps(self.doc, path, None, self.diags)
                out.append(Variable(name, vtype, _freeze(spec), False, span))
        return tuple(out)

    def coerce(self, value: Any, vtype: str, path: PathKey, code: str = "E101") -> Value:
        """Check (and for text from XML, convert) a literal against its declared type."""
        want = _PY_TYPES[vtype]
        if want is int and isinstance(value, int) and not -(2**63) <= value < 2**63:
            self.diags.error("E103", f"`{path[-1]}` {value} does not fit in 64 bits", self.doc.span(path))
            return 0
        if isinstance(value, want) and not (want is int and isinstance(value, bool)):
            return _freeze(value)
        if want is float and isinstance(value, int) and not isinstance(value, bool):
            return float(value)
        as_text = path[-1] in ("init", "default") or path[-2:-1] == ("with",)
        if isinstance(value, str) and as_text and self.doc.format != "yaml":
            converted = _from_text(value, vtype)
            if converted is not None:
                return converted
        notes: tuple[str, ...] = ()
        if vtype == "bool" and isinstance(value, str) and value.strip().lower() in YAML11_BOOLS:
            word = "true" if YAML11_BOOLS[value.strip().lower()] else "false"
            how = " (YAML 1.2 reads it as a string)" if self.doc.format == "yaml" else ""
            notes = (f"`{value.strip()}` is not a boolean{how}: write `{word}`",)
        article = "an" if vtype == "int" else "a"
        self.diags.error(code, f"`{path[-1]}` must be {article} {vtype}, not {value!r}", self.doc.span(path),
                         *notes)
        return _freeze(value)

    # -- states ------------------------------------------------------------
    def automaton(self, node: dict[str, Any], path: PathKey, owner: str, parent_ms: int,
                  region: str | None = None) -> Automaton:
        written = self.period(node, path)
        period_ms = written if written is not None else parent_ms
        prefix = owner if region is None else (f"{owner}/{region}" if owner else region)
        states = tuple(
            self.state(name, spec or {}, (*path, "states", name), prefix, period_ms)
            for name, spec in (node.get("states") or {}).items()
        )
        initial = node.get("initial", "")
        return Automaton(
            owner=owner,
            region=region,
            period_ms=period_ms,
            period_written=written is not None,
            initial=initial,
            history=bool(node.get("history", False)),
            states=states,
            span=self.doc.key_span((*path, "states")) if "states" in node else self.doc.key_span(path),
            initial_span=self.doc.span((*path, "initial")) if "initial" in node else self.doc.key_span(path),
        )

    def regions(self, node: dict[str, Any], path: PathKey, spath: str,
                period_ms: int) -> tuple[Automaton, ...]:
        """A state's parallel regions (docs/semantics.md: regions), in the order written."""
        regions: dict[str, Any] = node.get("regions") or {}
        rpath: PathKey = (*path, "regions")
        xml = self.doc.format == "xml"  # the words of the format the user wrote
        if "states" in node:
            both = "an `<automaton>` and `<region>` elements" if xml else "`states` and `regions`"
            self.diags.error("E160", f"state `{spath}` has both {both}: a state "
                             "holds one sub-automaton or parallel regions, not both",
                             self.doc.key_span(rpath),
                             "move the automaton's states into a `<region>`, or drop the "
                             "`<region>` elements" if xml else
                             "move the states into a region, or drop `regions`")
        if len(regions) == 1:
            name = next(iter(regions))
            self.diags.error("E161", f"state `{spath}` has a single region `{name}`: regions run "
                             "side by side, so a state needs two or more",
                             self.doc.key_span(rpath),
                             f"write the region as an `<automaton>` of `{spath}`" if xml else
                             f"write the region's `initial` and `states` on `{spath}` itself")
        for key in ("initial", "period", "history"):
            if key in node and "states" not in node:
                self.diags.error("E138", f"`{key}` of state `{spath}` belongs to one of its "
                                 "regions: each region has its own", self.doc.key_span((*path, key)))
        return tuple(self.automaton(spec or {}, (*rpath, name), spath, period_ms, name)
                     for name, spec in regions.items())

    def use(self, node: dict[str, Any], path: PathKey, spath: str,
            period_ms: int) -> tuple[Automaton, ...]:
        """The sub-automaton a state takes from another file (docs/model.md: use)."""
        for key in _USE_EXCLUDES:
            if key in node:
                self.diags.error("E176", f"state `{spath}` uses `{node['use']}`, which gives its "
                                 f"sub-automaton: `{key}` cannot be written beside `use`",
                                 self.doc.key_span((*path, key)),
                                 "the used file's root says it (its `period` too: without one, "
                                 "it takes this state's parent's)")
        if self.uses is None:
            return ()
        auto = self.uses(self.doc, self.diags, node, path, spath, period_ms)
        if auto is None:
            self.unresolved.append(spath)
            return ()
        return (auto,)

    def state(self, name: str, node: dict[str, Any], path: PathKey, parent: str, period_ms: int) -> State:
        spath = f"{parent}/{name}" if parent else name
        span = self.doc.key_span(path)
        autos: tuple[Automaton, ...] = ()
        if "with" in node and "use" not in node:
            self.diags.error("E184", f"`with` of state `{spath}` binds the parameters of a used "
                             "file, and the state has no `use`", self.doc.key_span((*path, "with")))
        if "use" in node:
            autos = self.use(node, path, spath, period_ms)
        elif "regions" in node:
            autos = self.regions(node, path, spath, period_ms)
        elif "states" in node:
            autos = (self.automaton(node, path, spath, period_ms),)
        else:
            for key in ("initial", "period", "history"):
                if key in node:
                    self.diags.error("E138", f"`{key}` needs a sub-automaton: state `{spath}` has no "
                                     "`states`", self.doc.key_span((*path, key)))
        final = bool(node.get("final", False))
        if final and autos:
            self.diags.error("E135", f"final state `{spath}` cannot hold a sub-automaton",
                             self.doc.key_span((*path, "final")))
        trans = tuple(self.transition(i, t, (*path, "transitions", i), spath)
                      for i, t in enumerate(node.get("transitions") or []))
        if final and trans:
            self.diags.error("E134", f"final state `{spath}` cannot have transitions",
                             self.doc.key_span((*path, "transitions")))
        return State(name, spath, self.code(node, path, "entry"), self.code(node, path, "during"),
                     self.code(node, path, "exit"), trans, final, autos, span)

    def transition(self, index: int, node: dict[str, Any], path: PathKey, source: str) -> Transition:
        after = self.duration(node, path, "after")
        when = self.code(node, path, "when")
        if when is None and "after" not in node:
            self.diags.error("E137", f"transition {index} of `{source}` needs `when`, `after` or both",
                             self.doc.span(path))
        return Transition(index, node["to"], when, after, self.code(node, path, "do"),
                          node.get("name"), self.doc.span(path), self.doc.span((*path, "to")))


_XML_LEADING_ZERO = re.compile(r"\s*[-+]?0[0-9]+\s*$")


def literal_traps(doc: Document, path: PathKey, declared: str | None, diags: Diagnostics) -> None:
    """Warn about a literal value (at ``path`` or inside it) that a YAML 1.1 reader, and
    many people, read differently from hfsmc: ``no`` is a string here (true in a
    condition), ``010`` is ten, not eight.  ``declared`` is the value's declared type,
    if any.  Used for variables and parameters' defaults; for any value bound from a
    model (a `with` binding) too.  docs/quoting.md explains.
    """
    if doc.format == "xml":
        text = doc_value(doc, path)
        if declared in ("int", "float") and isinstance(text, str) and _XML_LEADING_ZERO.match(text):
            _leading_zero(doc, path, text.strip(), diags)
        return
    if not doc.yaml11:
        return
    n = len(path)
    for p, raw in doc.yaml11.items():
        if p[:n] != path:
            continue
        if raw in YAML11_BOOLS:
            if declared in ("str", "bool", "int", "float"):
                continue  # a declared string is one; any other scalar type is already an error
            word = "true" if YAML11_BOOLS[raw] else "false"
            diags.warning("W210", f"`{raw}` is the string '{raw}' here, not the boolean {word} "
                          "(hfsmc reads YAML 1.2): a non-empty string is true in a condition",
                          doc.span(p), f"write `{word}` for a boolean, or '{raw}' in quotes "
                          "to keep the string")
        else:
            _leading_zero(doc, p, raw, diags)


def _leading_zero(doc: Document, path: PathKey, raw: str, diags: Diagnostics) -> None:
    digits = raw.lstrip("+-")
    sign = "-" if raw.startswith("-") else ""
    decimal = f"{sign}{int(digits, 10)}"
    if set(digits) <= set("01234567"):
        if int(digits, 8) == int(digits, 10):
            return  # `07`: seven either way
        octal = f"{sign}{int(digits, 8)}"
        diags.warning("W211", f"`{raw}` is {decimal} here, not octal {octal} as YAML 1.1 and C "
                      "read it", doc.span(path), f"write `{decimal}`, or `{sign}0o{digits.lstrip('0')}`"
                      f" for octal {octal}")
    else:
        diags.warning("W211", f"`{raw}` has a leading zero: it is {decimal}", doc.span(path),
                      f"write `{decimal}`")


def doc_value(doc: Document, path: PathKey) -> Any:
    """The document's value at ``path`` (None when absent)."""
    node: Any = doc.data
    for k in path:
        if isinstance(node, dict) and isinstance(k, str):
            node = node.get(k)
        elif isinstance(node, list) and isinstance(k, int) and 0 <= k < len(node):
            node = node[k]
        else:
            return None
    return node


def _from_text(text: str, vtype: str) -> Value:
    """Values written as XML attribute text."""
    try:
        if vtype == "str":
            return text
        if vtype == "bool":
            return {"true": True, "false": False}.get(text.strip().lower())
        if vtype == "int":
            return int(text)
        if vtype == "float":
            return float(text)
        value = ast.literal_eval(text)
        return _freeze(value) if isinstance(value, _PY_TYPES[vtype]) else None
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return None


def _cpp_text(value: Any) -> str:
    """A C++ initializer written as a YAML literal, as C++ text."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "{" + ", ".join(_cpp_text(v) for v in value) + "}"
    if isinstance(value, dict):
        return "{" + ", ".join(_cpp_text(v) for v in value.values()) + "}"
    return str(value)
