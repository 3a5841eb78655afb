"""A scenario's expectations checked against one run: its trace and the commands it sent.

Times in a window are inclusive: ``after: 10s`` holds for a record at 10 s,
``before: 60s`` for one at 60 s.  Each failure names the expectation and the
record that broke it (a record too early or too late, an `enter` that should
not be there), or says what is missing and how the run ended.
"""

from __future__ import annotations

import base64
import json
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from hfsmc.scenario import Expectation, Scenario
from hfsmc.scenario_ros2 import Topics, describe, matches


@dataclass(frozen=True, slots=True)
class Record:
    """One line of a trace or of commands.jsonl, with where it was read."""

    data: dict[str, Any]
    text: str
    line: int

    @property
    def us(self) -> int:
        # trace records are in ms; commands in us (schemas/recording.md)
        return int(self.data["t"]) * (1 if "call" in self.data else 1000)


@dataclass(frozen=True, slots=True)
class Failure:
    expectation: Expectation | None  # None: the implicit rules (no error, the run ended)
    message: str
    records: tuple[str, ...] = ()  # the records that broke it, as written


@dataclass(frozen=True, slots=True)
class Run:
    trace: list[Record]
    commands: list[Record]
    trace_name: str  # how the report names the trace file
    exit_status: int | None
    # The component's `file:line:col: error: ...` lines (stderr), which place each error in
    # the model: the line that matters in a failure report.
    errors: tuple[str, ...] = ()
    topics: Topics | None = None  # the model's ros2 interfaces: publishes decoded with them


_MODEL_ERROR = re.compile(r"^\S+:\d+:\d+: error: .+$")


def model_errors(stderr: Iterable[str]) -> tuple[str, ...]:
    """The lines of the component's stderr that place an error in a snippet."""
    return tuple(line for line in stderr if _MODEL_ERROR.match(line))


def read_records(text: str) -> list[Record]:
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            data = json.loads(line)
        except (ValueError, RecursionError):
            break  # a line cut by a crash (or nested past what is read): the run ends there
        if isinstance(data, dict) and "t" in data:
            out.append(Record(data, line, n))
    return out


def check(sc: Scenario, run: Run) -> list[Failure]:
    """Every expectation of ``sc`` that ``run`` breaks, in the scenario's order."""
    failures: list[Failure] = []
    stop = next((r for r in run.trace if r.data.get("ev") == "stop"), None)
    if stop is None:
        failures.append(Failure(None, "the run has no `stop` record: the component ended "
                                f"abnormally (exit status {run.exit_status})"))
    expects_errors = any(x.kind == "error" for x in sc.expect)
    if not expects_errors:
        errors = [r for r in run.trace if r.data.get("ev") == "error"]
        if errors:
            failures.append(Failure(None, "an error in a snippet (an `error` expectation "
                                    "allows it)", (*run.errors[:1],
                                                   *(_where(run, r) for r in errors[:3]))))
    for x in sc.expect:
        f = _CHECKS[x.kind](x, run, stop)
        if f is not None:
            failures.append(f)
    return failures


def _where(run: Run, r: Record) -> str:
    """A record as the report quotes it: a trace line as written (`t` in ms); a command in
    words, its time in ms too (commands.jsonl itself counts us, as recordings do), so that
    one report speaks one unit (docs/testing.md)."""
    if "call" not in r.data:
        return f"{run.trace_name}:{r.line}: {r.text}"
    args = r.data.get("args", [])
    words = ", ".join(json.dumps(a) for a in args) if isinstance(args, list) else str(args)
    message = _message(run, r)
    if message is not None:
        kind = str(getattr(message, "__msgtype__", "")).rsplit("/", 1)[-1]
        words = f"{json.dumps(args[0])}, {kind}({describe(message)})"
    us = r.us
    ms = str(us // 1000) if us % 1000 == 0 else f"{us / 1000:.3f}"
    return (f"commands.jsonl:{r.line}: at {ms} ms: {r.data.get('interface')}."
            f"{r.data.get('call')}({words})")


def _in_window(x: Expectation, us: int) -> bool:
    return (x.after_us is None or us >= x.after_us) and (x.before_us is None or us <= x.before_us)


def _ending(run: Run, stop: Record | None) -> str:
    if stop is not None:
        return f"the run stopped ({stop.data.get('reason')}) at {stop.us / 1e6:g} s"
    last = run.trace[-1] if run.trace else None
    return f"the trace ends at {last.us / 1e6:g} s without a stop" if last else "the trace is empty"


def _counted(x: Expectation, run: Run, stop: Record | None, matches: list[Record],
             what: str) -> Failure | None:
    """The common rule of entered, log, command, error: at least once (or `count` times)
    inside the window."""
    inside = [r for r in matches if _in_window(x, r.us)]
    if x.at_least is not None:
        if len(inside) >= x.at_least:
            return None
        shown = tuple(_where(run, r) for r in inside[:5])
        return Failure(x, f"{what} {len(inside)} time(s) in that window, not at least "
                       f"{x.at_least}", shown)
    if x.count is not None:
        if len(inside) == x.count:
            return None
        shown = tuple(_where(run, r) for r in inside[:5])
        return Failure(x, f"{what} {len(inside)} time(s) in that window, not {x.count}", shown)
    if inside:
        return None
    if matches:
        return Failure(x, f"{what} only outside the window", tuple(_where(run, r) for r in matches[:3]))
    return Failure(x, f"no such record: {_ending(run, stop)}",
                   (_where(run, stop),) if stop is not None else ())


def _entered(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    m = [r for r in run.trace if r.data.get("ev") == "enter" and r.data.get("state") == x.subject]
    return _counted(x, run, stop, m, "entered")


def _not_entered(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    m = [r for r in run.trace if r.data.get("ev") == "enter" and r.data.get("state") == x.subject
         and _in_window(x, r.us)]
    return Failure(x, "entered", (_where(run, m[0]),)) if m else None


def _active(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    assert x.at_us is not None
    active = False
    last: Record | None = None
    for r in run.trace:
        if r.us > x.at_us:
            break
        if r.data.get("state") == x.subject and r.data.get("ev") in ("enter", "exit"):
            active = r.data["ev"] == "enter"
            last = r
    if active:
        return None
    if stop is not None and stop.us < x.at_us:
        return Failure(x, f"{_ending(run, stop)}, before that time", (_where(run, stop),))
    if last is None:
        return Failure(x, "never entered by then", ())
    return Failure(x, "not active then: its last record before that time", (_where(run, last),))


def _stop(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    if stop is None:
        return Failure(x, _ending(run, stop))
    reason_ok = x.subject == "any" or stop.data.get("reason") == x.subject
    if reason_ok and _in_window(x, stop.us):
        return None
    return Failure(x, "the run stopped otherwise", (_where(run, stop),))


def _log(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    if x.kind == "log":
        m = [r for r in run.trace if r.data.get("ev") == "log" and x.subject in str(r.data.get("msg"))]
    else:
        pattern = re.compile(x.subject)
        m = [r for r in run.trace if r.data.get("ev") == "log"
             and pattern.search(str(r.data.get("msg"))) is not None]
    return _counted(x, run, stop, m, "logged")


def _command(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    iface, call = x.subject.split(".")
    calls = {call, "goto", "go_to"} if call in ("goto", "go_to") else {call}
    sent = [r for r in run.commands if r.data.get("interface") == iface and r.data.get("call") in calls]
    m = [r for r in sent if x.args is None or _same_args(x.args, r.data.get("args", []))]
    f = _counted(x, run, stop, m, "sent")
    if f is not None and not m and sent:  # sent, with other arguments: show those
        return Failure(x, "sent only with other arguments", tuple(_where(run, r) for r in sent[:3]))
    return f


def _same_args(want: Iterable[Any], got: Any) -> bool:
    want = list(want)
    if not isinstance(got, list) or len(got) != len(want):
        return False
    for a, b in zip(want, got, strict=True):
        if isinstance(a, (str, bool)) or isinstance(b, (str, bool)):
            if a != b or isinstance(a, bool) != isinstance(b, bool):
                return False
        elif not math.isclose(float(a), float(b), rel_tol=1e-6, abs_tol=1e-9):
            return False
    return True


def _message(run: Run, r: Record) -> Any:
    """A ros2 publish's message, decoded by the model's definitions (None: not one)."""
    if run.topics is None or r.data.get("call") != "publish":
        return None
    args = r.data.get("args")
    iface = str(r.data.get("interface"))
    if not isinstance(args, list) or len(args) != 2 or iface not in run.topics.interfaces:
        return None
    t = run.topics.publication(iface, str(args[0]))
    if t is None:
        return None
    try:
        return run.topics.decode(base64.b64decode(str(args[1]), validate=True), t.type)
    except Exception:  # bytes that do not decode: shown as they are (base64)
        return None


def _published(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    iface, name = x.subject.split(".")
    sent = [r for r in run.commands if r.data.get("interface") == iface
            and r.data.get("call") == "publish" and isinstance(r.data.get("args"), list)
            and r.data["args"][:1] == [name]]
    if x.fields is None:
        m = sent
    else:
        fields = x.fields
        m = [r for r in sent if (msg := _message(run, r)) is not None and matches(msg, fields)]
    f = _counted(x, run, stop, m, "published")
    if f is not None and not m and sent:  # published, with other fields: show those
        inside = [r for r in sent if _in_window(x, r.us)] or sent
        return Failure(x, "published only with other fields" + (
            "" if inside is not sent else " (and outside the window)"),
            tuple(_where(run, r) for r in inside[:3]))
    return f


def _error(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    m = [r for r in run.trace if r.data.get("ev") == "error"
         and (x.subject == "any" or r.data.get("state") == x.subject)]
    return _counted(x, run, stop, m, "an error")


def _trace(x: Expectation, run: Run, stop: Record | None) -> Failure | None:
    with open(x.subject, encoding="utf-8") as f:
        want = [ln for ln in f.read().splitlines() if ln.strip()]
    got = [r.text for r in run.trace]
    for i in range(max(len(want), len(got))):
        w = want[i] if i < len(want) else None
        g = got[i] if i < len(got) else None
        if w is not None and g is not None and _same_record(w, g):
            continue
        if g is None:
            return Failure(x, f"the trace ends before {x.subject}:{i + 1}", (f"expected: {w}",))
        if w is None:
            return Failure(x, f"the trace goes on after the end of {x.subject}",
                           (f"{run.trace_name}:{run.trace[i].line}: {g}",))
        return Failure(x, f"first difference at {x.subject}:{i + 1}",
                       (f"expected: {w}", f"{run.trace_name}:{run.trace[i].line}: {g}"))
    return None


def _same_record(want: str, got: str) -> bool:
    """Equal lines; a `start` record's component name does not count (twins differ in it)."""
    if want == got:
        return True
    try:
        a, b = json.loads(want), json.loads(got)
    except (ValueError, RecursionError):
        return False
    if isinstance(a, dict) and isinstance(b, dict) and a.get("ev") == b.get("ev") == "start":
        return {**a, "name": ""} == {**b, "name": ""}
    return False


_CHECKS = {
    "entered": _entered,
    "not_entered": _not_entered,
    "active": _active,
    "stop": _stop,
    "log": _log,
    "log_matches": _log,
    "command": _command,
    "published": _published,
    "error": _error,
    "trace": _trace,
}
