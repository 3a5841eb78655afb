"""A readable text dump of the IR (``hfsmc check --dump-ir``), used by golden tests."""

from __future__ import annotations

from pathlib import Path

from hfsmc.durations import format_us
from hfsmc.errors import Span
from hfsmc.ir import Automaton, Code, Model, State, Transition


def _at(span: Span) -> str:
    return f"@{span.line}:{span.col}"


def _code(label: str, code: Code | None, indent: str) -> list[str]:
    if code is None:
        return []
    lines = code.text.rstrip("\n").split("\n")
    if len(lines) == 1:
        return [f"{indent}{label}: {lines[0]!r} {_at(code.span)}"]
    return [f"{indent}{label}: {_at(code.span)}"] + [f"{indent}  | {ln}" for ln in lines]


def dump(model: Model) -> str:
    out = [f"model {model.name} ({model.language}) from {Path(model.file).name}"]
    if model.description:
        out.append(f"  description: {model.description!r}")
    for imp in model.imports:
        out.append(f"  import {imp.text!r} {_at(imp.span)}")
    for itf in model.interfaces:
        opts = "".join(f" {k}={v!r}" for k, v in itf.options)
        if itf.ros2 is None:
            out.append(f"  interface {itf.name}: {itf.type} url={itf.url!r}{opts} {_at(itf.span)}")
            continue
        r = itf.ros2
        out.append(f"  interface {itf.name}: ros2 node={r.node!r} namespace={r.namespace!r} "
                   f"domain={r.domain!r} distro={r.distro_or_default}"
                   f"{' introspection' if r.introspection else ''} {_at(itf.span)}")
        for kind, topics in (("subscribe", r.subscribe), ("publish", r.publish)):
            for t in topics:
                out.append(f"    {kind} {t.name}: topic={t.topic!r} type={t.type} "
                           f"qos={t.qos!r} {_at(t.span)}")
        for m in r.messages:
            out.append(f"    message {m.written!r} {_at(m.span)}")
        for kind, rpcs in (("action", r.actions), ("service", r.services)):
            for x in rpcs:
                out.append(f"    {kind} {x.name}: name={x.ros_name!r} type={x.type} "
                           f"timeout_us={x.timeout_us!r} {_at(x.span)}")
    for p in model.parameters:
        out.append(f"  parameter {p.name}: {p.type} = {p.default!r} {_at(p.span)}")
    for v in model.variables:
        out.append(f"  variable {v.name}: {v.type} = {v.init!r} {_at(v.span)}")
    out += _code("functions", model.functions, "  ")
    out += _code("on_shutdown", model.on_shutdown, "  ")
    if model.on_interrupt:
        timeout = format_us(model.interrupt_timeout_us) if model.interrupt_timeout_us else "none"
        out.append(f"  on_interrupt {model.on_interrupt} timeout {timeout}")
    if model.time_limit_us is not None:
        out.append(f"  time_limit {format_us(model.time_limit_us)}")
    out += _automaton(model.root, "  ")
    return "\n".join(out) + "\n"


def _automaton(auto: Automaton, indent: str) -> list[str]:
    kind = f"region {auto.region} of" if auto.region is not None else "automaton"
    head = f"{indent}{kind} {auto.owner or '(root)'} period {auto.period_ms}ms"
    head += "" if auto.period_written else " (inherited)"
    head += f" initial {auto.initial}" + (" history" if auto.history else "")
    out = [head]
    if auto.instance is not None:  # its states' positions (@line:col) are in the used file
        inst = auto.instance
        out.append(f"{indent}  use {inst.written!r} = {inst.file} {_at(inst.span)}")
        for b in inst.bindings:
            bound = f"${b.source}" if b.kind == "parameter" and b.source else \
                (b.source if b.kind == "interface" else repr(b.value))
            out.append(f"{indent}    with {b.kind} {b.name} = {bound} {_at(b.span)}")
    for s in auto.states:
        out += _state(s, indent + "  ")
    return out


def _state(s: State, indent: str) -> list[str]:
    flags = " final" if s.final else ""
    out = [f"{indent}state {s.path}{flags} {_at(s.span)}"]
    inner = indent + "  "
    for kind in ("entry", "during", "exit"):
        out += _code(kind, getattr(s, kind), inner)
    for t in s.transitions:
        out += _transition(t, inner)
    for a in s.automata:
        out += _automaton(a, inner)
    return out


def _transition(t: Transition, indent: str) -> list[str]:
    label = f" [{t.name}]" if t.name else ""
    after = f" after {format_us(t.after_us)}" if t.after_us is not None else ""
    out = [f"{indent}transition {t.index} -> {t.target}{label}{after} {_at(t.span)}"]
    out += _code("when", t.when, indent + "  ")
    out += _code("do", t.do, indent + "  ")
    return out
