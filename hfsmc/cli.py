"""The ``hfsmc`` command line: thin, it prints diagnostics and sets the exit status.

Exit status: 0 clean (warnings allowed), 1 model errors, 2 usage errors.  A
Python traceback is shown only with ``--verbose``; without it an unexpected
crash is reported in one line as an internal error.
"""

from __future__ import annotations

import sys
import traceback
from collections.abc import Callable, Iterable
from functools import wraps
from pathlib import Path
from typing import Any, TypeVar

import click

from hfsmc import __version__
from hfsmc.commands import completion
from hfsmc.errors import Diagnostic, HfsmcError, UsageError, render_json, render_text
from hfsmc.pipeline import Result, compile_file

F = TypeVar("F", bound=Callable[..., Any])


def _guard(fn: F) -> F:
    """Turn hfsmc errors into diagnostics and any other crash into one line."""

    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        verbose = bool(click.get_current_context().find_root().params.get("verbose"))
        try:
            return fn(*args, **kwargs)
        except (click.exceptions.Exit, click.ClickException, click.Abort):
            raise
        except UsageError as e:
            click.echo(f"hfsmc: error: {e}", err=True)
            sys.exit(2)
        except HfsmcError as e:
            _print(e.diagnostics, {}, "text")
            sys.exit(1)
        except KeyboardInterrupt:
            sys.exit(130)
        except Exception as e:  # a bug: say so in one line, traceback only on request
            if verbose:
                traceback.print_exc()
            click.echo(f"hfsmc: internal error: {type(e).__name__}: {e} "
                       "(please report it; --verbose shows the traceback)", err=True)
            sys.exit(3)

    return wrapper  # type: ignore[return-value]


def _print(diags: Iterable[Diagnostic], sources: dict[str, list[str]], fmt: str) -> None:
    diags = list(diags)
    if fmt == "json":
        click.echo(render_json(diags), nl=False)
    elif diags:
        click.echo(render_text(diags, sources, color=sys.stderr.isatty()), err=True, nl=False)


def _compile_or_exit(path: str) -> Result:
    """Compile one model; print its diagnostics; exit 1 when it has errors."""
    result = compile_file(path)
    _print(result.diagnostics, result.sources, "text")
    if not result.ok:
        sys.exit(1)
    return result


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="hfsmc")
@click.option("--verbose", is_flag=True, help="Show tracebacks of internal errors.")
def main(verbose: bool) -> None:
    """Compile hierarchical finite state machines into robot components."""


@main.command()
@click.argument("models", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text",
              help="Diagnostics as compiler text (stderr) or JSON (stdout).")
@click.option("--strict", is_flag=True, help="Warnings fail the check too.")
@click.option("--dump-ir", is_flag=True, help="Print the lowered IR of each clean model.")
@click.option("--no-cxx", is_flag=True, help="Do not compile the snippets of C++ models with g++.")
@_guard
def check(models: tuple[str, ...], fmt: str, strict: bool, dump_ir: bool, no_cxx: bool) -> None:
    """Parse, validate and check MODELS; print every problem of every model.

    The snippets of a `language: cpp` model are compiled too (g++ -fsyntax-only
    over the generated code; a cache in $HFSMC_CACHE_DIR or ~/.cache/hfsmc/cxx
    keeps that short), unless --no-cxx."""
    from hfsmc.emit.ir_text import dump

    results = [compile_file(m, cxx=not no_cxx) for m in models]
    for note in dict.fromkeys(n for r in results for n in r.notes):
        click.echo(f"hfsmc: note: {note}", err=True)
    all_diags = [d for r in results for d in r.diagnostics]
    _print(all_diags, {k: v for r in results for k, v in r.sources.items()}, fmt)
    if dump_ir:
        for r in results:
            if r.model is not None:
                click.echo(dump(r.model), nl=False)
    failed = any(not r.ok for r in results) or (strict and any(all_diags))
    if fmt == "text":
        errors = sum(d.severity == "error" for d in all_diags)
        warnings = len(all_diags) - errors
        if all_diags:
            click.echo(f"{len(models)} model(s): {errors} error(s), {warnings} warning(s)", err=True)
    sys.exit(1 if failed else 0)


@main.command()
@click.argument("model", type=click.Path(dir_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="OUT.svg, OUT.png or OUT.dot (default: MODEL's name with .svg).")
@click.option("--state", "state_path", metavar="PATH",
              help="Draw only this state's sub-automaton or regions, or one region (Flight/Altitude).",
              shell_complete=completion.complete_state)
@click.option("--rankdir", type=click.Choice(["auto", "LR", "TB"], case_sensitive=False),
              default="auto", show_default=True,
              help="Arrows left to right (LR) or top to bottom (TB); auto: LR when that fits "
                   "a 1920x1080 screen, else the direction that overflows it less.")
@click.option("--depth", type=click.IntRange(min=0), metavar="N",
              help="Draw composite states more than N levels down as one node "
                   "(0: only the top level's states).")
@click.option("--depfile", type=click.Path(dir_okay=False),
              help="Also write a make depfile: the drawing depends on MODEL and the files "
                   "its states use.")
@_guard
def diagram(model: str, output: str | None, state_path: str | None, rankdir: str,
            depth: int | None, depfile: str | None) -> None:
    """Draw MODEL with Graphviz: sub-automata as nested clusters, arrows numbered in the
    order they are tried, the direction chosen to fit a screen."""
    from hfsmc.emit.dot import font_warning, write_diagram

    # Errors inside snippets do not change the picture: a model being written, or a legacy
    # file whose code never ran, is still drawn (the errors are shown; check still fails).
    result = compile_file(model)
    _print(result.diagnostics, result.sources, "text")
    drawn = result.model if result.ok else (
        result.structure if result.errors_only_in_snippets else None)
    if drawn is None:
        sys.exit(1)
    out = Path(output) if output else Path(model).with_suffix(".svg")
    write_diagram(drawn, out, state_path, rankdir=rankdir, depth=depth)
    warning = font_warning() if out.suffix.lower() in (".svg", ".png") else None
    if warning:
        click.echo(f"hfsmc: warning: {warning}", err=True)
    if depfile:
        from hfsmc.component import write_depfile

        write_depfile(Path(depfile), [str(out)], drawn)
    note = "" if result.ok else " (drawn although its snippets have errors: check fails)"
    click.echo(f"wrote {out}{note}", err=True)


@main.command()
@click.argument("source", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="OUT.yaml or OUT.xml; an existing YAML file is edited in place (comments kept).")
@click.option("--strict", is_flag=True,
              help="Legacy files: refuse when their code has errors (default: convert, and "
                   "report them as W220 warnings to fix in the new model).")
@_guard
def convert(source: str, output: str, strict: bool) -> None:
    """Convert SOURCE between YAML and XML (and legacy XML to version 1)."""
    from hfsmc.commands.convert import compile_for_convert, convert_model

    result = compile_for_convert(source, strict)
    _print(result.diagnostics, result.sources, "text")
    if not result.ok:
        sys.exit(1)
    assert result.model is not None
    for line in convert_model(result, Path(output)):
        click.echo(line, err=True)


@main.command()
@click.argument("model", type=click.Path(dir_okay=False))
@click.option("-t", "--target", type=click.Choice(["python", "cpp"]), default="python",
              show_default=True, help="The language of the component.")
@click.option("-o", "--output", type=click.Path(file_okay=False),
              help="The component folder (default: build/NAME).")
@click.option("--compile", "compile_", is_flag=True, help="C++: also run CMake and the compiler.")
@click.option("--depfile", type=click.Path(dir_okay=False),
              help="Also write a make depfile: the component's files depend on MODEL "
                   "and the files it uses.")
@click.option("--dump-ir", is_flag=True, help="Print the lowered IR first.")
@_guard
def build(model: str, target: str, output: str | None, compile_: bool, depfile: str | None,
          dump_ir: bool) -> None:
    """Write the component of MODEL: only files whose content changed are rewritten."""
    from hfsmc.component import write_component

    result = _compile_or_exit(model)
    assert result.model is not None
    if dump_ir:
        from hfsmc.emit.ir_text import dump

        click.echo(dump(result.model), nl=False)
    folder = Path(output) if output else Path("build") / result.model.name
    built = write_component(result.model, target, folder, Path(depfile) if depfile else None)
    what = f"{len(built.changed)} of {len(built.files)} file(s) written" if built.changed \
        else "up to date"
    click.echo(f"{built.folder}: {what}; run {built.main}", err=True)
    if compile_ and target == "cpp":
        from hfsmc.cppcompile import compile_component

        diags = compile_component(folder, result.model.file)
        _print(diags, result.sources, "text")
        if any(d.severity == "error" for d in diags):
            click.echo(f"{built.folder}: the C++ build failed; the previous executable, if any, "
                       "is kept", err=True)
            sys.exit(1)
        click.echo(f"{built.main}: built", err=True)


@main.command(context_settings={"ignore_unknown_options": True})
@click.argument("model", type=click.Path(dir_okay=False))
@click.argument("args", nargs=-1, type=click.UNPROCESSED,
                shell_complete=completion.complete_run_args)
@_guard
def run(model: str, args: tuple[str, ...]) -> None:
    """Build MODEL's component into a cache and run it with ARGS (after --).

    A `language: cpp` model is compiled with CMake first (incrementally)."""
    import os

    from hfsmc.component import cache_folder, write_component

    result = _compile_or_exit(model)
    assert result.model is not None
    target = "cpp" if result.model.language == "cpp" else "python"
    folder = cache_folder(model, result.model.name + ("-cpp" if target == "cpp" else ""))
    built = write_component(result.model, target, folder)
    if target == "cpp":
        from hfsmc.cppcompile import compile_component

        diags = compile_component(folder, result.model.file)
        _print(diags, result.sources, "text")
        if any(d.severity == "error" for d in diags):
            sys.exit(1)
        sys.stderr.flush()
        os.execv(built.main, [str(built.main), *args])
    sys.stderr.flush()
    os.execv(sys.executable, [sys.executable, str(built.main), *args])


@main.command()
@click.argument("target", required=False, metavar="[HOST:]PORT")
@click.option("--replay", metavar="TRACE", type=click.Path(dir_okay=False),
              help="Play a trace file (written with --trace) instead of watching a component.")
@click.option("--model", metavar="MODEL", type=click.Path(dir_okay=False),
              help="With --replay: take the whole tree from the model, not only the states seen. "
                   "With --web: draw the diagram from it (conditions and timers on the arrows).")
@click.option("--speed", type=float, default=1.0, show_default=True,
              help="With --replay: times real time; 0 shows the end at once. With --web "
                   "--replay: the speed the page starts with.")
@click.option("--focus", metavar="PATH", help="Show only this state's sub-automaton.",
              shell_complete=completion.complete_focus)
@click.option("--no-autofocus", is_flag=True, help="Show every branch, not only the active ones.")
@click.option("--web", metavar="[HOST:]PORT",
              help="Serve a web page that draws the component live (or plays --replay), on "
                   "loopback unless a host is named (port 0 picks one), to whoever opens the "
                   "URL it prints (with its token); see docs/web.md.")
@click.option("--allow-host", "allow_hosts", metavar="NAME", multiple=True,
              help="With --web: also serve the page under this host name or address (as "
                   "another machine reaches it); repeatable. Loopback names always work.")
@click.option("--world", metavar="WORLD.yaml", type=click.Path(dir_okay=False),
              help="With --web: draw this ground world's walls and boxes under a ros2 "
                   "interface's odometry map (hfsmc sim --robot diffdrive's world file).")
@_guard
def view(target: str | None, replay: str | None, model: str | None, speed: float,
         focus: str | None, no_autofocus: bool, web: str | None,
         allow_hosts: tuple[str, ...], world: str | None) -> None:
    """Watch a component started with --monitor [HOST:]PORT, or replay a trace."""
    from hfsmc.commands.view import view as run_view

    sys.exit(run_view(target, replay, focus=focus, autofocus=not no_autofocus, speed=speed,
                      model=model, web=web, allow_hosts=allow_hosts, world=world))


@main.command()
@click.argument("recording", type=click.Path(dir_okay=False))
@click.option("--model", "model_arg", metavar="MODEL", type=click.Path(dir_okay=False),
              help="Replay against this model (yours: the recorded one, a changed version, or "
                   "the twin in the other language).")
@click.option("--allow-recorded-code", "allow_code", is_flag=True,
              help="Build and run the model the recording carries (its snippets are code: "
                   "only for a recording you trust).")
@click.option("-t", "--target", type=click.Choice(["python", "cpp"]),
              help="The component's language (default: the model's; the recorded model's is "
                   "the recording's).")
@_guard
def replay(recording: str, model_arg: str | None, allow_code: bool, target: str | None) -> None:
    """Run a recorded run again (a component's --record FILE) on the virtual clock, fed from
    the recording, and compare its trace and commands with the recorded ones.

    A recording is data: its model is built and run only with --allow-recorded-code; with
    neither that nor --model, the replay says what the recording carries and stops.

    Exit status 0: identical; 1: different (the first difference is shown), not run
    (neither --model nor --allow-recorded-code), or the recording cannot be replayed."""
    from hfsmc.commands.replay import NotAllowed, ReplayFailed, render
    from hfsmc.commands.replay import replay as run_replay
    from hfsmc.recording import RecordingError

    try:
        report = run_replay(recording, model_arg, target, allow_code)
    except NotAllowed as e:
        for line in e.args[0]:
            click.echo(line)
        click.echo("hfsmc replay: not run: a recording's model is code, built and run only "
                   "when asked (--model MODEL or --allow-recorded-code)", err=True)
        sys.exit(1)
    except RecordingError as e:
        click.echo(f"{recording}: {e}", err=True)
        sys.exit(1)
    except ReplayFailed as e:
        if e.report is not None:
            render(e.report)  # type: ignore[arg-type]
        click.echo(f"hfsmc replay: {e}", err=True)
        for line in e.details:
            click.echo(f"  {line}", err=True)
        sys.exit(1)
    render(report)
    sys.exit(report.status)


@main.group()
def export() -> None:
    """Write what a recording holds in another tool's format."""


@export.command("rosbag")
@click.argument("recording", type=click.Path(dir_okay=False))
@click.argument("folder", metavar="DIR", type=click.Path())
@_guard
def export_rosbag(recording: str, folder: str) -> None:
    """Write RECORDING's ROS 2 topics (a ros2 interface's subscriptions and publishes, the
    bytes that went over the wire) as a rosbag2 with MCAP storage in DIR, a new or empty
    folder, which `ros2 bag` and rosbags read (docs/ros2.md, "Recordings").

    Exit status 0: written; 1: the recording holds no topics, cannot be read, or DIR is
    not new or empty."""
    from hfsmc.commands.export import ExportError
    from hfsmc.commands.export import export_rosbag as run_export
    from hfsmc.recording import RecordingError

    try:
        done = run_export(recording, folder)
    except RecordingError as e:
        click.echo(f"hfsmc export: {recording}: {e}", err=True)
        sys.exit(1)
    except ExportError as e:
        click.echo(f"hfsmc export: {e}", err=True)
        sys.exit(1)
    span = (done.end_ns - done.start_ns) / 1e9
    click.echo(f"{done.folder}: rosbag2 (mcap), {len(done.topics)} topics, "
               f"{sum(n for *_, n in done.topics)} messages over {span:.3f} s")
    for topic, kind, n in done.topics:
        click.echo(f"  {topic} ({kind}): {n}")


@main.command("test")
@click.argument("scenarios", nargs=-1, required=True, type=click.Path())
@click.option("-t", "--target", type=click.Choice(["python", "cpp"]),
              help="Run only this language's models (default: every language a scenario names).")
@click.option("--allow-recorded-code", "allow_code", is_flag=True,
              help="Replay a recording (*.mcap) with the model it carries, built and run (only "
                   "for recordings you trust), rather than the model file of its name beside it.")
@click.option("--junit", metavar="FILE", type=click.Path(dir_okay=False),
              help="Also write a JUnit XML report (for CI).")
@click.option("--keep", metavar="DIR", type=click.Path(file_okay=False),
              help="Keep each run's folder (inputs, trace, commands, stderr) under DIR.")
@click.option("--timeout", type=click.FloatRange(min=0, min_open=True), default=300.0,
              show_default=True, help="Seconds of real time a run may take before it is killed.")
@_guard
def test(scenarios: tuple[str, ...], target: str | None, allow_code: bool, junit: str | None,
         keep: str | None, timeout: float) -> None:
    """Run models against scenario files (scripted inputs, expectations) on the virtual clock.

    SCENARIOS are scenario files (YAML), recordings (*.mcap: they pass when their replay
    against the model file of their model's name, beside them, is identical) or folders
    (searched for the *.yaml and *.mcap files of folders named tests, and test_*.yaml,
    *_test.yaml). One line per scenario and language, then the failures (docs/testing.md).
    Exit status: 0 all passed, 1 a scenario failed, 2 a scenario, its model or a recording
    has errors."""
    from hfsmc.commands.scenario_run import run_all

    sys.exit(run_all(list(scenarios), target, junit, keep, timeout, click.echo,
                     lambda s: click.echo(s, err=True), sys.stdout.isatty(),
                     allow_code=allow_code))


@main.command(cls=completion.SimCommand,
              context_settings={"ignore_unknown_options": True, "help_option_names": []})
@click.argument("args", nargs=-1, type=click.UNPROCESSED,
                shell_complete=completion.complete_sim_args)
@_guard
def sim(args: tuple[str, ...]) -> None:
    """Simulated multicopter (MAVLink over UDP) and its camera (MJPEG over HTTP).

    `hfsmc sim --help` lists its options (--world WORLD.yaml, --seed, --truth FILE, ...).
    """
    from hfsmc.sim.run import main as run_sim

    sys.exit(run_sim(list(args)))


@main.command()
@click.argument("model", type=click.Path(dir_okay=False))
@click.option("--web", metavar="[HOST:]PORT", default="127.0.0.1:0", show_default=True,
              help="Serve the editor's page there (loopback unless a host is named; port 0 "
                   "picks a free one). Open the URL it prints, with its token.")
@click.option("--monitor", metavar="[HOST:]PORT",
              help="Show the component running with --monitor there: its active states lit "
                   "on the canvas and in the tree, editing paused until Resume editing.")
@_guard
def edit(model: str, web: str, monitor: str | None) -> None:
    """Edit MODEL in a browser page (docs/editor.md): a canvas per sub-automaton, the state
    tree, code editors for snippets and conditions, errors on what they are about, undo,
    redo; Save changes only the edited lines; Build and run, and the running component's
    states lit (--monitor)."""
    from hfsmc.commands.edit import edit as run_edit

    sys.exit(run_edit(model, web, monitor))


@main.command()
@click.option("--stdio", is_flag=True, help="Speak on stdin/stdout (the default; editors pass it).")
def lsp(stdio: bool) -> None:
    """Language server for model files on stdio (docs/editors.md): diagnostics as you type,
    definition, references, rename, completion, hover, symbols, quick fixes."""
    try:
        from hfsmc.lsp.server import main as serve
    except ImportError as e:
        raise click.ClickException(f"the language server needs the `lsp` extra "
                                   f"(pip install 'hfsmc[lsp]'): {e}") from None
    serve()
