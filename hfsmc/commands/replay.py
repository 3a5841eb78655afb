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

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hfsmc.durations import format_us
from hfsmc.errors import HfsmcError, UsageError
from hfsmc.fsutil import write_atomic
from hfsmc.ir import Model, Transition
from hfsmc.pipeline import Result, compile_file
from hfsmc.recording import Command, Frame, Recording, RecordingError, read_recording

NOT_EVIDENCE = ("from here on the vehicle would have been commanded differently: "
                "the recording is no longer evidence")


class ReplayFailed(Exception):
    """Replay could not run (a model that does not compile, a component that failed)."""

    def __init__(self, message: str, details: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.details = tuple(details)
        self.report: Report | None = None  # what was said before it failed


@dataclass
class Report:
    """What replay found: the lines to print (style, text) and the exit status."""

    lines: list[tuple[str, str]] = field(default_factory=list)
    status: int = 0

    def add(self, text: str, style: str = "") -> None:
        self.lines.append((style, text))


# --- the model ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Built:
    model: Model
    label: str  # how the report names it
    recorded: bool  # the recorded model (same hash)
    files: Mapping[str, str]  # a model file's path as spans give it -> as the report shows it


def write_sources(sources: Sequence[tuple[str, str]], base: Path) -> Path:
    """Write the recorded sources below ``base`` keeping their relative paths (a used file
    may be `../lib/x.yaml`: the model goes deep enough); return the model file's path."""
    ups = 0
    for path, _ in sources:
        parts = Path(path).parts
        if Path(path).is_absolute():
            raise RecordingError(f"a source path is absolute: `{path}`")
        depth = 0
        for part in parts:
            depth += -1 if part == ".." else (0 if part == "." else 1)
            ups = max(ups, -depth)
    home = base.joinpath("src", *(["m"] * ups))
    root = os.path.realpath(base / "src")
    for path, text in sources:
        target = home / path
        if not os.path.realpath(target).startswith(root + os.sep):
            raise RecordingError(f"a source path leaves the model's tree: `{path}`")
        target.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(target, text)  # a replay of the same recording beside it reads whole files
    return home / sources[0][0]


def _compile(path: str) -> Result:
    result = compile_file(path)
    if not result.ok or result.model is None:
        raise HfsmcError(result.diagnostics)
    return result


def cache_base() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hfsmc" / "replay"


def recorded_model(rec: Recording) -> Built:
    """The recorded model, compiled from the text the recording holds."""
    base = cache_base() / rec.model_hash.removeprefix("sha256:")[:16]
    main = write_sources(rec.sources, base)
    result = _compile(str(main))
    assert result.model is not None
    home = main.parent
    files = {os.path.normpath(home / p): p for p, _ in rec.sources}
    return Built(result.model, f"the recorded model ({rec.sources[0][0]})", True, files)


def given_model(rec: Recording, path: str) -> tuple[Built, list[str]]:
    """The model of ``--model``, and what the report says of it against the recorded one."""
    from hfsmc.model_sources import model_hash, model_sources

    result = compile_file(path)
    if not result.ok or result.model is None:
        raise HfsmcError(result.diagnostics)
    sources = model_sources(result.model)
    digest = model_hash(sources)
    same = digest == rec.model_hash
    if same:
        notes = [f"{path} is the recorded model ({digest[:19]}...)"]
    elif result.model.language != rec.language:
        notes = [f"{path} is a {result.model.language} model, the recorded one "
                 f"({rec.sources[0][0]}) {rec.language}: replayed as its twin"]
    else:
        recorded = dict(rec.sources)
        main = sources[0][0]
        if main != rec.sources[0][0]:  # the model file itself, whatever its name now
            recorded.pop(rec.sources[0][0])
            recorded[main] = rec.sources[0][1]
        changed = [p for p, text in sources if p in recorded and recorded[p] != text]
        new = [p for p, _ in sources if p not in recorded]
        gone = [p for p in recorded if p not in dict(sources)]
        what = "; ".join(x for x in (
            f"changed: {', '.join(changed)}" if changed else "",
            f"not in the recording: {', '.join(new)}" if new else "",
            f"recorded but not used now: {', '.join(gone)}" if gone else "") if x)
        notes = [f"{path} is not the recorded model ({what or 'other paths'}; hash "
                 f"{digest[:19]}... against the recorded {rec.model_hash[:19]}...)"]
    return Built(result.model, path, same, {}), notes


def build(built: Built, target: str, model_arg: str | None, rec: Recording) -> list[str]:
    """Write (and for C++ compile) the component; its command line."""
    from hfsmc.component import cache_folder, write_component

    model = built.model
    if model_arg is not None:
        folder = cache_folder(model_arg, model.name + ("-cpp" if target == "cpp" else ""))
    else:
        folder = cache_base() / rec.model_hash.removeprefix("sha256:")[:16] / target
    written = write_component(model, target, folder)
    if target == "python":
        return [sys.executable, str(written.main)]
    from hfsmc.cppcompile import compile_component

    diags = compile_component(folder, model.file)
    if any(d.severity == "error" for d in diags):
        raise ReplayFailed("the C++ component did not build",
                           [f"{d.span}: {d.message}" for d in diags][:10])
    return [str(written.main)]


# --- the playback folder ------------------------------------------------------------------

def _frame_file(fr: Frame) -> str:
    return f"{fr.interface}-{fr.count}.{'jpg' if fr.format == 'jpeg' else 'png'}"


def write_playback(rec: Recording, folder: Path) -> None:
    """DIR/inputs.jsonl, and the frames as the files the recording holds (JPEG or PNG)."""
    frames: dict[tuple[str, int], Frame] = {}
    for fr in rec.frames:
        if (fr.interface, fr.count) not in frames:
            (folder / _frame_file(fr)).write_bytes(fr.data)
            frames[fr.interface, fr.count] = fr
    cameras = {n for n, spec in rec.interfaces.items()
               if isinstance(spec, Mapping) and spec.get("type") == "camera"}
    entries: list[tuple[int, dict[str, Any]]] = []
    for s in rec.snapshots:
        values = dict(s.values)
        if s.interface in cameras:
            seen = frames.get((s.interface, int(values.get("count", 0))))
            values["frame"] = None if seen is None else _frame_file(seen)
            if seen is not None and seen.crc32 is not None:
                values["crc32"] = seen.crc32  # the component checks the pixels it decodes
        entries.append((s.t, {"t": s.t, "kind": "snapshot", "interface": s.interface,
                              "values": values}))
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
        except ValueError:
            continue  # a line the component could not finish
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
            cross: bool) -> Report:
    report = Report()
    variables = not cross
    a = normalise((r.record for r in rec.trace), variables)
    b = normalise(now_trace, variables)
    i = first_difference(a, b, rec.cut)
    rec_cmds = list(rec.commands)
    cmds_now = list(now_commands)
    if rec.cut:  # the last instant's commands may be partly recorded: compare what was
        before = [c for c in now_commands if c.t < rec.end_us]
        last = [c for c in now_commands if c.t >= rec.end_us]
        cmds_now = before + last[:max(0, len(rec_cmds) - len(before))]
    j = first_difference(rec_cmds, cmds_now, False)
    if i is None and j is None:
        span = f"0-{seconds(rec.end_us)}"
        what = "identical up to the cut" if rec.cut else "identical"
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
            _command_difference(report, rec_cmds, cmds_now, j, "then at")
            report.add(NOT_EVIDENCE, "yellow")
        elif changed:
            report.add("it commands the vehicle as recorded throughout: the recording stays "
                       "evidence for the whole run", "green")
    else:
        assert j is not None
        _command_difference(report, rec_cmds, cmds_now, j, "at")
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
                        lead: str) -> None:
    old = a[j] if j < len(a) else None
    new = b[j] if j < len(b) else None
    t = min(c.t for c in (old, new) if c is not None)
    report.add(f"{lead} {seconds(t)} (command {j + 1}):", "bold")
    report.add(f"  recorded: {_command_text(old)}")
    report.add(f"  now:      {_command_text(new)}")


def _command_text(c: Command | None) -> str:
    return "(no more commands)" if c is None else f"{c.text()} at {seconds(c.t)}"


# --- the command --------------------------------------------------------------------------

def replay(recording: str, model_arg: str | None, target: str | None) -> Report:
    """Replay ``recording``; raise RecordingError, ReplayFailed, HfsmcError, UsageError."""
    report = Report()
    try:
        return _replay(recording, model_arg, target, report)
    except ReplayFailed as e:
        e.report = report
        raise


def _replay(recording: str, model_arg: str | None, target: str | None,
            report: Report) -> Report:
    rec = read_recording(recording)
    if rec.cut:
        report.add(f"the recording ends at {seconds(rec.end_us)} (cut: the component did not "
                   "close it)", "yellow")
    recorded_built: Built | None = None
    try:
        recorded_built = recorded_model(rec)
    except (HfsmcError, RecordingError):
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
    command = build(now_built, target, model_arg if model_arg is not None else None, rec)
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
    title = f"replay of {recording} ({rec.language} -> {target})"
    result = compare(rec, trace, commands, recorded_built, now_built, changed, title,
                     cross=rec.language != target)
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
