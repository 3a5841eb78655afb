"""New XML text for a model's elements, in the style of the file they go into: its
indentation step, its attribute quote, CDATA or entities for code (SPEC 8.1).

The values are the YAML form's (a state's body as a mapping: `entry`, `transitions`,
`states`, ...), so that a state copied from a YAML model pastes into an XML one and the
operations of :class:`hfsmc.edit.xml_ops.XmlOps` take the same arguments as
:class:`hfsmc.edit.yaml_ops.YamlOps`'."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from hfsmc.edit.text import EditError
from hfsmc.frontend.xmlsource import clean_text

STATE_ATTRS = ("final", "use")
AUTOMATON_ATTRS = ("period", "initial", "history")
ROOT_AUTOMATON_ATTRS = (*AUTOMATON_ATTRS, "on_interrupt", "interrupt_timeout", "time_limit")
STATE_TEXTS = ("description", "entry", "during", "exit")


def value_text(value: Any) -> str:
    """A scalar as an attribute's text (`true`, `2.5`, `5s`)."""
    if value is True or value is False:
        return "true" if value else "false"
    if isinstance(value, (dict, list)):
        return json.dumps(value)
    return str(value)


@dataclass(frozen=True)
class Style:
    """How the file writes its elements."""

    step: str = "  "  # one indentation level
    quote: str = '"'
    cdata: bool = False  # code holding `<` or `&` goes in CDATA (the file does so)
    nl: str = "\n"

    def attr(self, name: str, value: Any) -> str:
        v = value_text(value).replace("&", "&amp;").replace("<", "&lt;").replace("\n", "&#10;")
        v = v.replace(self.quote, "&quot;" if self.quote == '"' else "&apos;")
        return f" {name}={self.quote}{v}{self.quote}"

    def attrs(self, pairs: list[tuple[str, Any]]) -> str:
        return "".join(self.attr(k, v) for k, v in pairs if v is not None)

    def content(self, text: str, pad: str) -> tuple[str, bool]:
        """An element's content for ``text`` at indentation ``pad`` (the element's), and
        whether it must be read verbatim (`verbatim="true"`)."""
        raw = text
        if "\n" in text:
            body = text[:-1] if text.endswith("\n") else text
            inner = pad + self.step
            raw = "\n" + "\n".join(inner + ln if ln.strip() else "" for ln in body.split("\n")) + \
                ("\n" + pad if text.endswith("\n") else "")
        verbatim = clean_text(raw)[0] != text
        if verbatim:
            raw = text
        return self.escape(raw).replace("\n", self.nl), verbatim

    def escape(self, raw: str) -> str:
        if self.cdata and ("<" in raw or "&" in raw) and "]]>" not in raw and "\r" not in raw:
            return "<![CDATA[" + raw + "]]>"
        return raw.replace("&", "&amp;").replace("<", "&lt;").replace("]]>", "]]&gt;")

    def text(self, tag: str, text: str, pad: str) -> str:
        """``<tag>text</tag>`` at ``pad`` (no final line break), read back as ``text``."""
        body, verbatim = self.content(str(text), pad)
        head = f"{pad}<{tag}{self.attr('verbatim', 'true') if verbatim else ''}"
        return f"{head}/>" if not body else f"{head}>{body}</{tag}>"

    def lines(self, parts: list[str]) -> str:
        return self.nl.join(p for p in parts if p)

    # ----- elements of the model

    def state(self, name: str, body: Any, pad: str) -> str:
        """A `<state>` from a state's YAML body (a mapping; None for an empty state)."""
        body = body if isinstance(body, dict) else {}
        known = {*STATE_ATTRS, *STATE_TEXTS, *AUTOMATON_ATTRS, "with", "transitions", "states",
                 "regions"}
        unknown = sorted(set(body) - known)
        if unknown:
            raise EditError(f"a state has no `{unknown[0]}` in XML")
        head = f"{pad}<state{self.attr('name', name)}{self.attrs([(k, body.get(k)) for k in STATE_ATTRS])}"
        inner = pad + self.step
        parts = [self.text(k, body[k], inner) for k in STATE_TEXTS if body.get(k) is not None]
        for k, v in (body.get("with") or {}).items():
            parts.append(f"{inner}<with{self.attr('name', k)}{self.attr('value', v)}/>")
        for t in body.get("transitions") or []:
            parts.append(self.transition(t, inner))
        if body.get("states") is not None or any(body.get(k) is not None for k in AUTOMATON_ATTRS):
            parts.append(self.automaton("automaton", [], body, inner))
        for rname, rbody in (body.get("regions") or {}).items():
            parts.append(self.automaton("region", [("name", rname)], rbody or {}, inner))
        if not parts:
            return head + "/>"
        return self.lines([head + ">", *parts, f"{pad}</state>"])

    def automaton(self, tag: str, first: list[tuple[str, Any]], body: dict[str, Any], pad: str) -> str:
        states = body.get("states") or {}
        initial = body.get("initial", next(iter(states), None))
        attrs = self.attrs([*first, ("period", body.get("period")), ("initial", initial),
                            ("history", body.get("history"))])
        parts = [self.text("description", body["description"], pad + self.step)] \
            if tag == "region" and body.get("description") is not None else []
        parts += [self.state(str(n), b, pad + self.step) for n, b in states.items()]
        if not parts:
            return f"{pad}<{tag}{attrs}/>"
        return self.lines([f"{pad}<{tag}{attrs}>", *parts, f"{pad}</{tag}>"])

    def transition(self, t: Any, pad: str) -> str:
        if not isinstance(t, dict):
            raise EditError("a transition is a mapping (`to`, `when`, `after`, `do`, `name`)")
        unknown = sorted(set(t) - {"name", "to", "after", "when", "do"})
        if unknown:
            raise EditError(f"a transition has no `{unknown[0]}`")
        head = f"{pad}<transition{self.attrs([(k, t.get(k)) for k in ('name', 'to', 'after')])}"
        parts = [self.text(k, t[k], pad + self.step) for k in ("when", "do") if t.get(k) is not None]
        if not parts:
            return head + "/>"
        return self.lines([head + ">", *parts, f"{pad}</transition>"])

    def declaration(self, kind: str, name: str, spec: Any, pad: str) -> str:
        """A `<parameter>`, `<variable>` or `<interface>` from its YAML spec."""
        if not isinstance(spec, dict):  # a variable written `x: 0.0`: its type from the value
            t = {bool: "bool", int: "int", float: "float", str: "str", list: "list",
                 dict: "dict"}.get(type(spec), "str")
            spec = {"type": t, "init": spec}
        options = spec.get("options") or {}
        attrs = [("name", name), *((k, v) for k, v in spec.items() if k != "options")]
        head = f"{pad}<{kind}{self.attrs(attrs)}"
        if not options:
            return head + "/>"
        parts = [f"{pad}{self.step}<option{self.attr('name', k)}{self.attr('value', v)}/>"
                 for k, v in options.items()]
        return self.lines([head + ">", *parts, f"{pad}</{kind}>"])
