"""The ``ros2`` interface fed from a playback (``hfsmc replay``, ``hfsmc test``): no DDS.

Copied beside a component with a ``ros2`` interface; ``hfsmc_playback`` makes it for
``--playback DIR``. It answers what the live node answers (it is a ``Ros2Queries``), from
the script's snapshot entries (schemas/recording.md, "Playback"):

``{"t":us,"kind":"snapshot","interface":"robot","values":{"subscriptions":{"scan":
{"count":3,"age":0.02,"publishers":1,"dropped":0,"cdr":"BASE64"}},"subscribers":
{"cmd_vel":1}}}``

Each subscription's fields are applied over what held before; ``cdr`` (a sample's CDR
bytes, base64, as recorded) is decoded once, at start, with the generated classes, so a
script whose bytes do not decode is refused before anything runs. In a scenario's script
(not ``recorded``) a field left out follows the samples: ``count`` grows by one per
sample, ``age`` is the time since the latest sample's entry, ``publishers`` is 1 from
the first sample on. A publish is a command: told to the playback (``commands.jsonl``)
with the publication's name and its CDR in base64, and sent nowhere.
"""

from __future__ import annotations

import base64
import binascii
import math
from typing import Any

if __package__:
    from . import hfsmc_ros2 as ros2
    from . import hfsmc_ros2_cdr as cdr
    from . import hfsmc_ros2_rpc as rpc
    from . import hfsmc_ros2_servers as servers
    from . import hfsmc_ros2_wire as wire
else:  # beside the generated component
    import hfsmc_ros2 as ros2  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_cdr as cdr  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_rpc as rpc  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_servers as servers  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_wire as wire  # type: ignore[import-not-found, no-redef]

_FIELDS = ("count", "age", "publishers", "dropped", "cdr")


class Ros2Fake(ros2.Ros2Queries):
    """The ros2 interface of a playback: its snapshot comes from the script."""

    def __init__(self, name: str, settings: dict[str, Any], playback: Any) -> None:
        self.name = name
        self.playback = playback
        self.lacks: Any = None  # what the script lacks at this instant (Playback.advance)
        self.quiet = False
        self.on_command: Any = None  # the playback's (hfsmc_interfaces.hook)
        self.on_publish: Any = None
        self.node = wire.validate_node_name(str(settings.get("node") or name))
        self.namespace = wire.validate_namespace(str(settings.get("namespace") or "/"))
        self._acts = ros2.Ros2Node._rpc_settings(self, settings.get("actions") or {})  # type: ignore[arg-type]
        self._srvs = ros2.Ros2Node._rpc_settings(self, settings.get("services") or {})  # type: ignore[arg-type]
        # what the script says of each goal and call (the latest, applied over before)
        self._goals: dict[str, dict[str, Any]] = {
            n: {"status": "none", "feedback": None, "result": None} for n in self._acts}
        self._calls: dict[str, dict[str, Any]] = {
            n: {"status": "none", "response": None} for n in self._srvs}
        self._goal_snap = {n: ("none", None, None) for n in self._acts}
        self._call_snap = {n: ("none", None) for n in self._srvs}
        self._servers = servers.Scripted(self._acts, self._srvs)  # a scenario's
        self._subs = ros2.Ros2Node._endpoints(self, settings.get("subscribe") or {})  # type: ignore[arg-type]
        self._pubs = ros2.Ros2Node._endpoints(self, settings.get("publish") or {})  # type: ignore[arg-type]
        ros2.Ros2Node._check_topics(self)  # type: ignore[arg-type]
        self._state: dict[str, dict[str, Any]] = {n: {"count": 0, "age": None, "publishers": None, "dropped": 0,
                           "msg": None, "cdr": None, "arrived": None} for n in self._subs}
        self._given_subscribers = dict.fromkeys(self._pubs, 0)
        self._snap = {n: (None, math.inf, 0, 0) for n in self._subs}
        self._snap_subscribers = dict(self._given_subscribers)

    def __repr__(self) -> str:
        return f"<ros2 {self.name} (playback)>"

    # -- the script ----------------------------------------------------------------------
    def convert(self, t_us: int, values: dict[str, Any], recorded: bool = False
                ) -> dict[str, Any]:
        """A script entry checked and decoded (at start): ValueError says what is wrong.
        ``recorded``: a recorded run's, whose topics the model may no longer have (they
        are left out: another model than the recorded one can be replayed)."""
        if not isinstance(values, dict):
            raise ValueError("`values` must be a mapping")
        known = ("subscriptions", "subscribers", "goals", "calls", *(() if recorded else
                                                                      ("servers",)))
        odd = [k for k in values if k not in known]
        if odd:
            raise ValueError(f"the ros2 interface `{self.name}` has no snapshot field "
                             f"`{odd[0]}` ({', '.join(known)})")
        subs: dict[str, dict[str, Any]] = {}
        for n, v in _mapping(values.get("subscriptions"), "subscriptions").items():
            if recorded and n not in self._subs:
                continue
            self._known(n, self._subs, "subscription")
            fields = _mapping(v, f"subscription `{n}`")
            bad = [k for k in fields if k not in _FIELDS]
            if bad:
                raise ValueError(f"subscription `{n}` has no field `{bad[0]}` "
                                 f"({', '.join(_FIELDS)})")
            out: dict[str, Any] = {}
            for k in ("count", "publishers", "dropped"):
                if k in fields:
                    out[k] = _count(fields[k], f"`{n}`'s {k}")
            if "age" in fields:
                out["age"] = _seconds(fields["age"], f"`{n}`'s age")
            if "cdr" in fields:
                out["msg"], out["cdr"] = self._decode(n, fields["cdr"])
                out["arrived"] = t_us
            subs[n] = out
        pubs: dict[str, int] = {}
        for n, k in _mapping(values.get("subscribers"), "subscribers").items():
            if recorded and n not in self._pubs:
                continue
            self._known(n, self._pubs, "publication")
            pubs[n] = _count(k, f"`{n}`'s subscribers")
        out = {"subscriptions": subs, "subscribers": pubs,
               **rpc.from_recorded(values, self._acts, self._srvs, recorded)}
        if "servers" in values:
            out["servers"] = servers.convert(values["servers"], self._acts, self._srvs)
        return out

    def _decode(self, n: str, text: Any) -> tuple[Any, bytes | None]:
        if text is None:
            return None, None
        if not isinstance(text, str):
            raise ValueError(f"`{n}`'s cdr must be base64 text")
        try:
            data = base64.b64decode(text, validate=True)
        except (binascii.Error, ValueError):
            raise ValueError(f"`{n}`'s cdr is not base64") from None
        cls = self._subs[n]["class"]
        try:
            return cdr.deserialize(cls, data), data
        except cdr.CdrError as e:
            raise ValueError(f"`{n}`'s sample is no {cls._TYPE}: {e}") from None

    def _known(self, n: str, table: dict[str, Any], what: str) -> None:
        if n not in table:
            raise ValueError(f"the ros2 interface `{self.name}` has no {what} `{n}` "
                             f"({what}s: {', '.join(table) or 'none'})")

    def apply(self, values: dict[str, Any]) -> None:
        """An entry (as converted) over what held before."""
        for n, v in values["subscriptions"].items():
            s = self._state[n]
            if "cdr" in v and "count" not in v:
                s["count"] = s["count"] + (v["cdr"] is not None)
            s.update(v)
        self._given_subscribers.update(values["subscribers"])
        for n, v in values.get("goals", {}).items():
            self._goals[n].update(v)
        for n, v in values.get("calls", {}).items():
            self._calls[n].update(v)
        self._servers.holding.update(values.get("servers", {}))

    def snapshot(self) -> dict[str, Any]:
        now = self.playback.t if self.playback is not None else 0
        snap: dict[str, tuple[Any, float, int, int]] = {}
        topics: dict[str, Any] = {}
        for n, s in self._state.items():
            count = s["count"]
            age = s["age"]
            if age is None:
                age = (now - s["arrived"]) / 1e6 if s["arrived"] is not None and count else math.inf
            pubs = s["publishers"]
            if pubs is None:
                pubs = 1 if count else 0
            snap[n] = (s["msg"], age, count, pubs)
            topics[n] = {"count": count, "age": age, "publishers": pubs,
                         "dropped": s["dropped"], "cdr": s["cdr"]}
        self._snap = snap
        self._snap_subscribers = dict(self._given_subscribers)
        scripted = self._servers
        self._goal_snap = {n: scripted.goal(n, now) or (g["status"], g["feedback"], g["result"])
                           for n, g in self._goals.items()}
        self._call_snap = {n: scripted.call(n, now) or (c["status"], c["response"])
                           for n, c in self._calls.items()}
        return {"subscriptions": topics, "subscribers": dict(self._snap_subscribers),
                **rpc.snapshot_values(self._goal_snap, self._call_snap)}

    # -- what snippets call --------------------------------------------------------------
    def __getattr__(self, attr: str) -> Any:
        subs = self.__dict__.get("_subs") or {}
        if attr in subs:
            self._asked(attr, attr)
        return super().__getattr__(attr)

    def age(self, name: str) -> float:
        self._asked("age", name)
        return super().age(name)

    def count(self, name: str) -> int:
        self._asked("count", name)
        return super().count(name)

    def publishers(self, name: str) -> int:
        self._asked("publishers", name)
        return super().publishers(name)

    def subscribers(self, name: str) -> int:
        self._asked("subscribers", name)
        return super().subscribers(name)

    def goal_status(self, name: str) -> str:
        self._asked("goal_status", name)
        return super().goal_status(name)

    def feedback(self, name: str) -> Any:
        self._asked("feedback", name)
        return super().feedback(name)

    def result(self, name: str) -> Any:
        self._asked("result", name)
        return super().result(name)

    def call_status(self, name: str) -> str:
        self._asked("call_status", name)
        return super().call_status(name)

    def response(self, name: str) -> Any:
        self._asked("response", name)
        return super().response(name)

    def cancel(self, name: str) -> bool:
        self._asked("cancel", name)  # it reads the goal's status
        return super().cancel(name)

    def _send(self, name: str, data: bytes) -> None:
        self._tell("publish", [name, base64.b64encode(data).decode("ascii")])

    # -- commands: told, as the live node tells the recording, and sent nowhere --------
    def _send_goal(self, name: str, goal: Any, running: bool) -> None:
        if self._servers.scripted(name):
            self._servers.send(name, self._now())
        if running:
            self._tell("cancel", [name, "replaced"])
        self._tell("send_goal", [name, base64.b64encode(cdr.serialize(goal)).decode("ascii")])

    def _cancel(self, name: str) -> None:
        self._servers.cancel(name, self._now())
        self._tell("cancel", [name])

    def _call(self, name: str, request: Any) -> None:
        if self._servers.scripted(name):
            self._servers.send(name, self._now())
        self._tell("call", [name, base64.b64encode(cdr.serialize(request)).decode("ascii")])

    def _now(self) -> int:
        return int(self.playback.t) if self.playback is not None else 0

    def _tell(self, call: str, args: list[Any]) -> None:
        if self.on_command is not None:
            self.on_command(call, args)

    def close(self) -> None:
        """Nothing to leave (the live node's DDS entities)."""

    def warning_at_stop(self) -> str | None:
        return None

    def _asked(self, query: str, field: str | None) -> None:
        """A query of what a recorded script does not hold: the playback notes the first."""
        lacks = self.lacks
        if lacks is None or self.quiet or self.playback is None:
            return
        if isinstance(lacks, str):
            self.playback.asked(self.name, query, lacks, None)
        elif field is not None and field in lacks:
            self.playback.asked(self.name, query, field, None)


def _mapping(value: Any, what: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError(f"{what} must be a mapping")
    return value


def _count(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{what} must be a whole number >= 0")
    return value


def _seconds(value: Any, what: str) -> float:
    if value == "inf":
        return math.inf
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
        raise ValueError(f"{what} must be a number of seconds >= 0, or \"inf\"")
    return float(value)


def fake(name: str, settings: dict[str, Any], playback: Any,
         rows: list[tuple[int, dict[str, Any], frozenset[str]]]) -> tuple[Ros2Fake, list[Any]]:
    """The fake of interface ``name``, and the script's rows for it, converted (raises
    ValueError with the row's time for the first that is wrong)."""
    try:
        made = Ros2Fake(name, settings, playback)
    except ros2.Ros2Error as e:
        raise ValueError(f"interface `{name}`: {e}") from None
    recorded = bool(getattr(playback, "recorded", False))
    # A scenario's script: no server unless it scripts one. A script that gives the goals'
    # and calls' values itself (a recording, or one written by hand) answers with those.
    gives = any(isinstance(values, dict) and (values.get("goals") or values.get("calls"))
                for _, values, _ in rows)
    made._servers.every = not recorded and not gives
    out = []
    for t, values, missing in rows:
        try:
            converted = made.convert(t, values, recorded)
            if recorded:  # what the model has and the recorded run did not: not evidence
                missing = missing | (frozenset(made._subs) - frozenset(converted["subscriptions"]))
                missing = missing | (frozenset(made._pubs) - frozenset(converted["subscribers"]))
                missing = missing | (frozenset(made._acts) - frozenset(converted.get("goals", {})))
                missing = missing | (frozenset(made._srvs) - frozenset(converted.get("calls", {})))
            out.append((t, converted, missing))
        except ValueError as e:
            raise ValueError(f"t={t}: interface `{name}`: {e}") from None
    return made, out
