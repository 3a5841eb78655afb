"""`hfsmc test SCENARIO...`: run models against scripted inputs and check what they do.

Each scenario (hfsmc/scenario.py) is run once per language it names: its
inputs become a playback folder (hfsmc/scenario_inputs.py), the model's
component runs with ``--playback DIR`` on the virtual clock, and its trace and
commands are checked (hfsmc/scenario_check.py).  Components are built once per
model into the same cache as `hfsmc run` (a C++ one compiled incrementally).
The report is pytest's shape: one line per scenario and language, then the
failures; ``--junit FILE`` writes JUnit XML for CI.  Exit status: 0 every run
passed, 1 a run failed, 2 a scenario or a model could not be run.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from hfsmc.durations import format_us
from hfsmc.errors import Diagnostic, Diagnostics, HfsmcError, UsageError
from hfsmc.ir import Model
from hfsmc.pipeline import Result, compile_file
from hfsmc.scenario import (
    Language,
    Scenario,
    ScenarioError,
    check_against_model,
    grid_us,
    read_scenario,
)
from hfsmc.scenario_check import Failure, Run, check, model_errors, read_records
from hfsmc.scenario_inputs import write_playback

Echo = Callable[[str], None]


@dataclass
class Outcome:
    """One scenario run in one language."""

    file: str
    name: str
    language: str
    failures: list[Failure] = field(default_factory=list)
    seconds: float = 0.0
    folder: Path | None = None  # the run's folder, when kept
    stderr_tail: tuple[str, ...] = ()

    @property
    def id(self) -> str:
        return f"{self.file}::{self.language}"

    @property
    def passed(self) -> bool:
        return not self.failures


@dataclass
class Problems:
    """What stops scenarios from running: diagnostics and the files they point into."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    sources: dict[str, list[str]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


@dataclass
class Prepared:
    scenario: Scenario
    models: dict[Language, Model]


@dataclass
class Recorded:
    """A recording given as a scenario: it passes when its replay is identical."""

    path: str
    language: str


def prepare_recordings(paths: list[str], only: str | None, problems: Problems) -> list[Recorded]:
    """Check that each recording can be read; the ones to replay (in their own language)."""
    from hfsmc.recording import RecordingError, read_recording

    out = []
    for path in paths:
        try:
            rec = read_recording(path)
        except RecordingError as e:
            problems.notes.append(f"{path}: {e}")
            continue
        language = str(rec.run.get("language", "python"))
        if only is None or only == language:
            out.append(Recorded(path, language))
    return out


def run_recording(r: Recorded) -> Outcome:
    """`hfsmc replay` of one recording: identical passes, the first difference fails."""
    from hfsmc.commands.replay import ReplayFailed, replay
    from hfsmc.recording import RecordingError

    started = time.monotonic()
    outcome = Outcome(r.path, Path(r.path).stem, r.language)
    try:
        report = replay(r.path, None, None)
        if report.status != 0:
            outcome.failures.append(Failure(None, "the replay differs from the recording",
                                            tuple(text for _, text in report.lines)))
    except ReplayFailed as e:
        outcome.failures.append(Failure(None, f"the replay failed: {e}", e.details))
    except (RecordingError, HfsmcError, UsageError) as e:
        outcome.failures.append(Failure(None, f"the replay failed: {e}"))
    outcome.seconds = time.monotonic() - started
    return outcome


def prepare(paths: list[str], only: str | None, problems: Problems) -> list[Prepared]:
    """Read the scenarios and compile their models; every problem goes to ``problems``."""
    compiled: dict[str, Result] = {}
    out: list[Prepared] = []
    for path in paths:
        diags = Diagnostics()
        try:
            sc = read_scenario(path, diags)
        except HfsmcError as e:
            diags.extend(e.diagnostics)
            sc = None
        if sc is None:
            problems.diagnostics.extend(diags.sorted())
            problems.sources.update(_lines_of(path))
            continue
        problems.sources[sc.file] = list(sc.lines)
        models: dict[Language, Model] = {}
        for lang in sc.languages:
            if only is not None and lang != only:
                continue
            ref = sc.model_for(lang)
            if ref.path not in compiled:
                compiled[ref.path] = compile_file(ref.path)
            result = compiled[ref.path]
            problems.sources.update(result.sources)
            if not result.ok or result.model is None:
                problems.diagnostics.extend(result.diagnostics)
                continue
            if result.model.language != lang:
                diags.error("E194", f"`{ref.path}` is a {result.model.language} model, "
                            f"given for {lang}", ref.span)
                continue
            check_against_model(sc, result.model, diags)
            models[lang] = result.model
        problems.diagnostics.extend(diags.sorted())
        if not diags.has_errors and models:
            out.append(Prepared(sc, models))
    return out


def _lines_of(path: str) -> dict[str, list[str]]:
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return {path: f.read(1 << 20).splitlines()}
    except OSError:
        return {}


# ---------------------------------------------------------------------------
# building


@dataclass(frozen=True)
class Component:
    command: tuple[str, ...]


def build(model: Model, language: Language, problems: Problems, echo: Echo) -> Component | None:
    """The component of ``model``, written (and compiled) into `hfsmc run`'s cache."""
    from hfsmc.component import cache_folder, write_component

    folder = cache_folder(model.file, model.name + ("-cpp" if language == "cpp" else ""))
    built = write_component(model, language, folder)
    if language == "python":
        return Component((sys.executable, str(built.main)))
    from hfsmc.cppcompile import compile_component

    started = time.monotonic()
    diags = compile_component(folder, model.file)
    errors = [d for d in diags if d.severity == "error"]
    if errors:
        problems.diagnostics.extend(errors)
        return None
    took = time.monotonic() - started
    if took > 2:
        echo(f"built {model.name} (C++) in {took:.1f} s")
    return Component((str(built.main),))


# ---------------------------------------------------------------------------
# running


def run_one(sc: Scenario, model: Model, language: str, component: Component, folder: Path,
            timeout: float) -> Outcome:
    """Run ``sc`` against one built component in ``folder``; check it."""
    started = time.monotonic()
    outcome = Outcome(sc.file, sc.name, language)
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    types = {i.name: i.type for i in model.interfaces}
    write_playback(sc, types, grid_us([model]), folder)
    trace = folder / "trace.jsonl"
    args = [*component.command, "--playback", str(folder.resolve()), "--clock", "virtual",
            "--trace", str(trace.resolve()), "--until", format_us(sc.until_us)]
    if sc.time_limit_us is not None:
        args += ["--time-limit", format_us(sc.time_limit_us)]
    for o in sc.parameters:
        value = ("true" if o.value else "false") if isinstance(o.value, bool) else str(o.value)
        args += ["--param", f"{o.name}={value}"]
    status: int | None = None
    with open(folder / "stderr.txt", "wb") as err, open(folder / "stdout.txt", "wb") as out:
        try:
            proc = subprocess.run(args, cwd=folder, stdout=out, stderr=err, stdin=subprocess.DEVNULL,
                                  timeout=timeout, check=False)
            status = proc.returncode
        except subprocess.TimeoutExpired:
            outcome.failures.append(Failure(None, f"the component did not stop within {timeout:g} s "
                                            "of real time (killed)"))
    stderr = (folder / "stderr.txt").read_text("utf-8", errors="replace").splitlines()
    text = trace.read_text("utf-8", errors="replace") if trace.is_file() else ""
    commands_file = folder / "commands.jsonl"
    commands = commands_file.read_text("utf-8", errors="replace") if commands_file.is_file() else ""
    run = Run(read_records(text), read_records(commands), "trace.jsonl", status,
              model_errors(stderr))
    if status is not None:
        outcome.failures.extend(check(sc, run))
    if outcome.failures and (status not in (0, 1, 124) or not run.trace
                             or any(f.expectation is None for f in outcome.failures)):
        outcome.stderr_tail = tuple(stderr[-12:])
    outcome.seconds = time.monotonic() - started
    return outcome


def run_all(paths: list[str], only: str | None, junit: str | None, keep: str | None,
            timeout: float, echo: Echo, echo_err: Echo, color: bool) -> int:
    """The whole command; returns the exit status."""
    started = time.monotonic()
    problems = Problems()
    recordings = [p for p in paths if p.endswith(".mcap")]
    prepared = prepare([p for p in paths if not p.endswith(".mcap")], only, problems)
    recorded = prepare_recordings(recordings, only, problems) if recordings else []
    if not problems.diagnostics:
        components: dict[tuple[str, str], Component | None] = {}
        for p in prepared:
            for lang, model in p.models.items():
                key = (model.file, lang)
                if key not in components:
                    components[key] = build(model, lang, problems, echo_err)
    if problems.diagnostics or problems.notes:
        from hfsmc.errors import render_text

        if problems.diagnostics:
            echo_err(render_text(problems.diagnostics, problems.sources, color).rstrip("\n"))
        for note in problems.notes:
            echo_err(note)
        count = sum(d.severity == "error" for d in problems.diagnostics) + len(problems.notes)
        echo_err(f"hfsmc test: {count} error(s): no scenario was run")
        return 2
    if not prepared and not recorded:
        echo_err("hfsmc test: no scenario to run" + (f" in {only}" if only else ""))
        return 2
    base = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="hfsmc-test-"))
    outcomes: list[Outcome] = []
    try:
        for i, p in enumerate(prepared):
            for lang, model in p.models.items():
                comp = components[(model.file, lang)]
                assert comp is not None
                folder = base / f"{i:02d}-{Path(p.scenario.file).stem}-{lang}"
                try:
                    o = run_one(p.scenario, model, lang, comp, folder, timeout)
                except ScenarioError as e:  # a picture or a world that cannot be read
                    from hfsmc.errors import render_text

                    echo_err(render_text(e.diagnostics, {p.scenario.file: list(p.scenario.lines)},
                                         color).rstrip("\n"))
                    return 2
                o.folder = folder if keep else None
                outcomes.append(o)
                _say(o, echo, color)
        for r in recorded:
            o = run_recording(r)
            outcomes.append(o)
            _say(o, echo, color)
    finally:
        if not keep:
            shutil.rmtree(base, ignore_errors=True)
    report(outcomes, time.monotonic() - started, echo, color)
    if not keep and any(not o.passed for o in outcomes):
        echo("(--keep DIR keeps each run's inputs.jsonl, trace.jsonl, commands.jsonl and stderr.txt)")
    if junit:
        write_junit(Path(junit), outcomes)
    return 0 if all(o.passed for o in outcomes) else 1


def _say(o: Outcome, echo: Echo, color: bool) -> None:
    word = _tint("PASSED", "32", color) if o.passed else _tint("FAILED", "31", color)
    echo(f"{o.id} {word}")


def _tint(text: str, code: str, color: bool) -> str:
    return f"\x1b[{code}m{text}\x1b[0m" if color else text


def _rule(title: str, fill: str = "=") -> str:
    width = max(60, min(100, shutil.get_terminal_size((80, 24)).columns))
    title = f" {title} "
    left = (width - len(title)) // 2
    return fill * left + title + fill * max(0, width - left - len(title))


def report(outcomes: list[Outcome], seconds: float, echo: Echo, color: bool) -> None:
    failed = [o for o in outcomes if not o.passed]
    if failed:
        echo(_rule("FAILURES"))
        for o in failed:
            echo(_rule(o.id, "_"))
            for line in failure_lines(o):
                echo(line)
    passed = len(outcomes) - len(failed)
    words = ", ".join(w for w in (f"{len(failed)} failed" if failed else "",
                                  f"{passed} passed" if passed else "") if w)
    echo(_tint(_rule(f"{words} in {seconds:.2f}s"), "31" if failed else "32", color))


def failure_lines(o: Outcome) -> list[str]:
    """A failed run's lines: each broken expectation at its scenario line, then the records."""
    out = []
    for f in o.failures:
        x = f.expectation
        if x is not None:
            out.append(f"{x.span}: expected {x.describe()}")
            out.append(f"  got: {f.message}")
        else:
            out.append(f"{o.file}: {f.message}")
        out.extend(f"    {r}" for r in f.records)
    if o.stderr_tail:
        out.append("  the component's last lines on stderr:")
        out.extend(f"    {ln}" for ln in o.stderr_tail)
    if o.folder is not None:
        out.append(f"  run folder: {o.folder} (inputs.jsonl, trace.jsonl, commands.jsonl, stderr.txt)")
    return out


def write_junit(path: Path, outcomes: list[Outcome]) -> None:
    """JUnit XML (testsuites/testsuite/testcase/failure), as CI tools read it."""
    failed = sum(not o.passed for o in outcomes)
    total = sum(o.seconds for o in outcomes)
    suites = ET.Element("testsuites", name="hfsmc test", tests=str(len(outcomes)),
                        failures=str(failed), errors="0", time=f"{total:.3f}")
    suite = ET.SubElement(suites, "testsuite", name="hfsmc test", tests=str(len(outcomes)),
                          failures=str(failed), errors="0", skipped="0", time=f"{total:.3f}")
    for o in outcomes:
        case = ET.SubElement(suite, "testcase", classname=_classname(o.file),
                             name=f"{o.name}[{o.language}]", file=o.file, time=f"{o.seconds:.3f}")
        if not o.passed:
            first = o.failures[0]
            message = (f"expected {first.expectation.describe()}: {first.message}"
                       if first.expectation else first.message)
            fail = ET.SubElement(case, "failure", message=message, type="expectation")
            fail.text = "\n".join(failure_lines(o))
    ET.indent(suites)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = ET.tostring(suites, encoding="unicode", xml_declaration=False)
    path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n' + data + "\n", encoding="utf-8")


def _classname(file: str) -> str:
    """The file's path as a dotted name (relative to the current folder when inside it)."""
    p = Path(file).resolve().with_suffix("")
    if p.is_relative_to(Path.cwd()):
        p = p.relative_to(Path.cwd())
    return ".".join(part for part in p.parts if part not in ("..", ".", os.sep)) or p.name


__all__ = ["ScenarioError", "run_all"]
