"""A scenario's action servers and service responses (docs/testing.md, "Action servers
and service responses"): checked against the model's ros2 interfaces, then written into
the playback script as ``servers`` entries that the component's fake answers with
(templates/python/hfsmc_ros2_servers.py).

Under a ros2 interface, an entry names an action or a service of it:

``navigate: {accept: true, feedback: [{after: 0s, fields: {...}}, ...], after: 2s,
end: succeeded, result: {...}}`` and ``reset: {response: {...}, after: 100ms}``.
"""

from __future__ import annotations

import itertools
from typing import Any

from hfsmc.durations import parse_us
from hfsmc.errors import Diagnostics
from hfsmc.ir import Ros2Rpc
from hfsmc.scenario_ros2 import Topics, Written, b64

ACTION_KEYS = ("accept", "feedback", "after", "end", "result")
SERVICE_KEYS = ("response", "after")
ENDS = ("succeeded", "aborted")


def rpc(topics: Topics, iface: str, name: str) -> tuple[str, Ros2Rpc] | None:
    """("action" | "service", its declaration) of ``name`` in ``iface``; None otherwise."""
    s = topics.interfaces[iface].ros2
    assert s is not None
    for kind, table in (("action", s.actions), ("service", s.services)):
        for r in table:
            if r.name == name:
                return kind, r
    return None


def check_server(topics: Topics, iface: str, field: str, w: Any, diags: Diagnostics
                 ) -> dict[str, Any] | None:
    """The server an entry scripts for the action or service ``field`` (as the playback
    writes it, messages in CDR), or None with diagnostics."""
    kind, r = rpc(topics, iface, field) or (None, None)
    assert kind is not None and r is not None
    if not isinstance(w, Written):  # a scalar is no server (scenario.py says so: E190)
        return None
    if not isinstance(w.value, dict):
        diags.error("E191", f"`{field}` is the {kind} {r.type}: a mapping of "
                    f"{', '.join(ACTION_KEYS if kind == 'action' else SERVICE_KEYS)}", w.span)
        return None
    keys = ACTION_KEYS if kind == "action" else SERVICE_KEYS
    before = len(diags.sorted())
    for k, v in w.value.items():
        if k not in keys:
            diags.error("E190", f"`{k}` is not a key of a scripted {kind} server",
                        v.key_span, f"it takes: {', '.join(keys)}")
    given: dict[str, Written] = w.value
    after = _duration(given.get("after"), diags)
    if kind == "service":
        response = _message(topics, given.get("response"), f"{r.type}_Response", diags)
        return None if len(diags.sorted()) > before else {"response": response,
                                                          "after_us": after or 0}
    accept = given.get("accept")
    if accept is not None and not isinstance(accept.value, bool):
        diags.error("E191", "`accept` is true or false", accept.span)
    end = given.get("end")
    if end is not None and end.value not in ENDS:
        diags.error("E193", f"`end` is one of {', '.join(ENDS)} (a cancel from the model "
                    "ends a goal canceled)", end.span)
    feedback = []
    for item in _feedback_items(given.get("feedback"), diags):
        at = _duration(item.value.get("after"), diags) or 0
        feedback.append([at, _message(topics, item.value.get("fields"),
                                      f"{r.type}_Feedback", diags)])
    result = _message(topics, given.get("result"), f"{r.type}_Result", diags) \
        if "result" in given else None
    if len(diags.sorted()) > before:
        return None
    return {"accept": True if accept is None else accept.value, "feedback": feedback,
            "after_us": after, "end": "succeeded" if end is None else end.value,
            "result": result}


def _feedback_items(w: Written | None, diags: Diagnostics) -> list[Written]:
    """`feedback`: one message's fields (sent from the start), or a list of
    ``{after: DURATION, fields: {...}}``."""
    if w is None:
        return []
    if isinstance(w.value, dict) and set(w.value) - {"after", "fields"}:
        return [Written({"fields": w}, w.span, w.key_span)]
    items = w.value if isinstance(w.value, list) else [w]
    out = []
    for item in items:
        if not isinstance(item.value, dict) or set(item.value) - {"after", "fields"}:
            diags.error("E191", "a feedback item is `{after: DURATION, fields: {...}}`",
                        item.span)
            continue
        out.append(item)
    return out


def _duration(w: Written | None, diags: Diagnostics) -> int | None:
    if w is None:
        return None
    us = parse_us(w.value) if isinstance(w.value, str) else None
    if us is None:
        diags.error("E193", f"`{w.value}` is not a duration: write 500ms, 2s", w.span)
    return us


def _message(topics: Topics, w: Written | None, type_name: str, diags: Diagnostics
             ) -> str | None:
    """A message by its fields (None: the type's defaults), as CDR in base64."""
    if w is None:
        return None
    if not isinstance(w.value, dict):
        diags.error("E191", f"a {type_name} is a mapping of its fields", w.span)
        return None
    before = len(diags.sorted())
    msg = topics.build(w, type_name, diags)
    if msg is None or len(diags.sorted()) > before:  # a field that does not fit: said
        return None
    return b64(topics.cdr(msg, type_name))


def server_rows(entries: Any, until_us: int, topics: Topics) -> list[dict[str, Any]]:
    """The playback entries that say which server holds, per action and service, from
    when: the entry that started last holds (a span gives way at its end to what held
    before; none: no server)."""
    sources: dict[tuple[str, str], list[tuple[int, Any, Any]]] = {}
    for order, e in enumerate(entries):
        if e.interface not in topics.interfaces:
            continue
        for s in e.settings:
            if rpc(topics, e.interface, s.field) is not None:
                sources.setdefault((e.interface, s.field), []).append((order, e, s))
    rows: list[dict[str, Any]] = []
    for (iface, name), srcs in sources.items():
        points = sorted({0, *(e.start_us for _, e, _ in srcs),
                         *(e.end_us for _, e, _ in srcs if e.end_us is not None)})
        held: Any = "none yet"
        for a, _ in itertools.pairwise([p for p in points if p <= until_us] + [until_us + 1]):
            live = [x for x in srcs if x[1].start_us <= a and (x[1].end_us is None
                                                              or a < x[1].end_us)]
            s = max(live, key=lambda x: (x[1].start_us, x[0]))[2] if live else None
            if s is held:
                continue
            held = s
            server = None if s is None else check_server(topics, iface, name, s.value,
                                                         Diagnostics())
            rows.append({"t": a, "kind": "snapshot", "interface": iface,
                         "values": {"servers": {name: server}}})
    return rows
