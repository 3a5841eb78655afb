"""What a scenario expects (docs/testing.md, "Expectations"): the kinds of expectation and
the modifiers each takes, :class:`Expectation` and its words in a failure report, and the
reading of a scenario's ``expect:`` list with every position (:class:`ExpectationReader`,
on which the scenario's reader in hfsmc/scenario.py builds: the document's helpers, its
mappings, keys and times, live here with it)."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hfsmc.durations import has_unit, parse_us
from hfsmc.errors import Diagnostics, Span, did_you_mean
from hfsmc.frontend.source import Document, PathKey
from hfsmc.scenario_ros2 import Written, written

STOP_REASONS = ("final", "until", "shutdown", "sigint", "sigterm", "error", "timeout",
                "time_limit")

# An expectation is one mapping: one of these kinds, and the modifiers it takes.
_WINDOW = ("after", "before", "between")
KINDS: dict[str, tuple[str, ...]] = {
    "entered": (*_WINDOW, "count", "at_least"),
    "not_entered": _WINDOW,
    "active": ("at",),
    "stop": _WINDOW,
    "log": (*_WINDOW, "count", "at_least"),
    "log_matches": (*_WINDOW, "count", "at_least"),
    "command": ("args", *_WINDOW, "count", "at_least"),
    "published": ("fields", "type", *_WINDOW, "count", "at_least"),
    "error": (*_WINDOW, "count", "at_least"),
    "trace": (),
}
MODIFIERS = frozenset(m for mods in KINDS.values() for m in mods)


@dataclass(frozen=True, slots=True)
class Expectation:
    kind: str
    subject: str  # state path, text, regex, `drone.land`, stop reason, trace file (resolved)
    span: Span  # the expectation's kind key (`entered:`)
    subject_span: Span  # the value after it
    after_us: int | None = None
    before_us: int | None = None
    at_us: int | None = None
    count: int | None = None
    args: tuple[Any, ...] | None = None
    at_least: int | None = None
    fields: Written | None = None  # published: the fields the message must have
    msg_type: str | None = None  # published: the type it must be (`type:`)

    def describe(self) -> str:
        """The expectation in words, as the failure report says it."""
        what = {
            "entered": f"`{self.subject}` entered",
            "not_entered": f"`{self.subject}` never entered",
            "active": f"`{self.subject}` active",
            "stop": f"the run stops ({self.subject})",
            "log": f"a log line containing {self.subject!r}",
            "log_matches": f"a log line matching /{self.subject}/",
            "command": f"command {self.subject}"
                       + (f"({', '.join(_show(a) for a in self.args)})" if self.args is not None else ""),
            "published": f"{self.subject} published"
                         + (f" with {_written_words(self.fields)}" if self.fields is not None else ""),
            "error": f"an error in a snippet ({self.subject})",
            "trace": f"the trace equal to {self.subject}",
        }[self.kind]
        return what + window_words(self)


def window_words(e: Expectation) -> str:
    parts = []
    if e.count is not None:
        parts.append(f" {e.count} time(s)")
    if e.at_least is not None:
        parts.append(f" at least {e.at_least} time(s)")
    if e.at_us is not None:
        parts.append(f" at {secs(e.at_us)}")
    if e.after_us is not None and e.before_us is not None:
        parts.append(f" between {secs(e.after_us)} and {secs(e.before_us)}")
    elif e.after_us is not None:
        parts.append(f" at or after {secs(e.after_us)}")
    elif e.before_us is not None:
        parts.append(f" by {secs(e.before_us)}")
    return "".join(parts)


def secs(us: int) -> str:
    return f"{us / 1e6:g} s"


def _written_words(w: Written) -> str:
    """An expectation's fields as written: `linear.x=0, angular.z={not: 0}`."""
    def flat(v: Written, prefix: str) -> list[str]:
        if isinstance(v.value, dict) and not (set(v.value) & {"above", "below", "not"}):
            return [p for k, x in v.value.items() for p in flat(x, f"{prefix}{k}.")]
        return [f"{prefix[:-1]}={_plain(v)}"]
    return ", ".join(flat(w, "")) or "any fields"


def _plain(w: Written) -> str:
    if isinstance(w.value, dict):
        return "{" + ", ".join(f"{k}: {_plain(x)}" for k, x in w.value.items()) + "}"
    if isinstance(w.value, list):
        return "[" + ", ".join(_plain(x) for x in w.value) + "]"
    return _show(w.value)


def _show(v: Any) -> str:
    return f"{v!r}" if isinstance(v, str) else str(v)


def number(v: Any) -> float | None:
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v)
    return None


def kind_of(v: Any) -> str:
    return {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number", type(None): "null"}.get(type(v), type(v).__name__)


def display_path(file: Path) -> str:
    """A file the scenario names, as messages and builds name it: without `..` steps, relative
    to the current folder when inside it (one model is one component, however reached)."""
    absolute = Path(os.path.abspath(file))
    if absolute.is_relative_to(Path.cwd()):
        return str(absolute.relative_to(Path.cwd()))
    return str(absolute)


class ReaderBase:
    """A scenario document read with positions: its diagnostics, mappings, keys and times."""

    def __init__(self, doc: Document, diags: Diagnostics, folder: Path) -> None:
        self.doc = doc
        self.diags = diags
        self.folder = folder

    # -- helpers

    def at(self, path: PathKey) -> Span:
        return self.doc.span(path)

    def key_at(self, path: PathKey) -> Span:
        return self.doc.key_span(path)

    def error(self, code: str, message: str, span: Span, *notes: str) -> None:
        self.diags.error(code, message, span, *notes)

    def keys(self, value: dict[str, Any], path: PathKey, allowed: tuple[str, ...], what: str) -> None:
        for k in value:
            if k not in allowed:
                note = did_you_mean(k, allowed)
                self.error("E190", f"unknown key `{k}` in {what}", self.key_at((*path, k)),
                           *([note] if note else []), f"{what} takes: {', '.join(allowed)}")

    def mapping(self, value: Any, path: PathKey, what: str) -> dict[str, Any] | None:
        if isinstance(value, dict):
            return value
        self.error("E191", f"{what} must be a mapping, not {kind_of(value)}", self.at(path))
        return None

    def duration(self, value: Any, path: PathKey, what: str) -> int | None:
        us = parse_us(value)
        if us is None or isinstance(value, (int, float)) or not has_unit(value):
            hint = "write a time with its unit: `30s`, `500ms`, `1.5m`"
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                self.error("E193", f"{what}: a bare number ({value}) has no unit", self.at(path), hint)
            else:
                self.error("E193", f"{what}: `{value}` is not a time", self.at(path), hint)
            return None
        return us


class ExpectationReader(ReaderBase):
    """The ``expect:`` list of a scenario."""

    def expectations(self, data: dict[str, Any], until: int) -> tuple[Expectation, ...]:
        if "expect" not in data:
            return ()
        value = data["expect"]
        if not isinstance(value, list):
            self.error("E191", "`expect` must be a list of expectations "
                       "(`- entered: Mission`)", self.at(("expect",)))
            return ()
        out = []
        for i, item in enumerate(value):
            e = self.expectation(item, ("expect", i), until)
            if e is not None:
                out.append(e)
        return tuple(out)

    def expectation(self, item: Any, path: PathKey, until: int) -> Expectation | None:
        m = self.mapping(item, path, "an expectation")
        if m is None:
            return None
        kinds = [k for k in m if k in KINDS]
        if len(kinds) != 1:
            unknown = [k for k in m if k not in KINDS and k not in MODIFIERS]
            if unknown and not kinds:
                note = did_you_mean(unknown[0], KINDS)
                self.error("E190", f"unknown expectation `{unknown[0]}`",
                           self.key_at((*path, unknown[0])), *([note] if note else []),
                           f"expectations: {', '.join(KINDS)}")
            else:
                self.error("E193", "an expectation has exactly one of: " + ", ".join(KINDS)
                           + (f" (this one has {', '.join(kinds)})" if kinds else ""), self.at(path))
            return None
        kind = kinds[0]
        self.keys(m, path, (kind, *KINDS[kind]), f"a `{kind}` expectation")
        kpath = (*path, kind)
        subject = self.subject(kind, m[kind], kpath)
        if subject is None:
            return None
        times: dict[str, int | None] = {}
        for mod in ("after", "before", "at"):
            if mod in m and mod in KINDS[kind]:
                times[mod] = self.duration(m[mod], (*path, mod), f"`{mod}`")
        if "between" in m and "after" in KINDS[kind]:
            b = m["between"]
            if "after" in m or "before" in m:
                self.error("E193", "`between` replaces `after` and `before`: write one or the "
                           "other", self.key_at((*path, "between")))
            elif not isinstance(b, list) or len(b) != 2:
                self.error("E191", "`between` takes [FROM, TO]", self.at((*path, "between")))
            else:
                times["after"] = self.duration(b[0], (*path, "between", 0), "`between`")
                times["before"] = self.duration(b[1], (*path, "between", 1), "`between`")
        after, before = times.get("after"), times.get("before")
        if after is not None and before is not None and after > before:
            self.error("E193", f"the window's start ({secs(after)}) is later than its end "
                       f"({secs(before)})", self.at((*path, "between" if "between" in m else "after")))
        for mod, us in times.items():
            if us is not None and us > until and not (kind == "not_entered" or mod == "before"):
                where = (*path, mod) if mod in m else (*path, "between", 0)
                self.error("E193", f"{secs(us)} is after `until` ({secs(until)}): "
                           "the run never gets there", self.at(where))
        if kind == "active" and "at" not in m:
            self.error("E192", "`active` needs `at: TIME`", self.key_at(kpath))
        count = None
        if "count" in m and "count" in KINDS[kind]:
            c = m["count"]
            if isinstance(c, int) and not isinstance(c, bool) and c >= 0:
                count = c
            else:
                self.error("E191", "`count` must be a whole number (0: never)", self.at((*path, "count")))
        at_least = None
        if "at_least" in m and "at_least" in KINDS[kind]:
            c = m["at_least"]
            if "count" in m:
                self.error("E193", "`count` (exactly) or `at_least`: write one or the other",
                           self.key_at((*path, "at_least")))
            elif isinstance(c, int) and not isinstance(c, bool) and c >= 1:
                at_least = c
            else:
                self.error("E191", "`at_least` must be a whole number from 1 (`count: 0`: "
                           "never)", self.at((*path, "at_least")))
        fields = written(self.doc, (*path, "fields")) if "fields" in m and kind == "published" \
            else None
        msg_type = None
        if "type" in m and kind == "published":
            if isinstance(m["type"], str):
                msg_type = m["type"]
            else:
                self.error("E191", "`type` must be a message type (`geometry_msgs/msg/Twist`)",
                           self.at((*path, "type")))
        args = None
        if "args" in m and kind == "command":
            a = m["args"]
            if isinstance(a, list) and all(isinstance(x, (int, float, str)) for x in a):
                args = tuple(a)
            else:
                self.error("E191", "`args` must be a list of numbers, strings and booleans",
                           self.at((*path, "args")))
        return Expectation(kind, subject, self.key_at(kpath), self.at(kpath), after, before, times.get("at"),
                           count, args, at_least, fields, msg_type)

    def subject(self, kind: str, v: Any, path: PathKey) -> str | None:
        span = self.at(path)
        if kind == "trace":
            if not isinstance(v, str) or not (self.folder / v).is_file():
                self.error("E198", f"the trace file `{v}` does not exist (read relative to the "
                           "scenario's folder)", span)
                return None
            return display_path(self.folder / v)
        if kind == "stop":
            if v == "any" or v in STOP_REASONS:
                return str(v)
            note = did_you_mean(str(v), STOP_REASONS)
            self.error("E193", f"`{v}` is not a stop reason", span, *([note] if note else []),
                       f"reasons: any, {', '.join(STOP_REASONS)}")
            return None
        if not isinstance(v, str) or not v:
            self.error("E191", f"`{kind}` must be a non-empty string, not {kind_of(v)}", span)
            return None
        if kind == "log_matches":
            try:
                re.compile(v)
            except re.error as e:
                self.error("E193", f"not a regular expression: {e}", span)
                return None
        if kind in ("command", "published") and not re.fullmatch(r"[A-Za-z_]\w*\.[A-Za-z_]\w*", v):
            self.error("E193", f"`{v}`: write INTERFACE.COMMAND (`drone.land`)" if kind == "command"
                       else f"`{v}`: write INTERFACE.PUBLICATION (`robot.cmd_vel`)", span)
            return None
        return v
