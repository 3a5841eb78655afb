"""What a viewer of an hfsmc component knows, and the plain-line view of it.

Copied beside every generated Python component, and imported by ``hfsmc
view``; standard library only.  ``ViewState`` is the one model fed by the
component's observer calls, by the monitor protocol and by trace replay;
``PlainLines`` prints it without a terminal (one line per transition).
``hfsmc_view`` draws it with rich.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from typing import Any

RECENT = 8  # transitions and log lines kept for the view
EVENTS = ("start", "enter", "exit", "fire", "log", "error", "interrupt", "stop")
# Control characters in names or messages could drive the terminal: shown as "?".
_CONTROL = {c: "?" for c in [*range(32), 127]}

Item = tuple[str, Any]  # ("structure" | "record" | "sample" | "snapshot" | "advance" | ..., payload)


def clean(text: object) -> str:
    """``text`` as a string that is safe to print on a terminal."""
    return str(text).translate(_CONTROL)


SIGNIFICANT = 6  # digits of a float the live view shows (the monitor keeps every digit)


def readable(value: str) -> str:
    """A value's repr with each long float cut to SIGNIFICANT digits, for the live view:
    ``0.30000000000000004`` reads ``0.3``, ``[1.2345678, 'x1.2345678']`` reads
    ``[1.23457, 'x1.2345678']`` (quoted text and names are left alone). The C++
    view (viewstate.hpp) does the same, character for character."""
    out: list[str] = []
    k, n = 0, len(value)
    while k < n:
        ch = value[k]
        if ch in "'\"":  # a quoted string, as repr writes it (backslash escapes)
            j = k + 1
            while j < n and value[j] != ch:
                j += 2 if value[j] == "\\" else 1
            out.append(value[k:j + 1])
            k = j + 1
        elif ch in _DIGITS and not (k and (_word(value[k - 1]) or value[k - 1] == ".")):
            j = k
            while j < n and value[j] in _DIGITS:
                j += 1
            if j + 1 < n and value[j] == "." and value[j + 1] in _DIGITS:
                j += 1
                while j < n and value[j] in _DIGITS:
                    j += 1
            if j < n and value[j] in "eE":
                e = j + 1 + (j + 1 < n and value[j + 1] in "+-")
                if e < n and value[e] in _DIGITS:
                    j = e
                    while j < n and value[j] in _DIGITS:
                        j += 1
            out.append(_short_float(value[k:j]))
            k = j
        elif _word(ch):  # a name (which may hold digits): as it is
            j = k
            while j < n and _word(value[j]):
                j += 1
            out.append(value[k:j])
            k = j
        else:
            out.append(ch)
            k += 1
    return "".join(out)


_DIGITS = "0123456789"


def _word(ch: str) -> bool:
    """A character of a name: ASCII letters, digits, `_`, and anything beyond ASCII."""
    return not ch.isascii() or ch.isalnum() or ch == "_"


def _short_float(token: str) -> str:
    if "." not in token and "e" not in token.lower():
        return token  # an integer: every digit counts
    mantissa = token.lower().partition("e")[0].replace(".", "").lstrip("0")
    if len(mantissa) <= SIGNIFICANT:
        return token
    text = f"{float(token):.{SIGNIFICANT}g}"
    return text if any(c in text for c in ".einf") else text + ".0"


def check_record(rec: object) -> str | None:
    """Why ``rec`` is not a trace record (docs/semantics.md §13), or None when it is one."""
    if not isinstance(rec, dict):
        return "not a JSON object"
    t = rec.get("t")
    if not isinstance(t, int) or isinstance(t, bool) or t < 0:
        return "`t` is not a whole number of milliseconds"
    ev = rec.get("ev")
    if not isinstance(ev, str):
        return "`ev` is missing"
    needs = {"start": ("name",), "enter": ("state",), "exit": ("state",), "fire": ("from", "to"),
             "log": ("state", "msg"), "error": ("state", "snippet"), "interrupt": ("reason", "to"),
             "stop": ("reason",)}.get(ev, ())
    for key in needs:
        if not isinstance(rec.get(key), str):
            return f"`{ev}` record without a string `{key}`"
    if ev == "fire" and (not isinstance(rec.get("index"), int) or isinstance(rec.get("index"), bool)):
        return "`fire` record without an integer `index`"
    return None


def infer_structure(records: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """A structure (as the runtime gives it) guessed from the paths a trace names.

    A path segment that is never entered itself, but whose descendants are, is a
    region (``Mission/Watch`` of ``Mission/Watch/Ok``): every state has an ``enter``
    record, a region none (docs/semantics.md §13). Its period is not known."""
    view = ViewState()
    named: set[str] = set()
    for rec in records:
        if rec.get("ev") == "start" and not view.name:
            view.name = str(rec.get("name", ""))
        for key in ("state", "from", "to"):
            path = rec.get(key)
            if rec.get("ev") in ("enter", "exit", "fire") and isinstance(path, str) and path:
                view.learn(path)
                named.add(path)
    regions = [p for p in view.paths() if p not in named and "/" in p and p.rpartition("/")[0] in named]
    automata = [{"owner": r.rpartition("/")[0], "region": r.rpartition("/")[2],
                 "initial": view.children[r][0].rpartition("/")[2], "history": False}
                for r in regions if view.children[r]]
    states = [{"path": p, "final": False, "composite": bool(view.children[p])}
              for p in view.paths() if p not in regions]
    return {"name": view.name, "automata": automata, "states": states, "transitions": [],
            "variables": [], "parameters": {}}


class ViewState:
    """What a viewer knows about a component: its tree, active states, recent events."""

    def __init__(self, structure: dict[str, Any] | None = None) -> None:
        self.name = ""
        self.children: dict[str, list[str]] = {"": []}  # every known path -> child paths
        # Paths of regions (``Mission/Watch``): nodes of the tree that are no states; the
        # children of a parallel state are its regions, in the order written.
        self.regions: set[str] = set()
        self.final: set[str] = set()
        # Path of a sub-automaton (its owner's, "" for the root; OWNER/REGION for a
        # region) -> its period; ``history``: those that resume their last state.
        self.periods: dict[str, int] = {}
        self.history: set[str] = set()
        # A state whose sub-automaton is used from another file -> that file, as written.
        self.uses: dict[str, str] = {}
        self.transition_names: dict[tuple[str, int], str] = {}
        self.variable_names: list[str] = []
        self.parameters: dict[str, str] = {}
        self.values: dict[str, str] = {}
        self.active: dict[str, int] = {}  # active path -> entry time (ms), outermost first
        self.transitions: deque[dict[str, Any]] = deque(maxlen=RECENT)
        self.logs: deque[dict[str, Any]] = deque(maxlen=RECENT)
        self.t_ms = 0
        self.overruns = 0
        self.sim_rate: float | None = None  # --clock sim: simulated s per real s; else None
        self.started = False
        self.interrupt: dict[str, Any] | None = None
        self.stop_reason: str | None = None
        self.stopped_in: dict[str, int] = {}  # the states the stop exited
        self.note: str | None = None  # "disconnected", "replayed ...": shown with the status
        self.ros2: dict[str, dict[str, Any]] = {}  # a ros2 interface's latest ``ros2`` message
        self.drivers: dict[str, dict[str, Any]] = {}  # a user driver's latest ``driver`` message
        self._exited: dict[str, int] = {}  # exits since the last enter, fire or interrupt
        if structure is not None:
            self.apply_structure(structure)

    # -- the tree -----------------------------------------------------------------------
    def learn(self, path: str) -> None:
        """Add ``path`` (and its ancestors) to the tree if it is new."""
        if path in self.children:
            return
        parent = path.rpartition("/")[0]
        self.learn(parent)
        self.children[parent].append(path)
        self.children[path] = []

    def paths(self, top: str = "") -> list[str]:
        """Every known path under ``top``, depth first, in model (or first seen) order."""
        out: list[str] = []
        stack = list(reversed(self.children.get(top, [])))
        while stack:
            p = stack.pop()
            out.append(p)
            stack.extend(reversed(self.children[p]))
        return out

    def innermost(self) -> str:
        """The deepest active state ("" when none is)."""
        return max(self.active, key=lambda p: p.count("/"), default="")

    def leaves(self, active: Iterable[str] | None = None) -> list[str]:
        """The innermost of the active states (or of ``active``), one per active region
        (one without regions), in model order."""
        paths = list(self.active if active is None else active)
        order = {p: i for i, p in enumerate(self.paths())}
        return sorted((p for p in paths if not any(q.startswith(p + "/") for q in paths)),
                      key=lambda p: order.get(p, len(order)))

    def owner(self, path: str) -> str:
        """The state that holds ``path``'s node: its parent, or the parallel state of a region."""
        parent = path.rpartition("/")[0]
        return parent.rpartition("/")[0] if parent in self.regions else parent

    def lit(self, path: str) -> bool:
        """Whether ``path`` is active (a region: whether its state is)."""
        return path in self.active or (path in self.regions and path.rpartition("/")[0] in self.active)

    # -- applying what the component says ------------------------------------------------
    def apply_structure(self, s: dict[str, Any]) -> None:
        """Take the component's structure (states in model order, automata, names)."""
        self.name = str(s.get("name") or self.name)
        for st in s.get("states", ()):
            self.learn(str(st["path"]))
            if st.get("final"):
                self.final.add(str(st["path"]))
        for a in s.get("automata", ()):
            where = str(a["owner"])
            if a.get("region"):
                where = f"{where}/{a['region']}"
                self.learn(where)
                self.regions.add(where)
            if a.get("period_ms") is not None:
                self.periods[where] = int(a["period_ms"])
            if a.get("history"):
                self.history.add(where)
            if a.get("use"):
                self.uses[where] = str(a["use"])
        for tr in s.get("transitions", ()):
            if tr.get("name"):
                self.transition_names[(str(tr["from"]), int(tr["index"]))] = str(tr["name"])
        self.variable_names = [str(v) for v in s.get("variables", ())]
        self.parameters = {str(k): str(v) for k, v in dict(s.get("parameters", {})).items()}

    def apply_record(self, rec: dict[str, Any]) -> None:
        """Apply one trace record (docs/semantics.md §13); unknown events only move the time."""
        ev, t = rec.get("ev"), int(rec.get("t", self.t_ms))
        if ev == "start":
            self.active.clear()
            self.transitions.clear()
            self.logs.clear()
            self._exited.clear()
            self.interrupt, self.stop_reason, self.stopped_in = None, None, {}
            self.started, self.t_ms = True, t
            self.name = str(rec.get("name") or self.name)
            return
        self.t_ms = max(self.t_ms, t)
        if ev == "enter":
            path = str(rec["state"])
            self.learn(path)
            self.active[path] = t
            self._exited.clear()
        elif ev == "exit":
            path = str(rec["state"])
            self._exited[path] = self.active.pop(path, t)
        elif ev == "fire":
            src, dst, index = str(rec["from"]), str(rec["to"]), int(rec["index"])
            self.learn(src)
            self.learn(dst)
            self.transitions.append({"t": t, "from": src, "to": dst, "index": index,
                                     "name": self.transition_names.get((src, index))})
            self._exited.clear()
        elif ev == "log":
            self.logs.append({"t": t, "state": str(rec["state"]), "msg": str(rec["msg"])})
        elif ev == "error":
            self.logs.append({"t": t, "state": str(rec["state"]), "error": str(rec["snippet"])})
        elif ev == "interrupt":
            self.interrupt = {"t": t, "reason": str(rec["reason"]), "to": str(rec["to"])}
            self._exited.clear()
        elif ev == "variables" and isinstance(rec.get("values"), dict):  # --trace-variables
            self.values.update({str(k): str(v) for k, v in rec["values"].items()})
        elif ev == "stop":
            self.stop_reason = str(rec["reason"])
            # Exits come innermost first: reversed, the stopped states are outermost first.
            self.stopped_in = dict(reversed(self._exited.items()))
            self.stopped_in.update(self.active)

    def apply_sample(self, t_ms: int, values: dict[str, str], overruns: int,
                     rate: float | None = None) -> None:
        """Take the variables and overrun count sampled at ``t_ms`` (and, on the
        simulator's clock, its rate: simulated seconds per real second)."""
        self.t_ms = max(self.t_ms, int(t_ms))
        self.values = {str(k): str(v) for k, v in values.items()}
        self.overruns = int(overruns)
        if rate is not None:
            self.sim_rate = float(rate)

    def advance(self, t_ms: int) -> None:
        """Move the clock on (replay between records); a stopped component's stays."""
        if self.stop_reason is None:
            self.t_ms = max(self.t_ms, int(t_ms))

    def snapshot(self) -> dict[str, Any]:
        """The current state as a monitor ``snapshot`` message (schemas/monitor.md)."""
        stop = None
        if self.stop_reason is not None:
            stop = {"reason": self.stop_reason,
                    "states": [{"state": p, "since": s} for p, s in self.stopped_in.items()]}
        return {"type": "snapshot", "t": self.t_ms, "started": self.started,
                "active": [{"state": p, "since": s} for p, s in self.active.items()],
                "variables": dict(self.values), "overruns": self.overruns,
                "transitions": list(self.transitions), "logs": list(self.logs),
                "interrupt": self.interrupt, "stop": stop}

    def apply_snapshot(self, snap: dict[str, Any]) -> None:
        """Take a monitor ``snapshot``: a late viewer knows at once what others do."""
        self.t_ms = int(snap["t"])
        self.started = bool(snap.get("started", True))
        self.active = {}
        for a in snap.get("active", ()):
            self.learn(str(a["state"]))
            self.active[str(a["state"])] = int(a["since"])
        self.values = {str(k): str(v) for k, v in dict(snap.get("variables", {})).items()}
        self.overruns = int(snap.get("overruns", 0))
        self.transitions = deque(
            ({"t": int(x["t"]), "from": str(x["from"]), "to": str(x["to"]),
              "index": int(x.get("index", 0)), "name": None if x.get("name") is None else str(x["name"])}
             for x in snap.get("transitions", ())), maxlen=RECENT)
        self.logs = deque(
            ({"t": int(x["t"]), "state": str(x["state"]),
              **({"error": str(x["error"])} if "error" in x else {"msg": str(x["msg"])})}
             for x in snap.get("logs", ())), maxlen=RECENT)
        i = snap.get("interrupt")
        self.interrupt = {"t": int(i["t"]), "reason": str(i["reason"]), "to": str(i["to"])} if i else None
        stop = snap.get("stop")
        self.stop_reason = str(stop["reason"]) if stop else None
        self.stopped_in = {str(a["state"]): int(a["since"]) for a in stop["states"]} if stop else {}

    def apply(self, kind: str, payload: Any) -> None:
        """Apply one queued item (see ``Item``); other kinds are not about the component."""
        if kind == "structure":
            self.apply_structure(payload)
        elif kind == "record":
            self.apply_record(payload)
        elif kind == "sample":
            self.apply_sample(*payload)
        elif kind == "snapshot":
            self.apply_snapshot(payload)
        elif kind == "advance":
            self.advance(payload)
        elif kind == "ros2":
            self.ros2[str(payload["name"])] = payload
        elif kind == "driver":
            self.drivers[str(payload["name"])] = payload


# -- plain lines ---------------------------------------------------------------------------
def _ts(t_ms: int) -> str:
    return f"{t_ms / 1000:7.3f}"


class PlainLines:
    """One line per transition, interrupt and stop: the view without a terminal.

    ``lines`` is called *before* the item is applied to the view, so that the
    start line names the initial states before any of them is left.
    """

    def __init__(self, focus: str | None = None) -> None:
        self.focus = (focus or "").strip("/")
        self._start: int | None = None  # start seen, its line not printed yet

    def _shown(self, path: str) -> bool:
        return not self.focus or path.startswith(self.focus + "/")

    def lines(self, view: ViewState, kind: str, payload: Any) -> list[str]:
        out: list[str] = []
        ev = payload.get("ev") if kind == "record" else None
        if self._start is not None and kind != "structure" and ev not in ("enter", "log", "error"):
            inner = ", ".join(view.leaves())
            out.append(f"{_ts(self._start)}  start {clean(view.name)}" + (f" in {clean(inner)}" if inner else ""))
            self._start = None
        if ev == "start":
            self._start = int(payload["t"])
        elif ev == "fire" and self._shown(str(payload["from"])):
            name = view.transition_names.get((str(payload["from"]), int(payload["index"])))
            out.append(f"{_ts(payload['t'])}  {clean(payload['from'])} -> {clean(payload['to'])}"
                       + (f"  ({clean(name)})" if name else ""))
        elif ev == "interrupt":
            out.append(f"{_ts(payload['t'])}  interrupt ({clean(payload['reason'])}) -> {clean(payload['to'])}")
        elif ev == "stop":
            out.append(f"{_ts(payload['t'])}  stop ({clean(payload['reason'])})")
        elif kind == "snapshot":
            out.append(_snapshot_line(view, payload))
        return out


def _snapshot_line(view: ViewState, snap: dict[str, Any]) -> str:
    if snap.get("stop"):
        return f"{_ts(snap['t'])}  stopped ({clean(snap['stop']['reason'])})"
    inner = ", ".join(view.leaves(str(a["state"]) for a in snap.get("active", ())))
    return f"{_ts(snap['t'])}  in {clean(inner)}" if inner else f"{_ts(snap['t'])}  not started"
