"""The IR as plain YAML-shaped data (the inverse of the builder), for writers."""

from __future__ import annotations

import json
from typing import Any

from hfsmc.durations import format_us
from hfsmc.ir import (
    SERVICE_TIMEOUT_US,
    Automaton,
    Binding,
    Code,
    DictValue,
    Model,
    Ros2Settings,
    State,
    Transition,
    Value,
)


def thaw(v: Value) -> Any:
    """A frozen literal back to lists and dicts."""
    if isinstance(v, DictValue):
        return {k: thaw(x) for k, x in v.items}
    if isinstance(v, tuple):
        return [thaw(x) for x in v]
    return v


def _code(c: Code | None) -> str | None:
    return None if c is None else c.text


def model_to_data(model: Model) -> dict[str, Any]:
    d: dict[str, Any] = {"hfsm": 1, "name": model.name, "language": model.language}
    if model.description is not None:
        d["description"] = model.description
    if model.imports:
        d["imports"] = [i.text for i in model.imports]
    if model.interfaces:
        d["interfaces"] = {
            i.name: {"type": i.type, **({"url": i.url} if i.url is not None else {}),
                     **({"python": i.python.written} if i.python is not None else {}),
                     **({"cpp": i.cpp.written} if i.cpp is not None else {}),
                     **({"options": dict(i.options)} if i.options else {}),
                     **(ros2_data(i.ros2) if i.ros2 is not None else {})}
            for i in model.interfaces
        }
    if model.parameters:
        d["parameters"] = {p.name: {"type": p.type, "default": thaw(p.default),
                                    **({"description": p.description} if p.description is not None
                                       else {})}
                           for p in model.parameters}
    if model.variables:
        d["variables"] = {
            v.name: {"type": v.type, "init": thaw(v.init)} if v.typed or v.type == "dict" else thaw(v.init)
            for v in model.variables
        }
    if model.functions is not None:
        d["functions"] = model.functions.text
    if model.on_shutdown is not None:
        d["on_shutdown"] = model.on_shutdown.text
    if model.on_interrupt is not None:
        d["on_interrupt"] = model.on_interrupt
    if model.interrupt_timeout_us is not None:
        d["interrupt_timeout"] = format_us(model.interrupt_timeout_us)
    if model.time_limit_us is not None:
        d["time_limit"] = format_us(model.time_limit_us)
    d.update(_automaton(model.root))
    return d


def _automaton(a: Automaton) -> dict[str, Any]:
    d: dict[str, Any] = {}
    if a.period_written:
        d["period"] = format_us(a.period_ms * 1000)
    d["initial"] = a.initial
    if a.history:
        d["history"] = True
    d["states"] = {s.name: _state(s) for s in a.states}
    return d


def _state(s: State) -> dict[str, Any]:
    d: dict[str, Any] = {}
    for kind in ("entry", "during", "exit"):
        text = _code(getattr(s, kind))
        if text is not None:
            d[kind] = text
    if s.final:
        d["final"] = True
    instance = s.automaton.instance if s.automaton is not None else None
    if instance is not None:  # as written: the used file is not copied in
        d["use"] = instance.written
        if instance.bindings:
            d["with"] = {b.name: binding_value(b) for b in instance.bindings}
    first = written_first(s) or instance is not None
    if s.transitions and not first:
        d["transitions"] = [_transition(t) for t in s.transitions]
    if s.parallel:
        d["regions"] = {a.region: _automaton(a) for a in s.automata}
    elif s.automaton is not None and instance is None:
        d.update(_automaton(s.automaton))
    if first:
        d["transitions"] = [_transition(t) for t in s.transitions]
    return d


def binding_value(b: Binding) -> Any:
    """A `with` entry's value as written: `$NAME` for a parameter of the using model, the
    interface's name, or the literal (a string that starts with `$` written `$$`)."""
    if b.kind == "interface":
        return b.source
    if b.source is not None:
        return f"${b.source}"
    if isinstance(b.value, str) and b.value.startswith("$"):
        return f"${b.value}"
    return thaw(b.value)


def written_first(s: State) -> bool:
    """Whether the source has ``s``'s sub-automaton or regions before its transitions
    (both formats allow either order; the writers keep the user's)."""
    if not s.automata or not s.transitions:
        return False
    a, t = s.automata[0].span, s.transitions[0].span
    return a.file == t.file and (a.line, a.col) < (t.line, t.col)


def _transition(t: Transition) -> dict[str, Any]:
    d: dict[str, Any] = {}
    if t.name is not None:
        d["name"] = t.name
    d["to"] = t.target
    if t.when is not None:
        d["when"] = t.when.text
    if t.after_us is not None:
        d["after"] = format_us(t.after_us)
    if t.do is not None:
        d["do"] = t.do.text
    return d


def ros2_data(r: Ros2Settings) -> dict[str, Any]:
    """A ros2 interface's keys as the model writes them (those it leaves out, left out)."""
    d: dict[str, Any] = {}
    for key in ("node", "namespace", "domain", "distro"):
        value = getattr(r, key)
        if value is not None:
            d[key] = value
    for key, topics in (("subscribe", r.subscribe), ("publish", r.publish)):
        if topics:
            d[key] = {t.name: {"topic": t.topic, "type": t.type,
                               **({} if t.qos == "default" else
                                  {"qos": t.qos if isinstance(t.qos, str) else dict(t.qos)})}
                      for t in topics}
    if r.messages:
        d["messages"] = [m.written for m in r.messages]
    for key, rpcs in (("actions", r.actions), ("services", r.services)):
        if rpcs:
            d[key] = {x.name: {"name": x.ros_name, "type": x.type,
                               **({} if x.timeout_us is None
                                  else {"timeout": format_us(x.timeout_us)})}
                      for x in rpcs}
    if r.introspection is not None:
        d["introspection"] = r.introspection
    return d


def ros2_config(model_name: str, r: Ros2Settings) -> dict[str, Any]:
    """A ros2 interface as NAME.yaml gives it to the component: every key, defaults filled
    in (the domain stays null: $ROS_DOMAIN_ID, else 0, at start)."""
    topics = {key: {t.name: {"topic": t.topic, "type": t.type,
                             "qos": t.qos if isinstance(t.qos, str) else dict(t.qos)}
                    for t in ts}
              for key, ts in (("subscribe", r.subscribe), ("publish", r.publish))}
    rpcs = {key: {x.name: {"name": x.ros_name, "type": x.type,
                           "timeout": _timeout_s(x.timeout_us, key)} for x in xs}
            for key, xs in (("actions", r.actions), ("services", r.services)) if xs}
    return {"type": "ros2", "node": r.node or model_name, "namespace": r.namespace or "/",
            "domain": r.domain, "distro": r.distro_or_default, **topics, **rpcs,
            **({"introspection": True} if r.introspection else {})}


def _timeout_s(us: int | None, key: str) -> float | None:
    """A goal's or a call's time limit in seconds (services: 10 s when none is given)."""
    if us is None:
        return SERVICE_TIMEOUT_US / 1e6 if key == "services" else None
    return us / 1e6


def component_config(model: Model) -> str:
    """The body of a component's NAME.yaml: parameters and interfaces, JSON-syntax YAML."""
    data = {
        "parameters": {p.name: thaw(p.default) for p in model.parameters},
        "interfaces": {i.name: ros2_config(model.name, i.ros2) if i.ros2 is not None else
                       {"type": i.kind, "url": i.url,
                        **({"options": dict(i.options)} if i.options else {})}
                       for i in model.interfaces},
    }
    return json.dumps(data, indent=2, ensure_ascii=True)
