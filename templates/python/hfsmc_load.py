# hfsmc_load.py: what a component does as it loads, before it runs.
# Copied unchanged into every component folder; standard library only.
"""The instances of used files (`use`), each its module in a namespace of its own,
bound at start to the using namespace; and the report of an import or `functions`
code that failed when the component was loaded."""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Sequence
from typing import Any

from hfsmc_runtime import Engine  # type: ignore[import-not-found]  # beside the component


def load_failure(engine: Engine, early: tuple[BaseException, int, str | None, str]) -> int:
    """An import or the `functions` code failed when the component was loaded: exit 1."""
    exc, where, text, file = early
    if text is not None:  # an import: `where` is its model line
        what = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        sys.stderr.write(f"{file}:{where}: error: cannot import `{text}`: {what}\n")
    else:
        sys.stderr.write(engine.report(exc, where))
    return 1


def load_instance(engine: Engine, here: str, unit: str, number: int, base: int, sid0: int,
                  prefix: str, where: str, values: dict[str, Any],
                  links: Sequence[tuple[str, str, str]], parent: dict[str, Any]) -> Any:
    """One instance of a used file (`use`): its module loaded into a namespace of its own,
    with the helpers, its parameters (``values``: literals and defaults; ``links``:
    (name, the using namespace's parameter, type), bound again at start by
    ``bind_instances`` once --param is read) and its interfaces (bound at start)."""
    import importlib.util
    path = os.path.join(here, f"{unit}.py")
    spec = importlib.util.spec_from_file_location(f"{unit}_{number}", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    ns = module.__dict__
    ns.update(_hfsm=engine, _hfsm_BASE=base, _hfsm_SID0=sid0, log=engine.log,
              elapsed=engine.elapsed, now=engine.now, done=engine.done,
              active=engine.active_below(prefix, where), shutdown=engine.shutdown)
    ns.update(values)
    for name, source, kind in links:
        ns[name] = _bound(parent.get(source), kind)
    spec.loader.exec_module(module)
    return module


def _bound(value: Any, kind: str) -> Any:
    return float(value) if kind == "float" and isinstance(value, int) else value


def bind_instances(engine: Engine) -> None:
    """At start, once parameters and interfaces are set: each instance's `$NAME` parameters
    and its interfaces take the using namespace's (parents first)."""
    spaces = [engine.m["namespace"]]
    for inst in engine.m["instances"]:
        ns = inst["module"].__dict__
        parent = spaces[inst["parent"]]
        for name, source, kind in inst["links"]:
            ns[name] = _bound(parent.get(source), kind)
        for name, source in inst["interfaces"]:
            ns[name] = parent.get(source)
        spaces.append(ns)
