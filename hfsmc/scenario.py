"""Scenario files for `hfsmc test` (docs/testing.md): the model, read with positions.

A scenario names a model (or a model per language), parameter overrides, a time
bound, scripted interface values over time and expectations on what the run
does.  :func:`load_scenario` reads one (ruamel.yaml's round-trip loader, as the
model front end does, so every value keeps its file:line:col) and checks its
shape; :func:`check_against_model` then checks its names against the compiled
model (states, parameters, interfaces, commands).  Every mistake is a
:class:`~hfsmc.errors.Diagnostic` with a code E190-E199; all of them are
collected before :class:`ScenarioError` is raised. What a scenario expects, and the
reading of its ``expect:`` list, is hfsmc/scenario_expect.py; its ROS 2 topics,
hfsmc/scenario_ros2.py.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hfsmc.drivers import driver
from hfsmc.errors import Diagnostic, Diagnostics, HfsmcError, Span, did_you_mean
from hfsmc.frontend import read_text
from hfsmc.frontend.source import PathKey
from hfsmc.frontend.yaml import load_yaml
from hfsmc.ir import Interface, Model
from hfsmc.scenario_driver import Ramp, check_settings
from hfsmc.scenario_expect import (
    Expectation,
    ExpectationReader,
    display_path,
    kind_of,
    number,
    secs,
)
from hfsmc.scenario_ros2 import RecordedTopic, Topics, Written, recorded_topic, written
from hfsmc.scenario_rpc import check_server, rpc

Language = Literal["python", "cpp"]
LANGUAGES: tuple[Language, ...] = ("python", "cpp")

# What a scenario may script, per interface type (schemas/recording.md's snapshot
# fields, with `connected` for heartbeat_age and `image` for a camera's frames).
MAVLINK_FIELDS: dict[str, str] = {
    "connected": "bool", "heartbeat_age": "number", "ready": "bool", "armed": "bool",
    "vehicle": "bool", "mode": "str", "type": "int", "position": "vector",
    "velocity": "vector", "altitude": "number", "yaw": "number", "battery": "int",
    "acks": "acks", "location": "vector", "home": "vector", "status_text": "str",
    "battery_failsafe": "str", "mission": "pair", "fence_breached": "bool",
    "failsafe": "str",
}
CAMERA_FIELDS: dict[str, str] = {"image": "image", "world": "world", "rate": "number"}
FIELDS = {"mavlink": MAVLINK_FIELDS, "camera": CAMERA_FIELDS}
RAMPABLE = frozenset({"number", "vector"})
ACK_OUTCOMES = ("accepted", "denied", "temporarily_rejected", "unsupported", "failed",
                "cancelled", "pending", "timeout", "not_sent")
DEFAULT_UNTIL_US = 600_000_000  # 10 min of virtual time

TOP_KEYS = ("name", "description", "model", "languages", "parameters", "until", "time_limit",
            "inputs", "expect")
ENTRY_KEYS = ("at", "from", "to")


class ScenarioError(HfsmcError):
    """A scenario file that cannot be run as written (exit status 2)."""


Scalar = bool | int | float | str | None | tuple[float, ...] | tuple[tuple[str, str], ...]


@dataclass(frozen=True, slots=True)
class Setting:
    field: str
    value: Any  # a Scalar, or a Ramp
    span: Span
    key_span: Span
    # The value as written, with its positions: a user driver's field (its type is known
    # only with the model: hfsmc/scenario_driver.py); `spanned`: in a from/to entry.
    raw: Written | None = dataclasses.field(default=None, compare=False)
    spanned: bool = False
    # What reading it as a built-in interface's input found wrong: said unless the
    # interface turns out to be a user driver's, whose fields are its own.
    held: tuple[Diagnostic, ...] = dataclasses.field(default=(), compare=False)


@dataclass(frozen=True, slots=True)
class Entry:
    """Values an interface takes from ``start_us`` on (until ``end_us``, then what held before)."""

    interface: str
    start_us: int
    end_us: int | None
    settings: tuple[Setting, ...]
    span: Span
    interface_span: Span  # the interface's name under `inputs`


@dataclass(frozen=True, slots=True)
class ModelRef:
    language: Language
    path: str  # resolved: relative to the current folder, or absolute
    span: Span


@dataclass(frozen=True, slots=True)
class Override:
    name: str
    value: bool | int | float | str
    span: Span


@dataclass(frozen=True, slots=True)
class Scenario:
    file: str
    name: str
    models: tuple[ModelRef, ...]
    languages: tuple[Language, ...]
    parameters: tuple[Override, ...]
    until_us: int
    time_limit_us: int | None
    inputs: tuple[Entry, ...]
    expect: tuple[Expectation, ...]
    lines: tuple[str, ...]
    model_span: Span

    def model_for(self, language: Language) -> ModelRef:
        return next(m for m in self.models if m.language == language)


# ---------------------------------------------------------------------------
# reading


def load_scenario(path: str) -> Scenario:
    """Read and check the shape of one scenario file; raise :class:`ScenarioError`."""
    diags = Diagnostics()
    scenario = read_scenario(path, diags)
    if diags.has_errors or scenario is None:
        raise ScenarioError(diags.sorted())
    return scenario


def read_scenario(path: str, diags: Diagnostics) -> Scenario | None:
    """Read one scenario file, its shape's problems into ``diags``; None when it cannot be
    read at all (or names no model). Raises :class:`HfsmcError` for unreadable YAML."""
    text = read_text(path)
    doc = load_yaml(path, text, diags)
    if diags.has_errors:
        return None
    if not isinstance(doc.data, dict):
        diags.error("E191", "a scenario is a mapping (model:, inputs:, expect:...)", doc.span(()))
        return None
    return _Reader(doc, diags, Path(path).parent).scenario()


class _Reader(ExpectationReader):
    # -- the document

    def scenario(self) -> Scenario | None:
        data: dict[str, Any] = self.doc.data
        self.keys(data, (), TOP_KEYS, "a scenario")
        name = data.get("name", Path(self.doc.file).stem)
        if not isinstance(name, str):
            self.error("E191", f"`name` must be a string, not {kind_of(name)}", self.at(("name",)))
            name = Path(self.doc.file).stem
        if "description" in data and not isinstance(data["description"], str):
            self.error("E191", "`description` must be a string", self.at(("description",)))
        models = self.models(data)
        languages = self.languages(data, models)
        until = DEFAULT_UNTIL_US
        if "until" in data:
            until = self.duration(data["until"], ("until",), "`until`") or DEFAULT_UNTIL_US
            if until == 0:
                self.error("E193", "`until` must be after 0 s", self.at(("until",)))
        time_limit = None
        if "time_limit" in data:
            time_limit = self.duration(data["time_limit"], ("time_limit",), "`time_limit`")
            if time_limit == 0:
                self.error("E193", "`time_limit` must be after 0 s", self.at(("time_limit",)))
        overrides = self.parameters(data)
        inputs = self.inputs(data, until)
        expect = self.expectations(data, until)
        if models is None:
            return None
        return Scenario(self.doc.file, name, models, languages, overrides, until, time_limit, inputs,
                        expect, tuple(self.doc.lines), self.key_at(("model",)))

    def models(self, data: dict[str, Any]) -> tuple[ModelRef, ...] | None:
        if "model" not in data:
            self.error("E192", "missing key `model`: the model to test, relative to this file",
                       self.at(()), "`model: ../mission.yaml`, or one per language: "
                       "`model: {python: ../m.yaml, cpp: ../m_cpp/m_cpp.yaml}`")
            return None
        value = data["model"]
        written: list[tuple[Language | None, str, PathKey]] = []
        if isinstance(value, str):
            written.append((None, value, ("model",)))
        elif isinstance(value, dict):
            self.keys(value, ("model",), LANGUAGES, "`model`")
            for one in LANGUAGES:
                if one in value:
                    if isinstance(value[one], str):
                        written.append((one, value[one], ("model", one)))
                    else:
                        self.error("E191", f"`model.{one}` must be a path", self.at(("model", one)))
            if not value:
                self.error("E192", "`model` names no model", self.at(("model",)))
        else:
            self.error("E191", f"`model` must be a path or a mapping language: path, not "
                       f"{kind_of(value)}", self.at(("model",)))
        refs = []
        for lang, rel, path in written:
            file = self.folder / rel
            span = self.at(path)
            if not file.is_file():
                self.error("E194", f"the model `{rel}` does not exist (read relative to the "
                           "scenario's folder)", span)
                continue
            found: Language | None = lang or _model_language(file)
            if found is None:
                self.error("E194", f"`{rel}` is not a YAML or XML model with `language:`", span)
                continue
            if lang is not None and _model_language(file) not in (lang, None):
                self.error("E194", f"`{rel}` is a model of language `{_model_language(file)}`, "
                           f"given as `{lang}`", span)
                continue
            refs.append(ModelRef(found, display_path(file), span))
        if not refs:
            return None
        return tuple(refs)

    def languages(self, data: dict[str, Any], models: tuple[ModelRef, ...] | None) -> tuple[Language, ...]:
        given = tuple(m.language for m in models or ())
        if "languages" not in data:
            return given
        value = data["languages"]
        items = [value] if isinstance(value, str) else value
        if value == "both":
            items = list(LANGUAGES)
        if not isinstance(items, list) or not items:
            self.error("E191", "`languages` must be python, cpp, both or a list of them",
                       self.at(("languages",)))
            return given
        out: list[Language] = []
        for i, lang in enumerate(items):
            path: PathKey = ("languages",) if isinstance(value, str) else ("languages", i)
            if lang not in LANGUAGES:
                self.error("E193", f"unknown language `{lang}`: python or cpp", self.at(path))
            elif models is not None and lang not in given:
                self.error("E194", f"no model given for `{lang}`: write "
                           "`model: {python: ..., cpp: ...}`", self.at(path))
            elif lang not in out:
                out.append(lang)
        return tuple(out) or given

    def parameters(self, data: dict[str, Any]) -> tuple[Override, ...]:
        if "parameters" not in data:
            return ()
        value = self.mapping(data["parameters"], ("parameters",), "`parameters`")
        out = []
        for name, v in (value or {}).items():
            path = ("parameters", name)
            if isinstance(v, (bool, int, float, str)):
                out.append(Override(name, v, self.key_at(path)))
            else:
                self.error("E196", f"parameter `{name}`: only bool, int, float and str parameters "
                           f"can be set, not {kind_of(v)}", self.at(path))
        return tuple(out)

    # -- inputs

    def inputs(self, data: dict[str, Any], until: int) -> tuple[Entry, ...]:
        if "inputs" not in data:
            return ()
        value = self.mapping(data["inputs"], ("inputs",), "`inputs`")
        out: list[Entry] = []
        for iface, entries in (value or {}).items():
            path: PathKey = ("inputs", iface)
            if not isinstance(entries, list):
                self.error("E191", f"`inputs.{iface}` must be a list of entries "
                           "(`- {at: 0s, connected: true}`)", self.at(path))
                continue
            for i, entry in enumerate(entries):
                e = self.entry(iface, entry, (*path, i), until)
                if e is not None:
                    out.append(e)
        return tuple(out)

    def entry(self, iface: str, entry: Any, path: PathKey, until: int) -> Entry | None:
        m = self.mapping(entry, path, "an input entry")
        if m is None:
            return None
        has_at, has_from = "at" in m, "from" in m
        if has_at == has_from:
            self.error("E192" if not has_at else "E193",
                       "an input entry starts with `at: TIME` (from then on) or `from: TIME` "
                       "(with `to: TIME`: over that span)", self.at(path))
            return None
        if has_at and "to" in m:
            self.error("E193", "`to` goes with `from`, not `at`", self.key_at((*path, "to")))
        start = self.duration(m["at" if has_at else "from"], (*path, "at" if has_at else "from"),
                              "the entry's time")
        end = None
        if "to" in m:
            end = self.duration(m["to"], (*path, "to"), "`to`")
            if end is not None and start is not None and end <= start:
                self.error("E193", f"`to` ({secs(end)}) must come after `from` "
                           f"({secs(start)})", self.at((*path, "to")))
                return None
        if start is None:
            return None
        if start > until:
            self.error("E193", f"the entry starts at {secs(start)}, after `until` "
                       f"({secs(until)}): it would never be seen", self.at(path))
        settings = []
        for key, v in m.items():
            if key in ENTRY_KEYS:
                continue
            # read as a built-in interface's input; what is wrong is held until the model
            # says whether the interface is one, or a user driver's (its own fields)
            held, self.diags = self.diags, Diagnostics()
            try:
                s = self.setting(key, v, (*path, key), end is not None)
            finally:
                held, self.diags = self.diags, held
            settings.append(Setting(key, None if s is None else s.value, self.at((*path, key)),
                                    self.key_at((*path, key)), written(self.doc, (*path, key)),
                                    end is not None, tuple(held)))
        if not settings:
            self.error("E192", "the entry sets no value", self.at(path))
        return Entry(iface, start, end, tuple(settings), self.at(path), self.key_at(path[:2]))

    def setting(self, key: str, v: Any, path: PathKey, span_entry: bool) -> Setting | None:
        kind = MAVLINK_FIELDS.get(key) or CAMERA_FIELDS.get(key)
        if isinstance(v, dict) and key != "acks" and not (kind is not None and "ramp" in v):
            # a message of a ros2 interface's subscription: checked once the model is known
            topic: Written | RecordedTopic | None = written(self.doc, path)
            if "recorded" in v:
                topic = recorded_topic(self.doc, path, self.folder, self.diags, self.duration)
            return None if topic is None else Setting(key, topic, self.at(path), self.key_at(path))
        if kind is None:
            allowed = tuple(MAVLINK_FIELDS) + tuple(CAMERA_FIELDS)
            note = did_you_mean(key, allowed)
            self.error("E190", f"unknown input `{key}`", self.key_at(path), *([note] if note else []),
                       f"a mavlink interface takes: {', '.join(MAVLINK_FIELDS)}; a camera: "
                       f"{', '.join(CAMERA_FIELDS)}; a ros2 interface: its subscriptions, each "
                       "a message (`scan: {range_max: 12.0}`), `rate`, and its actions and "
                       "services, each a server (`navigate: {after: 2s}`) (and every entry "
                       "at/from/to)")
            return None
        span = self.at(path)
        if isinstance(v, dict) and "ramp" in v:
            if kind not in RAMPABLE:
                self.error("E193", f"`{key}` cannot ramp: only numbers and vectors do", span)
                return None
            if not span_entry:
                self.error("E193", "a ramp needs a span: `from: TIME, to: TIME`", span)
                return None
            self.keys(v, path, ("ramp",), "a ramp")
            r = v["ramp"]
            if not isinstance(r, list) or len(r) != 2:
                self.error("E191", "`ramp` takes [START, END]", self.at((*path, "ramp")))
                return None
            a = self.value(key, kind, r[0], (*path, "ramp", 0))
            b = self.value(key, kind, r[1], (*path, "ramp", 1))
            if a is None or b is None:
                return None
            return Setting(key, Ramp(a, b), span, self.key_at(path))
        value = self.value(key, kind, v, path)
        if value is None and not (kind in ("image", "world") and v is None):
            return None
        return Setting(key, value, span, self.key_at(path))

    def value(self, key: str, kind: str, v: Any, path: PathKey) -> Scalar:
        span = self.at(path)
        bad = None
        if kind == "bool":
            if isinstance(v, bool):
                return v
            bad = "true or false"
        elif kind == "int":
            if isinstance(v, int) and not isinstance(v, bool):
                return v
            bad = "an integer"
        elif kind == "number":
            num = number(v)
            if num is not None:
                if key == "rate" and not (math.isfinite(num) and num > 0):
                    self.error("E193", "`rate` (frames per second) must be above 0", span)
                    return None
                return num
            bad = "a number (.nan and .inf are numbers too)"
        elif kind == "str":
            if isinstance(v, str):
                return v
            bad = "a string"
        elif kind == "vector":
            if isinstance(v, list) and len(v) == 3 and all(number(x) is not None for x in v):
                return tuple(float(number(x)) for x in v)  # type: ignore[arg-type]
            bad = "[north, east, down] (three numbers, m or m/s)"
        elif kind == "pair":
            if isinstance(v, list) and len(v) == 2 and all(
                    isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in v):
                return (v[0], v[1])
            bad = "[current, total] (two integers, 0 or more)"
        elif kind == "acks":
            return self.acks(v, path)
        elif kind in ("image", "world"):
            return self.image(v, path, kind)
        self.error("E191", f"`{key}` must be {bad}, not {kind_of(v)}", span)
        return None

    def acks(self, v: Any, path: PathKey) -> Scalar:
        m = self.mapping(v, path, "`acks`")
        if m is None:
            return None
        out = []
        acked = acknowledged("mavlink")
        for cmd, outcome in m.items():
            if cmd not in acked:
                note = did_you_mean(cmd, acked)
                self.error("E193", f"no acknowledgement for `{cmd}`", self.key_at((*path, cmd)),
                           *([note] if note else []), f"commands acknowledged: {', '.join(acked)}")
            elif outcome not in ACK_OUTCOMES:
                note = did_you_mean(str(outcome), ACK_OUTCOMES)
                self.error("E193", f"`{outcome}` is not an outcome", self.at((*path, cmd)),
                           *([note] if note else []), f"outcomes: {', '.join(ACK_OUTCOMES)}")
            else:
                out.append((cmd, outcome))
        return tuple(out)

    def image(self, v: Any, path: PathKey, kind: str) -> Scalar:
        """A picture file (`image`) or a simulator world file (`world`), or null."""
        if v is None:
            return None
        what = "an image" if kind == "image" else "a world file (hfsmc sim --world)"
        if not isinstance(v, str):
            self.error("E191", f"`{kind}` must be {what} (or null: no more frames), not "
                       f"{kind_of(v)}", self.at(path))
            return None
        file = self.folder / v
        if not file.is_file():
            self.error("E198", f"the {kind} file `{v}` does not exist (read relative to the "
                       "scenario's folder)", self.at(path))
            return None
        return display_path(file)


def _model_language(file: Path) -> Language | None:
    """The `language:` a model file declares (python when it says none), by a light read."""
    try:
        text = file.read_text("utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    m = re.search(r"^language:\s*[\"']?(python|cpp)[\"']?\s*(#.*)?$", text, re.MULTILINE) \
        or re.search(r"\blanguage=[\"'](python|cpp)[\"']", text)
    if m:
        return m.group(1)  # type: ignore[return-value]
    return "python"


# ---------------------------------------------------------------------------
# checking the names against the model


def check_against_model(sc: Scenario, model: Model, diags: Diagnostics) -> None:
    """The scenario's states, parameters, interfaces and commands against one model."""
    where = f"the model `{model.name}`" if len(sc.models) > 1 else "the model"
    params = {p.name: p for p in model.parameters}
    for o in sc.parameters:
        p = params.get(o.name)
        if p is None:
            note = did_you_mean(o.name, params)
            diags.error("E196", f"{where} has no parameter `{o.name}`", o.span,
                        *([note] if note else []))
        elif not _fits(p.type, o.value):
            diags.error("E196", f"parameter `{o.name}` is a {p.type}; {o.value!r} is not", o.span)
    interfaces = {i.name: i for i in model.interfaces}
    topics = Topics(model) if any(i.type == "ros2" for i in model.interfaces) else None
    said: set[str] = set()
    for e in sc.inputs:
        iface = interfaces.get(e.interface)
        if iface is not None and iface.type == "driver":  # its own fields (scenario_driver.py)
            check_settings(e.interface, iface.declaration, e.settings, e.interface_span, diags)
            continue
        for s in e.settings:  # what reading it as a built-in interface's input found
            diags.extend(s.held)
        settings = [s for s in e.settings if not s.held]
        if iface is None or (FIELDS.get(iface.type) is None and iface.type != "ros2"):
            if e.interface in said:
                continue
            said.add(e.interface)
        if iface is None:
            note = did_you_mean(e.interface, interfaces)
            diags.error("E195", f"{where} has no interface `{e.interface}`", e.interface_span,
                        *([note] if note else []))
            continue
        if iface.type == "ros2" and topics is not None:
            servers = [s for s in settings if rpc(topics, e.interface, s.field) is not None]
            for s in servers:  # an action's or a service's scripted server
                check_server(topics, e.interface, s.field, s.value, diags)
            topics.check_settings(e.interface, tuple(s for s in settings if s not in servers),
                                  diags)
            continue
        fields = FIELDS.get(iface.type)
        if fields is None:
            diags.error("E195", f"`{e.interface}` is a {iface.type} interface: scenarios script "
                        "mavlink, camera, ros2 and user driver interfaces", e.interface_span)
            continue
        for s in settings:
            if isinstance(s.value, (Written, RecordedTopic)):
                diags.error("E195", f"`{s.field}`: a message (a mapping of fields) is an input of "
                            f"a ros2 interface; `{e.interface}` is a {iface.type} interface",
                            s.key_span, f"it takes: {', '.join(fields)}")
            elif s.field not in fields:
                diags.error("E195", f"`{s.field}` is not an input of a {iface.type} interface "
                            f"(`{e.interface}`)", s.key_span, f"it takes: {', '.join(fields)}")
    states = {s.path for s in model.states()}
    for x in sc.expect:
        if x.kind in ("entered", "not_entered", "active") or (x.kind == "error" and x.subject != "any"):
            if x.subject not in states and not (x.kind == "error" and x.subject == ""):
                note = did_you_mean(x.subject, states)
                diags.error("E197", f"{where} has no state `{x.subject}`", x.subject_span,
                            *([note] if note else []))
        elif x.kind == "published":
            iname = x.subject.split(".")[0]
            iface = interfaces.get(iname)
            if iface is None or iface.type != "ros2" or topics is None:
                note = did_you_mean(iname, [i for i, f in interfaces.items() if f.type == "ros2"])
                diags.error("E195", f"{where} has no ros2 interface `{iname}`" if iface is None
                            else f"`{iname}` is a {iface.type} interface: `published` is for "
                            "the messages of a ros2 interface", x.subject_span,
                            *([note] if note and iface is None else []))
            else:
                topics.check_published(x.subject, x.subject_span, x.msg_type, x.fields, diags)
        elif x.kind == "command":
            iname, call = x.subject.split(".")
            iface = interfaces.get(iname)
            if iface is None:
                note = did_you_mean(iname, interfaces)
                diags.error("E195", f"{where} has no interface `{iname}`", x.subject_span,
                            *([note] if note else []))
            elif _call(call) not in _commands(iface):
                commands = _commands(iface)
                note = did_you_mean(call, commands)
                diags.error("E199", f"`{call}` is not a command of a {iface.kind} interface",
                            x.subject_span, *([note] if note else []),
                            f"commands: {', '.join(commands) or 'none'}")


def commands_of(kind: str) -> tuple[str, ...]:
    """The commands of an interface type, as its driver defines them (hfsmc/drivers.py)."""
    d = driver(kind)
    return () if d is None else d.commands


def _commands(iface: Interface) -> tuple[str, ...]:
    """The commands of one interface: a user driver's as it declares them."""
    if iface.type == "driver":
        return () if iface.declaration is None else iface.declaration.commands
    return commands_of(iface.type)


def acknowledged(kind: str) -> tuple[str, ...]:
    """The commands of an interface type whose outcome ``last_ack`` gives."""
    d = driver(kind)
    return () if d is None else d.acknowledged


def _call(name: str) -> str:
    return "goto" if name == "go_to" else name


def _fits(kind: str, v: object) -> bool:
    checks: dict[str, Callable[[object], bool]] = {
        "bool": lambda x: isinstance(x, bool),
        "int": lambda x: isinstance(x, int) and not isinstance(x, bool),
        "float": lambda x: isinstance(x, (int, float)) and not isinstance(x, bool),
        "str": lambda x: isinstance(x, str),
    }
    check = checks.get(kind)
    return check is not None and check(v)


def grid_us(models: list[Model]) -> int:
    """The step of scripted values: the greatest common divisor of every period of the
    models (the instants all fall on it), 10 ms at the finest."""
    step = 0
    for model in models:
        for a in model.automata():
            step = math.gcd(step, a.period_ms)
    return max(step, 10) * 1000 if step else 10_000
