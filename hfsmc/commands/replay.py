"""``hfsmc replay RECORDING``: run a recorded model again, fed from the recording, and compare.

The component (the recorded model, or the one given with ``--model``) runs with
``--playback DIR --clock virtual``: its interfaces are fakes fed from
``DIR/inputs.jsonl`` (each instant's snapshots, the clock's skips, the signals),
written here from the recording (schemas/recording.md, "Playback").  What it
does (its trace and the commands it sent, ``DIR/commands.jsonl``) is compared
with what was recorded; the first difference is reported with the instant, the
active states and the transition that went the other way, with its model line.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hfsmc.commands.replay_model import (
    Built,
    NotAllowed,
    ReplayFailed,
    build,
    given_model,
    recorded_model,
    what_it_carries,
)

__all__ = ["NotAllowed", "ReplayFailed", "Report", "render", "replay"]
from hfsmc.durations import format_us
from hfsmc.errors import HfsmcError, UsageError
from hfsmc.ir import Model, Transition
from hfsmc.recording import Command, Frame, Recording, read_recording

NOT_EVIDENCE = ("from here on the vehicle would have been commanded differently: "
                "the recording is no longer evidence")


@dataclass
class Report:
    """What replay found: the lines to print (style, text) and the exit status."""

    lines: list[tuple[str, str]] = field(default_factory=list)
    status: int = 0

    def add(self, text: str, style: str = "") -> None:
        self.lines.append((style, text))


# --- the playback folder ------------------------------------------------------------------

def _frame_file(fr: Frame) -> str:
    return f"{fr.interface}-{fr.count}.{'jpg' if fr.format == 'jpeg' else 'png'}"


def write_playback(rec: Recording, folder: Path) -> None:
    """DIR/inputs.jsonl, and the frames as the files the recording holds (JPEG or PNG).

    The script says it is a recorded run (its first entry, `recorded`): the component then
    knows that an instant without a snapshot of an interface is one the recorded run did
    not have, and a camera snapshot says when its frame was never read then (`unrecorded`):
    a query of what the recording does not hold is written down, not answered as if it
    were recorded (schemas/recording.md, "Playback")."""
    frames: dict[tuple[str, int], Frame] = {}
    for fr in rec.frames:
        if (fr.interface, fr.count) not in frames:
            (folder / _frame_file(fr)).write_bytes(fr.data)
            frames[fr.interface, fr.count] = fr
    cameras = {n for n, spec in rec.interfaces.items()
               if isinstance(spec, Mapping) and spec.get("type") == "camera"}
    ros2 = _Ros2Samples(rec)
    entries: list[tuple[int, dict[str, Any]]] = [(0, {"t": 0, "kind": "recorded"})]
    for s in rec.snapshots:
        values = dict(s.values)
        entry: dict[str, Any] = {"t": s.t, "kind": "snapshot", "interface": s.interface,
                                 "values": values}
        if s.interface in ros2.interfaces:
            ros2.fill(s.t, s.interface, entry)
        elif s.interface in cameras:
            count = values.get("count", 0)
            known = isinstance(count, int) and not isinstance(count, bool)
            seen = frames.get((s.interface, count)) if known else None
            values["frame"] = None if seen is None else _frame_file(seen)
            if seen is not None and seen.crc32 is not None:
                values["crc32"] = seen.crc32  # the component checks the pixels it decodes
            if seen is None and known and count > 0:
                entry["unrecorded"] = ["frame"]  # frames came, this one was never read
        entries.append((s.t, entry))
    for k in rec.skips:
        entries.append((k.t, {"t": k.t, "kind": "skip", "automaton": k.automaton,
                              "deadline": k.deadline, "missed": k.missed}))
    for g in rec.signals:
        entries.append((g.t, {"t": g.t, "kind": "signal", "reason": g.reason,
                              "ticks": g.ticks}))
    entries.sort(key=lambda e: e[0])  # stable: at one instant, snapshots, skips, signals
    with open(folder / "inputs.jsonl", "w", encoding="utf-8") as f:
        for _, entry in entries:
            f.write(json.dumps(entry, separators=(",", ":")) + "\n")


class _Ros2Samples:
    """A ros2 interface's snapshots as a playback takes them: each subscription's entry
    with the CDR of the sample that entered the snapshot at that instant (base64); a
    subscription whose latest sample the recording does not hold is `unrecorded` (a cut,
    a recording made without them): a snippet that reads it gets no evidence."""

    def __init__(self, rec: Recording) -> None:
        self.interfaces = {n for n, spec in rec.interfaces.items()
                           if isinstance(spec, Mapping) and spec.get("type") == "ros2"}
        self.bytes: dict[tuple[int, str, str], bytes] = {}
        for sample in rec.samples:
            topic = rec.topics[sample.topic]
            if topic.role == "subscription":
                self.bytes[(sample.t, topic.interface, topic.name)] = sample.data
        self.held: dict[tuple[str, str], Any] = {}  # the count of the last sample given

    def fill(self, t: int, interface: str, entry: dict[str, Any]) -> None:
        values = entry["values"]
        subs = values.get("subscriptions")
        if not isinstance(subs, Mapping):
            return  # the component refuses it, with the line
        subs = values["subscriptions"] = {n: dict(v) if isinstance(v, Mapping) else v
                                          for n, v in subs.items()}
        lacking = []
        for n, v in subs.items():
            if not isinstance(v, dict):
                continue
            data = self.bytes.get((t, interface, n))
            if data is not None:
                v["cdr"] = base64.b64encode(data).decode("ascii")
                self.held[(interface, n)] = v.get("count")
            elif v.get("count") and self.held.get((interface, n)) != v.get("count"):
                lacking.append(n)  # its latest sample is not in the recording
        if lacking:
            entry["unrecorded"] = lacking


def unanswered(folder: Path) -> dict[str, Any] | None:
    """The first query the recording could not answer (DIR/unanswered.jsonl), if any."""
    for u in read_jsonl(folder / "unanswered.jsonl"):
        if isinstance(u.get("t"), int) and all(isinstance(u.get(k), str)
                                               for k in ("interface", "query", "reason")):
            return u
    return None


def unanswered_text(u: Mapping[str, Any]) -> str:
    """The first query the recording cannot answer, and what it means, in one line."""
    asked = f"at {seconds(int(u['t']))} the model asked {u['interface']}.{u['query']}()"
    reason = u["reason"]
    if reason == "frame":
        what = f"for frame {u.get('count')}, which the recorded run never read"
    elif reason == "instant":
        what = "at an instant the recorded run did not have"
    elif reason == "interface":
        what = "of an interface the recording does not hold"
    else:
        what = f"for `{reason}`, which the recording does not hold"
    return (f"{asked} {what}: the recording holds no evidence from there on (nothing after it "
            "is compared)")


def until_us(rec: Recording) -> int:
    """Where the replay stops: the recorded stop, or the last instant recorded when cut."""
    stop = rec.stop
    if stop is not None and stop.get("reason") == "until" and rec.until_us is not None:
        return rec.until_us
    # +1 us: a signal acted on at the last instant still wins over --until there
    return rec.end_us if rec.cut else rec.end_us + 1


def component_args(rec: Recording, model: Model, folder: Path) -> tuple[list[str], list[str]]:
    """The flags of the replay run, and notes on recorded parameters the model lacks."""
    args = ["--playback", str(folder), "--clock", "virtual", "--trace", str(folder / "trace.jsonl"),
            "--until", format_us(until_us(rec))]
    if rec.time_limit_us is not None:
        args += ["--time-limit", format_us(rec.time_limit_us)]
    if any(r.record.get("ev") == "variables" for r in rec.trace):
        args.append("--trace-variables")
    kinds = {p.name: p.type for p in model.parameters}
    notes = []
    for name, value in rec.parameters.items():
        if name not in kinds:
            notes.append(f"parameter `{name}` (recorded {json.dumps(value)}) is not a parameter "
                         "of this model: left out")
            continue
        text = value if isinstance(value, str) and kinds[name] == "str" else json.dumps(value)
        args += ["--param", f"{name}={text}"]
    return args, notes


# --- comparing ----------------------------------------------------------------------------

def normalise(records: Iterable[Mapping[str, Any]], variables: bool) -> list[dict[str, Any]]:
    """Trace records as compared: the component's name in `start` left out, and the
    `variables` records too when the two languages format values differently."""
    out = []
    for r in records:
        if r.get("ev") == "variables" and not variables:
            continue
        r = dict(r)
        if r.get("ev") == "start":
            r.pop("name", None)
        out.append(r)
    return out


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    out = []
    for line in path.read_text("utf-8", errors="replace").splitlines():
        try:
            obj = json.loads(line)
        except (ValueError, RecursionError):
            continue  # a line the component could not finish (or a value nested too deep)
        if isinstance(obj, dict):
            out.append(obj)
    return out


def first_difference(recorded: Sequence[Any], now: Sequence[Any], cut: bool) -> int | None:
    """The index of the first difference (None: the same); with a cut recording, the replay
    may go on after the recorded records end."""
    for i, (a, b) in enumerate(zip(recorded, now, strict=False)):
        if a != b:
            return i
    if len(now) < len(recorded) or (len(now) > len(recorded) and not cut):
        return min(len(now), len(recorded))
    return None


def active_states(records: Sequence[Mapping[str, Any]]) -> list[str]:
    """The deepest active states after ``records`` (their enters and exits)."""
    active: list[str] = []
    for r in records:
        if r.get("ev") == "enter":
            active.append(str(r["state"]))
        elif r.get("ev") == "exit" and r.get("state") in active:
            active.remove(str(r["state"]))
    return [s for s in active if not any(o.startswith(s + "/") for o in active)]


def find_transition(model: Model | None, source: str, index: int) -> Transition | None:
    if model is None:
        return None
    for s in model.states():
        if s.path == source:
            return s.transitions[index] if 0 <= index < len(s.transitions) else None
    return None


def describe_fire(r: Mapping[str, Any], built: Built | None) -> str:
    text = f"{r.get('from')} -> {r.get('to')}"
    t = find_transition(built.model if built else None, str(r.get("from")), int(r.get("index", -1)))
    if t is None or built is None:
        return text
    why = []
    if t.when is not None:
        cond = " ".join(t.when.text.split())
        why.append(f"when: {cond if len(cond) <= 70 else cond[:67] + '...'}")
    if t.after_us is not None:
        why.append(f"after: {format_us(t.after_us)}")
    where = built.files.get(os.path.normpath(os.path.abspath(t.span.file)),
                            os.path.normpath(t.span.file))
    return f"{text} ({'; '.join(why)}{'; ' if why else ''}{where}:{t.span.line})"


def seconds(us: int) -> str:
    return f"{us / 1e6:.3f} s"


def compare(rec: Recording, now_trace: list[dict[str, Any]], now_commands: list[Command],
            recorded_built: Built | None, now_built: Built, changed: bool, title: str,
            cross: bool, asked: Mapping[str, Any] | None = None) -> Report:
    """The report; with ``asked`` (the first query the recording could not answer), only
    what came before its instant is compared."""
    report = _compare(rec, now_trace, now_commands, recorded_built, now_built, changed, title,
                      cross, None if asked is None else int(asked["t"]))
    if asked is not None:
        report.add(unanswered_text(asked), "yellow")
        report.status = 1
    return report


def _compare(rec: Recording, now_trace: list[dict[str, Any]], now_commands: list[Command],
             recorded_built: Built | None, now_built: Built, changed: bool, title: str,
             cross: bool, cutoff: int | None) -> Report:
    report = Report()
    variables = not cross
    a = normalise((r.record for r in rec.trace), variables)
    b = normalise(now_trace, variables)
    rec_cmds = list(rec.commands)
    cmds_now = list(now_commands)
    if cutoff is not None:  # from the unanswered query on, nothing is evidence
        a = [r for r in a if int(r.get("t", 0)) * 1000 < cutoff]
        b = [r for r in b if int(r.get("t", 0)) * 1000 < cutoff]
        rec_cmds = [c for c in rec_cmds if c.t < cutoff]
        cmds_now = [c for c in cmds_now if c.t < cutoff]
        now_commands = cmds_now
    i = first_difference(a, b, rec.cut)
    if rec.cut:  # the last instant's commands may be partly recorded: compare what was
        before = [c for c in now_commands if c.t < rec.end_us]
        last = [c for c in now_commands if c.t >= rec.end_us]
        cmds_now = before + last[:max(0, len(rec_cmds) - len(before))]
    j = first_difference(rec_cmds, cmds_now, False)
    if i is None and j is None:
        span = f"0-{seconds(rec.end_us)}"
        what = "identical up to the cut" if rec.cut else "identical"
        if cutoff is not None:
            what, span = f"identical up to {seconds(cutoff)}", f"0-{seconds(cutoff)}"
        report.add(f"{title}: {what}: {len(a)} trace records, {len(rec_cmds)} commands, "
                   f"{span}", "bold green")
        return report
    report.status = 1
    trace_ms = _t_ms(a, b, i)
    cmd_ms = _cmd_ms(rec_cmds, cmds_now, j)
    report.add(f"{title}: different", "bold red")
    if i is not None and (j is None or trace_ms <= cmd_ms):
        _trace_difference(report, a, b, i, recorded_built, now_built,
                          until_us(rec) // 1000)
        if changed and j is not None:
            report.add("")
            _command_difference(report, rec_cmds, cmds_now, j, "then at", rec)
            report.add(NOT_EVIDENCE, "yellow")
        elif changed:
            report.add("it commands the vehicle as recorded throughout: the recording stays "
                       "evidence for the whole run", "green")
    else:
        assert j is not None
        _command_difference(report, rec_cmds, cmds_now, j, "at", rec)
        report.add("  the trace is the same up to this command")
        states = active_states(a[:_records_before(a, cmd_ms - 1)])
        if states:
            report.add(f"  active when the instant began: {', '.join(states)}")
        if changed:
            report.add(NOT_EVIDENCE, "yellow")
    if not changed:
        report.add("the recorded model did not do what it did then: a snippet reads something "
                   "the recording does not hold (the wall clock, a file, random numbers: "
                   "docs/recording.md), or the two components differ", "yellow")
    return report


def _t_ms(a: Sequence[Mapping[str, Any]], b: Sequence[Mapping[str, Any]], i: int | None) -> int:
    if i is None:
        return 1 << 62
    ts = [int(x[i]["t"]) for x in (a, b) if i < len(x)]
    return min(ts)


def _cmd_ms(a: Sequence[Command], b: Sequence[Command], j: int | None) -> int:
    if j is None:
        return 1 << 62
    return min(x[j].t for x in (a, b) if j < len(x)) // 1000


def _records_before(records: Sequence[Mapping[str, Any]], ms: int) -> int:
    n = 0
    while n < len(records) and int(records[n]["t"]) <= ms:
        n += 1
    return n


def _trace_difference(report: Report, a: Sequence[Mapping[str, Any]],
                      b: Sequence[Mapping[str, Any]], i: int, recorded_built: Built | None,
                      now_built: Built, end_ms: int) -> None:
    old = a[i] if i < len(a) else None
    new = b[i] if i < len(b) else None
    t = min(int(r["t"]) for r in (old, new) if r is not None)
    states = active_states(a[:i])
    where = f" in {', '.join(states)}" if states else ""
    report.add(f"at {t / 1000:.3f} s{where} (trace record {i + 1}):", "bold")
    old_fire = old is not None and old.get("ev") == "fire"
    new_fire = new is not None and new.get("ev") == "fire"
    if old_fire and old is not None:
        # The recorded run went on as it was until its next transition.
        then = f"nothing then; at {int(old['t']) / 1000:.3f} s " if int(old["t"]) != t else ""
        report.add(f"  recorded: {then}took {describe_fire(old, recorded_built)}", "cyan")
    else:
        report.add(f"  recorded: {_record_text(old)}", "cyan")
    if new_fire and new is not None:
        report.add(f"  now:      took {describe_fire(new, now_built)}", "magenta")
    elif old_fire and old is not None:
        same = _same_transition(old, now_built)
        report.add("  now:      not taken" + (f": {same}" if same else ""), "magenta")
    if not new_fire:
        instead = _record_text(new)
        if new is not None and int(new["t"]) >= end_ms and new.get("ev") in ("exit", "stop"):
            instead += " (the replay reached the end of the recording and stopped)"
        report.add(f"  {'instead:' if old_fire else 'now:    '}  {instead}", "magenta")
    elif not old_fire and new is not None:
        report.add(f"  the transition {new.get('from')} -> {new.get('to')} was not taken "
                   "in the recorded run", "magenta")


def _same_transition(fire: Mapping[str, Any], built: Built) -> str:
    """The transition of ``built`` from the fire's source to its target (the one written
    in the model given), described; "" when it has none."""
    source, target = str(fire.get("from")), str(fire.get("to"))
    for s in built.model.states():
        if s.path == source:
            for t in s.transitions:
                parent = source.rpartition("/")[0]
                if (f"{parent}/{t.target}" if parent else t.target) == target:
                    return describe_fire({"from": source, "to": target, "index": t.index}, built)
    return ""


def _record_text(r: Mapping[str, Any] | None) -> str:
    """A trace record in words: `exit Climb`, `log in Climb: "text"`, `stop (final)`."""
    if r is None:
        return "(no more records)"
    ev = r.get("ev")
    if ev in ("enter", "exit"):
        text = f"{ev} {r.get('state')}"
    elif ev == "fire":
        text = f"took {r.get('from')} -> {r.get('to')}"
    elif ev == "log":
        text = f"log in {r.get('state') or 'on_shutdown'}: {json.dumps(r.get('msg'))}"
    elif ev == "stop":
        text = f"stop ({r.get('reason')})"
    elif ev == "interrupt":
        text = f"interrupt ({r.get('reason')}) to {r.get('to')}"
    elif ev == "error":
        text = f"error in {r.get('state')}'s {r.get('snippet')}"
    else:
        return json.dumps(r, separators=(",", ":"))
    return f"at {int(r.get('t', 0)) / 1000:.3f} s: {text}"


def _command_difference(report: Report, a: Sequence[Command], b: Sequence[Command], j: int,
                        lead: str, rec: Recording | None = None) -> None:
    old = a[j] if j < len(a) else None
    new = b[j] if j < len(b) else None
    t = min(c.t for c in (old, new) if c is not None)
    report.add(f"{lead} {seconds(t)} (command {j + 1}):", "bold")
    report.add(f"  recorded: {_command_text(old, rec)}")
    report.add(f"  now:      {_command_text(new, rec)}")


def _command_text(c: Command | None, rec: Recording | None = None) -> str:
    if c is None:
        return "(no more commands)"
    text = _publish_text(c, rec) if rec is not None and c.call == "publish" else None
    if rec is not None and c.call in ("send_goal", "call"):
        text = _rpc_text(c, rec)
    return f"{text or c.text()} at {seconds(c.t)}"


def _rpc_text(c: Command, rec: Recording) -> str | None:
    """A goal or a request decoded as ``_publish_text`` does, by the action's or the
    service's type in the recording's wiring (hfsmc's definitions of it)."""
    if len(c.args) != 2 or not all(isinstance(a, str) for a in c.args):
        return None
    spec = rec.interfaces.get(c.interface)
    options = spec.get("options") if isinstance(spec, Mapping) else None
    table = options.get("actions" if c.call == "send_goal" else "services") \
        if isinstance(options, Mapping) else None
    entry = table.get(c.args[0]) if isinstance(table, Mapping) else None
    if not isinstance(entry, Mapping) or not isinstance(entry.get("type"), str):
        return None
    kind = f"{entry['type']}_{'Goal' if c.call == 'send_goal' else 'Request'}"
    try:
        from hfsmc.ros2.definitions import rosbags_store

        store = rosbags_store(str(options.get("distro") or "jazzy"))  # type: ignore[union-attr]
        msg = store.deserialize_cdr(base64.b64decode(c.args[1], validate=True), kind)
    except Exception:  # a type or bytes hfsmc does not know: the raw text then
        return None
    fields = ", ".join(f"{k}={v!r}" for k, v in _fields(msg, ""))
    short = entry["type"].rsplit("/", 1)[1] + (".Goal" if c.call == "send_goal" else ".Request")
    return f"{c.interface}.{c.call}({json.dumps(c.args[0])}, {short}({fields}))"


def _publish_text(c: Command, rec: Recording) -> str | None:
    """A ros2 publish with its message decoded from the CDR (its fields that are not
    zero), by the definition the recording holds: ``robot.publish("cmd_vel",
    Twist(linear.x=0.4))``; None when it cannot be decoded (the base64 is shown)."""
    if len(c.args) != 2 or not all(isinstance(a, str) for a in c.args):
        return None
    topic = next((t for t in rec.topics if t.interface == c.interface
                  and t.role == "publication" and t.name == c.args[0]), None)
    if topic is None:
        return None
    try:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(topic.definition, topic.type))
        msg = store.deserialize_cdr(base64.b64decode(c.args[1], validate=True), topic.type)
    except Exception:  # bytes or a definition rosbags refuses: the raw text then
        return None
    fields = ", ".join(f"{k}={v!r}" for k, v in _fields(msg, ""))
    return (f"{c.interface}.publish({json.dumps(c.args[0])}, "
            f"{topic.type.rsplit('/', 1)[1]}({fields}))")


def _fields(msg: Any, prefix: str) -> list[tuple[str, Any]]:
    """A rosbags message's fields that are not zero or empty, nested ones dotted."""
    out: list[tuple[str, Any]] = []
    for name in getattr(msg, "__dataclass_fields__", {}):
        if name == "__msgtype__":
            continue
        v = getattr(msg, name)
        if hasattr(v, "__dataclass_fields__"):
            out.extend(_fields(v, f"{prefix}{name}."))
        elif hasattr(v, "tolist"):
            if len(v):
                out.append((f"{prefix}{name}", v.tolist()))
        elif v:
            out.append((f"{prefix}{name}", v))
    return out


# --- the command --------------------------------------------------------------------------

def replay(recording: str, model_arg: str | None, target: str | None,
           allow_code: bool = False) -> Report:
    """Replay ``recording`` against ``model_arg`` or, with ``allow_code``, the recorded
    model; raise NotAllowed (neither: the lines say what the recording carries),
    RecordingError, ReplayFailed, HfsmcError, UsageError."""
    report = Report()
    try:
        return _replay(recording, model_arg, target, allow_code, report)
    except ReplayFailed as e:
        e.report = report
        raise


def _replay(recording: str, model_arg: str | None, target: str | None, allow_code: bool,
            report: Report) -> Report:
    rec = read_recording(recording)  # its model hash checked against its sources
    if model_arg is None and not allow_code:
        raise NotAllowed(what_it_carries(rec, recording))
    if rec.cut:
        report.add(f"the recording ends at {seconds(rec.end_us)} (cut: the component did not "
                   "close it)", "yellow")
    recorded_built: Built | None = None
    try:
        recorded_built = recorded_model(rec)  # as data: in memory, nothing runs
    except HfsmcError:
        if model_arg is None:
            raise
    if model_arg is not None:
        now_built, notes = given_model(rec, model_arg)
        for n in notes:
            report.add(n, "" if now_built.recorded else "yellow")
    else:
        assert recorded_built is not None
        now_built = recorded_built
    language = now_built.model.language
    if target is not None and target != language:
        raise UsageError(f"-t {target}: the snippets of {now_built.label} are {language}; "
                         f"give the model's {target} twin with --model")
    target = language
    changed = not now_built.recorded
    command = build(now_built, target, model_arg, rec)
    with tempfile.TemporaryDirectory(prefix="hfsmc-replay-") as tmp:
        folder = Path(tmp)
        write_playback(rec, folder)
        args, notes = component_args(rec, now_built.model, folder)
        for n in notes:
            report.add(n, "yellow")
        with open(folder / "component.log", "wb") as log:
            proc = subprocess.run([*command, *args], stdout=log, stderr=subprocess.STDOUT,
                                  stdin=subprocess.DEVNULL, cwd=folder, check=False)
        out = (folder / "component.log").read_text("utf-8", errors="replace")
        trace = read_jsonl(folder / "trace.jsonl")
        if proc.returncode not in (0, 1, 124, 130, 143) or not trace:
            raise ReplayFailed(f"the component failed (exit status {proc.returncode})",
                               out.strip().splitlines()[-12:])
        commands = [Command(int(c.get("t", 0)), str(c.get("interface", "")),
                            str(c.get("call", "")), tuple(c.get("args", ())))
                    for c in read_jsonl(folder / "commands.jsonl")]
        asked = unanswered(folder)
    title = f"replay of {recording} ({rec.language} -> {target})"
    result = compare(rec, trace, commands, recorded_built, now_built, changed, title,
                     cross=rec.language != target, asked=asked)
    report.lines.extend(result.lines)
    report.status = result.status
    return report


def render(report: Report, out: Any = None) -> None:
    """Print the report: with colours on a terminal, plain text otherwise."""
    from rich.console import Console
    from rich.text import Text

    console = Console(file=out or sys.stdout, highlight=False, soft_wrap=True)
    for style, text in report.lines:
        console.print(Text(text, style=style or ""))
