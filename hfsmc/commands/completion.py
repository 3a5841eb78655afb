"""Shell completion of the command line, through click's own protocol.

``eval "$(_HFSMC_COMPLETE=bash_source hfsmc)"`` turns it on (README.md, "Shell
completion"). Beyond click's completion of commands and options, this module
completes what click cannot know:

- state paths for ``hfsmc diagram MODEL --state``, ``hfsmc view --focus`` (from
  ``--model``, else from the ``--replay`` trace) and ``hfsmc run MODEL --
  --focus``, read from the model: composite states and regions (``Mission/Watch``),
  through the instances of used files (``TakeOff/Hold``);
- the component's flags after ``hfsmc run MODEL --``;
- the simulator's options and file arguments in ``hfsmc sim``.

A completion never prints a diagnostic and never fails: a model that does
not compile, or a file that cannot be read, completes nothing.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from importlib.resources import files
from itertools import islice

import click
from click.shell_completion import CompletionItem

_FILE_FLAGS = {"--config", "--trace"}  # component flags whose value is a file
_CHOICES = {"--clock": ("real", "virtual"), "--displaygui": ("true", "false")}
_SIM_FILE_OPTIONS = {"--world", "--truth"}
_TRACE_LINES = 200_000  # enough for the paths of any trace, bounded for a huge one


def state_paths(model: str | None, regions: bool = False) -> list[str]:
    """Paths of the composite states of ``model`` (those ``--state`` and ``--focus``
    take), in model order, with ``regions`` their regions' paths too (``--state``
    draws a region); [] when it does not compile."""
    if not model:
        return []
    try:
        from hfsmc.pipeline import compile_file

        result = compile_file(model, cxx=False)  # no g++ run for a Tab
        if result.model is None:
            return []
        return [path for s in result.model.states() if s.automata
                for path in (s.path, *(a.path for a in s.automata if regions and s.parallel))]
    except Exception:  # completion must never show a traceback
        return []


def trace_paths(trace: str | None) -> list[str]:
    """Paths of the states of a trace that have children (entered below them)."""
    if not trace:
        return []
    seen: dict[str, None] = {}
    try:
        with open(trace, encoding="utf-8", errors="replace") as f:
            for line in islice(f, _TRACE_LINES):
                try:
                    rec = json.loads(line)
                except ValueError:
                    continue
                state = rec.get("state") if isinstance(rec, dict) else None
                if rec.get("ev") == "enter" and isinstance(state, str) and "/" in state:
                    seen[state.rpartition("/")[0]] = None
    except OSError:
        return []
    return list(seen)


def _matching(words: Iterable[str], incomplete: str) -> list[CompletionItem]:
    return [CompletionItem(w) for w in words if w.startswith(incomplete)]


def _model_argument(ctx: click.Context) -> str | None:
    """MODEL as given on the line. While an option waits for its value, click
    leaves the arguments unparsed in ``ctx.args``: MODEL is the first of them."""
    model = ctx.params.get("model")
    if model:
        return str(model)
    return next((a for a in ctx.args if not a.startswith("-")), None)


def complete_state(ctx: click.Context, param: click.Parameter,
                   incomplete: str) -> list[CompletionItem]:
    """``--state`` of ``hfsmc diagram``: the composite states and regions of MODEL."""
    return _matching(state_paths(_model_argument(ctx), regions=True), incomplete)


def complete_focus(ctx: click.Context, param: click.Parameter,
                   incomplete: str) -> list[CompletionItem]:
    """``--focus`` of ``hfsmc view``: from ``--model``, else from the ``--replay`` trace
    (whose regions are among the paths with children)."""
    paths = state_paths(ctx.params.get("model"), regions=True) or trace_paths(ctx.params.get("replay"))
    return _matching(paths, incomplete)


def component_flags() -> list[str]:
    """The flags a component takes, read from the Python runtime's argument parser
    (the C++ component takes the same ones)."""
    try:
        text = files("hfsmc.templates.python").joinpath("hfsmc_main.py").read_text("utf-8")
    except OSError:
        return []
    return list(dict.fromkeys(re.findall(r"add_argument\(\s*\"(--[a-z][a-z-]*)\"", text)))


def complete_run_args(ctx: click.Context, param: click.Parameter,
                      incomplete: str) -> list[CompletionItem]:
    """The component's flags after ``hfsmc run MODEL --``, and their values."""
    before: tuple[str, ...] = tuple(ctx.params.get(param.name or "") or ())
    last = before[-1] if before else ""
    if last == "--focus":  # a component's --focus takes a region too
        return _matching(state_paths(ctx.params.get("model"), regions=True), incomplete)
    if last in _FILE_FLAGS:
        return [CompletionItem(incomplete, type="file")]
    if last in _CHOICES:
        return _matching(_CHOICES[last], incomplete)
    if incomplete.startswith("-"):
        return _matching(component_flags(), incomplete)
    return []


def _sim_options() -> list[str]:
    try:
        from hfsmc.sim.run import parser
    except Exception:  # the simulator's dependencies missing: nothing to offer
        return []
    return [o for action in parser()._actions for o in action.option_strings
            if o.startswith("--")]


def complete_sim_args(ctx: click.Context, param: click.Parameter,
                      incomplete: str) -> list[CompletionItem]:
    """Values of ``hfsmc sim`` options: files for ``--world`` and ``--truth``."""
    before: tuple[str, ...] = tuple(ctx.params.get(param.name or "") or ())
    if before and before[-1] in _SIM_FILE_OPTIONS:
        return [CompletionItem(incomplete, type="file")]
    if incomplete.startswith("-"):
        return _matching(_sim_options(), incomplete)
    return []


class SimCommand(click.Command):
    """``hfsmc sim``: its options belong to the simulator's own argument parser,
    so their names complete from there."""

    def shell_complete(self, ctx: click.Context, incomplete: str) -> list[CompletionItem]:
        return _matching(_sim_options(), incomplete)
