"""`hfsmc test SCENARIO...`: run models against scripted inputs and check what they do.

Each scenario (hfsmc/scenario.py) is run once per language it names: its
inputs become a playback folder (hfsmc/scenario_inputs.py), the model's
component runs with ``--playback DIR`` on the virtual clock, and its trace and
commands are checked (hfsmc/scenario_check.py).  Components are built once per
model into the same cache as `hfsmc run` (a C++ one compiled incrementally).
The report is pytest's shape: one line per scenario and language, then the
failures; ``--junit FILE`` writes JUnit XML for CI.  Exit status: 0 every run
passed, 1 a run failed, 2 a scenario or a model could not be run.

A recording (``*.mcap``) is replayed against the model file of its recorded name in its
folder (or the folder above), never with the code it carries unless
``--allow-recorded-code`` says so; one that cannot be replayed is an ERROR of its own and
the others still run.  A folder stands for the scenarios in it (``find_scenarios``).
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
from hfsmc.scenario_ros2 import Topics

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
    errored: bool = False  # it could not be run (a recording that cannot be replayed)

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
    model: str | None  # the model replayed (None: the recorded one, --allow-recorded-code)
    error: str | None = None  # why it cannot be replayed


SKIPPED_FOLDERS = ("build", "dist", "node_modules", "venv", "__pycache__")


def find_scenarios(paths: list[str]) -> tuple[list[str], list[str]]:
    """Each folder of ``paths`` replaced by the scenarios below it, as pytest collects
    tests: in folders named `tests`, every *.yaml, *.yml and *.mcap file; anywhere,
    test_*.yaml and *_test.yaml; folders starting with `.` or `_` and build folders
    skipped.  Also the folders in which nothing was found."""
    out: list[str] = []
    empty: list[str] = []
    for path in paths:
        if not os.path.isdir(path):
            out.append(path)
            continue
        found = []
        for folder, dirs, files in os.walk(path):
            dirs[:] = sorted(d for d in dirs
                             if not d.startswith((".", "_")) and d not in SKIPPED_FOLDERS)
            in_tests = "tests" in Path(folder).relative_to(path).parts or (
                Path(folder).name == "tests")
            for name in sorted(files):
                stem, ext = os.path.splitext(name)
                if (in_tests and ext in (".yaml", ".yml", ".mcap")) or (
                        ext in (".yaml", ".yml") and (stem.startswith("test_")
                                                      or stem.endswith("_test"))):
                    found.append(os.path.join(folder, name))
        out.extend(found)
        if not found:
            empty.append(path)
    return out, empty


def recorded_model_file(rec_path: str, name: str) -> str | None:
    """The model file of the recorded name (`follow_colors.yaml`: a file name, checked on
    reading) in the recording's folder, or the folder above (a recording kept in tests/)."""
    here = Path(rec_path).parent
    for folder in (here, here.parent):
        candidate = folder / name
        if candidate.is_file():
            return str(candidate)
    return None


def prepare_recordings(paths: list[str], only: str | None, allow_code: bool) -> list[Recorded]:
    """Each recording to replay, with its model; one that cannot be read or has no model
    to replay with is kept with its error, to be reported as such (the others still run)."""
    from hfsmc.commands.replay_model import ALLOW_FLAG
    from hfsmc.pipeline import compile_file
    from hfsmc.recording import RecordingError, read_recording

    out = []
    for path in paths:
        try:
            rec = read_recording(path)
        except RecordingError as e:
            out.append(Recorded(path, only or "python", None, str(e)))
            continue
        except Exception as e:  # anything else a forged file does: this one errs, not the run
            out.append(Recorded(path, only or "python", None, f"cannot be read: {e!r}"[:200]))
            continue
        if allow_code:
            if only is None or only == rec.language:
                out.append(Recorded(path, rec.language, None))
            continue
        name = rec.sources[0][0]
        model = recorded_model_file(path, name)
        if model is None:
            out.append(Recorded(path, only or rec.language, None, (
                f"no model `{name}` beside it to replay it with (a recording's own model is "
                f"code, run only with {ALLOW_FLAG}; or hfsmc replay {path} --model MODEL)")))
            continue
        result = compile_file(model)
        language = result.model.language if result.model is not None else rec.language
        if only is None or only == language:
            out.append(Recorded(path, language, model))
    return out


def run_recording(r: Recorded) -> Outcome:
    """`hfsmc replay` of one recording: identical passes, the first difference fails; a
    recording that cannot be replayed errs."""
    from hfsmc.commands.replay import NotAllowed, ReplayFailed, replay
    from hfsmc.recording import RecordingError

    started = time.monotonic()
    outcome = Outcome(r.path, Path(r.path).stem, r.language)
    try:
        if r.error is not None:
            raise RecordingError(r.error)
        report = replay(r.path, r.model, None, allow_code=r.model is None)
        if report.status != 0:
            outcome.failures.append(Failure(None, "the replay differs from the recording",
                                            tuple(text for _, text in report.lines)))
    except ReplayFailed as e:
        outcome.errored = True
        outcome.failures.append(Failure(None, f"the replay failed: {e}", e.details))
    except (RecordingError, HfsmcError, UsageError, NotAllowed) as e:
        outcome.errored = True
        outcome.failures.append(Failure(None, f"cannot be replayed: {_one_line(e)}"))
    except Exception as e:  # a bug, or a file that finds one: this run errs, not the others
        outcome.errored = True
        outcome.failures.append(Failure(None, f"cannot be replayed: internal error: "
                                        f"{type(e).__name__}: {e}"[:300]))
    outcome.seconds = time.monotonic() - started
    return outcome


def _one_line(e: Exception) -> str:
    if isinstance(e, HfsmcError) and e.diagnostics:
        d = e.diagnostics[0]
        return f"{d.span}: {d.message}"
    return " ".join(str(e).split())


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
    topics = Topics(model) if "ros2" in types.values() else None
    drivers = {i.name: dict(i.declaration.snapshot) for i in model.interfaces
               if i.type == "driver" and i.declaration is not None}
    write_playback(sc, types, grid_us([model]), folder, topics, drivers)
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
              model_errors(stderr), topics)
    if status is not None:
        outcome.failures.extend(check(sc, run))
    if outcome.failures and (status not in (0, 1, 124) or not run.trace
                             or any(f.expectation is None for f in outcome.failures)):
        outcome.stderr_tail = tuple(stderr[-12:])
    outcome.seconds = time.monotonic() - started
    return outcome


def run_all(paths: list[str], only: str | None, junit: str | None, keep: str | None,
            timeout: float, echo: Echo, echo_err: Echo, color: bool,
            allow_code: bool = False) -> int:
    """The whole command; returns the exit status."""
    started = time.monotonic()
    problems = Problems()
    paths, empty = find_scenarios(paths)
    for where in empty:
        echo_err(f"hfsmc test: no scenario in {where} (docs/testing.md: the files of folders "
                 "named tests, test_*.yaml, *_test.yaml)")
    recordings = [p for p in paths if p.endswith(".mcap")]
    prepared = prepare([p for p in paths if not p.endswith(".mcap")], only, problems)
    recorded = prepare_recordings(recordings, only, allow_code) if recordings else []
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
                    o = Outcome(p.scenario.file, p.scenario.name, lang, errored=True)
                    o.failures.append(Failure(None, "its inputs cannot be read (above)"))
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
    if not keep and any(not o.passed and not o.errored for o in outcomes):
        echo("(--keep DIR keeps each run's inputs.jsonl, trace.jsonl, commands.jsonl and stderr.txt)")
    if junit:
        write_junit(Path(junit), outcomes)
    if any(o.errored for o in outcomes):
        return 2
    return 0 if all(o.passed for o in outcomes) else 1


def _say(o: Outcome, echo: Echo, color: bool) -> None:
    word = (_tint("PASSED", "32", color) if o.passed else
            _tint("ERROR", "31", color) if o.errored else _tint("FAILED", "31", color))
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
    for title, group in (("ERRORS", [o for o in failed if o.errored]),
                         ("FAILURES", [o for o in failed if not o.errored])):
        if group:
            echo(_rule(title))
        for o in group:
            echo(_rule(o.id, "_"))
            for line in failure_lines(o):
                echo(line)
    errors = sum(o.errored for o in failed)
    passed = len(outcomes) - len(failed)
    words = ", ".join(w for w in (f"{len(failed) - errors} failed" if len(failed) > errors else "",
                                  f"{passed} passed" if passed else "",
                                  f"{errors} error{'s' if errors > 1 else ''}" if errors else "")
                      if w)
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
    errors = sum(o.errored for o in outcomes)
    failed = sum(not o.passed for o in outcomes) - errors
    total = sum(o.seconds for o in outcomes)
    suites = ET.Element("testsuites", name="hfsmc test", tests=str(len(outcomes)),
                        failures=str(failed), errors=str(errors), time=f"{total:.3f}")
    suite = ET.SubElement(suites, "testsuite", name="hfsmc test", tests=str(len(outcomes)),
                          failures=str(failed), errors=str(errors), skipped="0",
                          time=f"{total:.3f}")
    for o in outcomes:
        case = ET.SubElement(suite, "testcase", classname=_classname(o.file),
                             name=f"{o.name}[{o.language}]", file=o.file, time=f"{o.seconds:.3f}")
        if not o.passed:
            first = o.failures[0]
            message = (f"expected {first.expectation.describe()}: {first.message}"
                       if first.expectation else first.message)
            fail = ET.SubElement(case, "error" if o.errored else "failure", message=message,
                                 type="replay" if o.errored else "expectation")
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
