"""Sub-automata from other files: `use` and `with` (docs/model.md: use).

The IR builder hands every state that writes `use` to a :class:`UseLoader`.  The
loader builds and lowers each used file once per compile (its own names, its own
paths, its own diagnostics), then gives the using state a copy of the used root
sub-automaton whose paths continue the state's (``TakeOff/Climb``), with the
:class:`~hfsmc.ir.Instance` that says which file and what `with` binds.  The used
files' diagnostics join the using model's at the end (:meth:`UseLoader.finish`),
once per file, with a note saying where it is used from.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from hfsmc.errors import Diagnostic, Diagnostics, HfsmcError, Span, did_you_mean
from hfsmc.frontend import load, read_text, schema
from hfsmc.frontend.source import Document, PathKey
from hfsmc.ir import Automaton, Binding, Instance, Model, State, Value
from hfsmc.ir_builder import build_ir, coerce_literal, literal_traps
from hfsmc.lower import lower

# A used model runs inside the using component, which alone decides how it stops.
_COMPONENT_KEYS = ("on_interrupt", "interrupt_timeout", "time_limit", "on_shutdown")


@dataclass
class UsedFile:
    """One used file, built once per compile however often it is used."""

    path: str  # as hfsmc reads it: joined to the folder of the first file that uses it
    model: Model | None  # None when it could not be built
    diagnostics: list[Diagnostic]
    lines: list[str]
    sites: list[Span] = field(default_factory=list)  # every `use` of it


class UseLoader:
    """Builds the states that `use` another file, for one compile of one model file."""

    def __init__(self, main: str, texts: Mapping[str, str] | None = None) -> None:
        # With ``texts`` (a recording's sources, by normalised path), used files are looked
        # up there and the disk is never read: a recorded model is compiled as data.
        self.texts = texts
        self.files: dict[str, UsedFile] = {}  # by real path
        self.stack: list[tuple[str, str]] = [(self._real(main), main)]  # being built

    def _real(self, path: str) -> str:
        return os.path.realpath(path) if self.texts is None else os.path.normpath(path)

    @property
    def sources(self) -> dict[str, list[str]]:
        """The used files' lines, by the name their diagnostics give."""
        return {f.path: f.lines for f in self.files.values()}

    def finish(self, diags: Diagnostics) -> None:
        """Add every used file's diagnostics (once each) to the using model's, with where
        the file is used from."""
        for f in self.files.values():
            sites = ", ".join(str(s) for s in sorted(set(f.sites)))
            note = f"used from {sites}"
            diags.extend(replace(d, notes=(*d.notes, note)) for d in f.diagnostics)

    def __call__(self, doc: Document, diags: Diagnostics, node: dict[str, Any], path: PathKey,
                 spath: str, period_ms: int) -> Automaton | None:
        written = str(node["use"])
        site = doc.span((*path, "use"))
        used = self._file(os.path.join(os.path.dirname(doc.file), written), written, site, diags)
        if used is None or used.model is None:
            return None
        model = used.model
        language = doc.data.get("language", "python")
        if model.language != language:
            diags.error("E173", f"`{written}` is a {model.language} model, and this one is "
                        f"{language}: snippets of both run in one component", site)
            return None
        bindings = _bind(doc, diags, node, path, model, written)
        root = model.root
        period = root.period_ms if root.period_written else period_ms
        auto = _graft(root, spath, period)
        return replace(auto, instance=Instance(used.path, written, model, bindings, site))

    def _file(self, path: str, written: str, site: Span, diags: Diagnostics) -> UsedFile | None:
        real = self._real(path)
        for k, (seen, _) in enumerate(self.stack):
            if seen == real:
                chain = " -> ".join([shown for _, shown in self.stack[k:]] + [path])
                diags.error("E175", f"`use` cycle: {chain}", site,
                            "a file cannot use itself, even through others")
                return None
        used = self.files.get(real)
        if used is None:
            text = self._text(path, written, site, diags)
            if text is None:
                return None
            self.stack.append((real, path))
            try:
                used = self._build(path, text, written, site, diags)
            finally:
                self.stack.pop()
            if used is None:
                return None
            self.files[real] = used
        used.sites.append(site)
        return used

    def _text(self, path: str, written: str, site: Span, diags: Diagnostics) -> str | None:
        if self.texts is not None:
            text = self.texts.get(os.path.normpath(path))
            if text is None:
                diags.error("E170", f"used file `{written}` is not in the recording", site)
            return text
        if not os.path.exists(path):
            diags.error("E170", f"used file `{written}` does not exist (looked for {path})", site)
            return None
        try:
            return read_text(path)
        except HfsmcError as e:
            why = e.diagnostics[0].message if e.diagnostics else "cannot be read"
            diags.error("E171", f"used file `{written}` cannot be read: {why}", site)
            return None

    def _build(self, path: str, text: str, written: str, site: Span,
               diags: Diagnostics) -> UsedFile | None:
        own = Diagnostics()
        doc: Document | None = None
        model: Model | None = None
        try:
            doc = load(path, own, text)
            if doc.format not in ("yaml", "xml"):
                diags.error("E172", f"used file `{written}` is a legacy {doc.format} file, not an "
                            "hfsm model", site, f"convert it first: hfsmc convert {path} NEW.yaml")
                return None
            if not own.has_errors:
                schema.validate(doc, own)
            if not own.has_errors:
                model = lower(build_ir(doc, own, self), own)
        except HfsmcError as e:
            if any(d.code == "E005" for d in e.diagnostics):
                diags.error("E172", f"used file `{written}` is not an hfsm model",
                            site, e.diagnostics[0].message)
                return None
            own.extend(e.diagnostics)
        if doc is not None and isinstance(doc.data, dict):
            for key in _COMPONENT_KEYS:
                if key in doc.data:
                    own.error("E174", f"a used model has no `{key}`: the using component alone "
                              "decides how it stops", doc.key_span((key,)),
                              "move it to the model that uses this file")
        return UsedFile(path, model, own.sorted(), doc.lines if doc is not None else [])


def _graft(auto: Automaton, owner: str, period_ms: int) -> Automaton:
    """``auto`` (from a used model) with its states' paths under ``owner`` and the periods
    it does not write inherited from ``period_ms``, as any sub-automaton's are."""
    period = auto.period_ms if auto.period_written else period_ms
    prefix = owner if auto.region is None else f"{owner}/{auto.region}"
    states = tuple(_graft_state(s, prefix, period) for s in auto.states)
    return replace(auto, owner=owner, period_ms=period, states=states)


def _graft_state(state: State, parent: str, period_ms: int) -> State:
    path = f"{parent}/{state.name}"
    return replace(state, path=path,
                   automata=tuple(_graft(a, path, period_ms) for a in state.automata))


def _a(word: object) -> str:
    return f"an {word}" if str(word)[:1] in ("a", "e", "i", "o", "u") else f"a {word}"


def _bind(doc: Document, diags: Diagnostics, node: dict[str, Any], path: PathKey,
          model: Model, used: str) -> tuple[Binding, ...]:
    """What `with` binds, checked against the used model (``used``: as written) and the
    using one."""
    params = {p.name: p for p in model.parameters}
    ifaces = {i.name: i for i in model.interfaces}
    mine_params: dict[str, Any] = doc.data.get("parameters") or {}
    mine_ifaces: dict[str, Any] = doc.data.get("interfaces") or {}
    out: list[Binding] = []
    for name, value in (node.get("with") or {}).items():
        vpath: PathKey = (*path, "with", name)
        span = doc.span(vpath)
        if name in params:
            out.append(_bind_parameter(doc, diags, vpath, name, value, params[name].type,
                                       mine_params, used))
        elif name in ifaces:
            want = ifaces[name].type
            spec = mine_ifaces.get(value) if isinstance(value, str) else None
            if not isinstance(spec, dict):
                note = did_you_mean(str(value), mine_ifaces) if isinstance(value, str) else None
                diags.error("E181", f"`with` binds interface `{name}` of `{used}` to "
                            f"`{value}`, which is not an interface of this model", span,
                            *((note,) if note else (f"its interfaces: "
                                                    f"{', '.join(mine_ifaces) or 'none'}",)))
            elif spec.get("type") != want:
                diags.error("E182", f"interface `{name}` of `{used}` is {_a(want)} interface, "
                            f"and `{value}` is {_a(spec.get('type'))} one", span)
            out.append(Binding(name, "interface", None, str(value), span))
        else:
            note = did_you_mean(name, [*params, *ifaces])
            diags.error("E177", f"`with` names `{name}`, which is neither a parameter nor an "
                        f"interface of `{used}`", doc.key_span(vpath),
                        *((note,) if note else (f"it has: {', '.join([*params, *ifaces]) or 'none'}",)))
    bound = {b.name for b in out}
    site = doc.span((*path, "use"))
    for name, iface in ifaces.items():
        if name in bound:
            continue
        spec = mine_ifaces.get(name)
        if not isinstance(spec, dict):
            diags.error("E183", f"interface `{name}` of `{used}` is not bound, and this model "
                        f"has no interface `{name}`", site,
                        f"bind it to one of this model's {iface.type} interfaces: with: {{{name}: NAME}}")
        elif spec.get("type") != iface.type:
            diags.error("E183", f"interface `{name}` of `{used}` is not bound, and this "
                        f"model's `{name}` is {_a(spec.get('type'))} interface, not {_a(iface.type)} one",
                        site, f"bind it to a {iface.type} interface: with: {{{name}: NAME}}")
    return tuple(out)


def _bind_parameter(doc: Document, diags: Diagnostics, vpath: PathKey, name: str, value: Any,
                    vtype: str, mine: dict[str, Any], used: str) -> Binding:
    span = doc.span(vpath)
    if isinstance(value, str) and value.startswith("$") and not value.startswith("$$"):
        ref = value[1:]
        spec = mine.get(ref)
        if not isinstance(spec, dict):
            note = did_you_mean(ref, mine)
            diags.error("E179", f"`{value}` names no parameter of this model", span,
                        *((note,) if note else ()), "write `$$` for a literal `$`")
        elif spec.get("type") != vtype and not (vtype == "float" and spec.get("type") == "int"):
            diags.error("E180", f"parameter `{name}` of `{used}` is {_a(vtype)}, and `{ref}` is "
                        f"{_a(spec.get('type'))}", span)
        return Binding(name, "parameter", None, ref, span)
    if isinstance(value, str) and value.startswith("$$"):
        value = value[1:]
    literal: Value = coerce_literal(doc, diags, value, vtype, vpath, "E178")
    literal_traps(doc, vpath, vtype, diags)
    return Binding(name, "parameter", literal, None, span)
