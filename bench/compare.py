#!/usr/bin/env python3
"""Per-tick cost of the generated components of two hfsmc revisions, side by side.

Builds the speed models of ``bench/models/`` (flat and nested, bare and counted; the
Python side also the 21-sub-automaton chain20) with the hfsmc of two source trees
(``--base``, a checkout of another revision, and this one, or ``--here``), then times
them interleaved, in the same run: round 1 of every model on both sides (base first
in odd rounds, here first in even ones), then round 2, ... On a shared, noisy machine
that keeps both sides under the same load; the figures are medians of the rounds and
the ratio is the median of the rounds' ratios (here / base).

* Python: each timed run is a child process that imports the component, runs it once
  unmeasured (warm-up), imports it afresh and runs ``Engine.run("virtual", ...)``
  timed in its own process CPU time (``time.process_time_ns``): ns per instant, which
  for flat and nested is ns per transition, as in ``component.py``.
* C++: as in ``cpp.py``, the difference of the children's CPU times (``wait4``) of a
  small and a large ``--clock virtual`` run over the difference of instants.
* Both, with valgrind: instructions per instant under callgrind (the difference of two
  runs as processes: C++ 100,000 and 200,000 instants, Python 2,000 and 12,000 with a
  fixed hash seed), which do not move with the load (``--no-callgrind`` skips them).

Usage::

    git clone -q . /tmp/benchold && git -C /tmp/benchold checkout -q REV
    ln -s ../templates /tmp/benchold/hfsmc/templates   # see below
    python bench/compare.py --base /tmp/benchold [--rounds 7] [--only python|cpp]

hfsmc reads its templates as the package ``hfsmc.templates``, which an editable
install maps to the installed tree's ``templates/``: a tree given here must have
``hfsmc/templates`` (a symbolic link to ``../templates``) so that its own templates
are used; the script checks it and says so otherwise.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cpp import Proc, model_name, run  # bench/cpp.py, beside this script
from report import loadavg, machine, merge_json, table

HERE = Path(__file__).resolve().parent
MODELS = HERE / "models"
WORK = HERE / "_work" / "compare"
KEY = "revision_compare"
SIDES = ("base", "here")
PY_MODELS = ("flat", "flat_counted", "nested", "nested_counted", "chain20")
CPP_MODELS = ("flat", "flat_counted", "nested", "nested_counted")
PERIOD_MS = {"chain20": 100}  # of the root, when not 1 ms


@dataclass
class Case:
    """One model in one language, on both sides."""

    lang: str  # python, cpp
    model: str
    target: dict[str, Path] = field(default_factory=dict)  # side -> NAME.py or executable
    sizes: tuple[int, int] = (0, 0)  # instants: python (0, n); cpp (small, large)
    ns: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in SIDES})
    ratios: list[float] = field(default_factory=list)  # here / base, per round
    instructions: dict[str, float | None] = field(default_factory=dict)


def tree_env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree)}


def check_tree(tree: Path) -> str:
    """The tree's commit; stop unless its hfsmc (templates included) is the one imported."""
    probe = subprocess.run([sys.executable, "-c",
                            "import hfsmc, hfsmc.templates as t; "
                            "print(hfsmc.__file__); print(list(t.__path__)[0])"],
                           capture_output=True, text=True, env=tree_env(tree), cwd=tree)
    lines = probe.stdout.split()
    if probe.returncode != 0 or len(lines) != 2 or \
            not all(Path(p).resolve().is_relative_to(tree.resolve()) for p in lines):
        raise SystemExit(f"{tree}: its own hfsmc is not the one imported (got {lines}); "
                         f"ln -s ../templates {tree}/hfsmc/templates")
    rev = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True)
    return rev.stdout.strip() or "?"


def build(tree: Path, side: str, lang: str, model: str) -> Path:
    src = MODELS / (f"{model}.yaml" if lang == "python" else f"{model}.cpp.yaml")
    out = WORK / side / f"{lang}_{model}"
    p = subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", lang, str(src), "-o",
                        str(out)], capture_output=True, text=True, env=tree_env(tree), cwd=tree)
    if p.returncode != 0:
        raise SystemExit(f"{side}: hfsmc build -t {lang} {src.name} failed:\n{p.stderr}")
    name = model_name(src)
    if lang == "python":
        return out / f"{name}.py"
    for cmd in (["cmake", "-S", str(out), "-B", str(out / "build"), "-DCMAKE_BUILD_TYPE=Release"],
                ["cmake", "--build", str(out / "build")]):
        q = run(cmd)
        if q.status != 0:
            raise SystemExit(f"{side}: {' '.join(cmd)} failed:\n{(q.out + q.err)[-3000:]}")
    return out / "build" / name


# ---------------------------------------------------------------------------
# Python: a child process per timed run
# ---------------------------------------------------------------------------

def py_worker(path: Path, n: int) -> int:
    """Child: warm-up run, then a fresh import timed over n instants; print JSON."""
    def load(k: int) -> Any:
        spec = importlib.util.spec_from_file_location(f"_cmp_{k}", path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    warm = load(0)
    period = warm._hfsm.period_us[0]
    warm._hfsm.run("virtual", (min(n, 2000) - 1) * period)
    del warm
    module = load(1)
    gc.collect()
    w0, c0 = time.perf_counter_ns(), time.process_time_ns()
    module._hfsm.run("virtual", (n - 1) * period)
    c1, w1 = time.process_time_ns(), time.perf_counter_ns()
    eng = module._hfsm
    if eng.status != 0 or eng.t != (n - 1) * period:
        print(json.dumps({"error": f"status {eng.status}, t {eng.t}"}))
        return 1
    print(json.dumps({"cpu_ns": c1 - c0, "wall_ns": w1 - w0, "instants": n}))
    return 0


def py_timed(path: Path, n: int) -> float:
    """ns of CPU per instant of one child run."""
    p = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--py-worker",
                        str(path), str(n)], capture_output=True, text=True)
    try:
        data = json.loads(p.stdout.strip().splitlines()[-1])
        return float(data["cpu_ns"]) / int(data["instants"])
    except (IndexError, KeyError, ValueError) as e:
        raise SystemExit(f"{path} ({n} instants): {p.stdout}{p.stderr} ({e})") from None


def py_calibrate(case: Case, seconds: float) -> None:
    per = py_timed(case.target["here"], 5000)
    case.sizes = (0, max(5000, int(seconds * 1e9 / per)))


# ---------------------------------------------------------------------------
# C++: difference of two runs' CPU times
# ---------------------------------------------------------------------------

def cpp_run(exe: Path, n: int) -> Proc:
    p = run([str(exe), "--clock", "virtual", "--until", f"{n - 1}ms"])
    if p.status != 0:
        raise SystemExit(f"{exe} ({n} instants): exit {p.status}\n{p.err[-2000:]}")
    return p


def cpp_timed(exe: Path, small: int, large: int) -> float:
    a, b = cpp_run(exe, small), cpp_run(exe, large)
    return (b.cpu_s - a.cpu_s) / (large - small) * 1e9


def cpp_calibrate(case: Case, seconds: float) -> None:
    exe = case.target["here"]
    start = cpp_run(exe, 1).cpu_s
    n = 1_000_000
    p = cpp_run(exe, n)
    while p.cpu_s - start < 0.05 and n < 10**9:
        n *= 10
        p = cpp_run(exe, n)
    large = max(100_000, int(seconds * n / max(p.cpu_s - start, 1e-3))) // 10 * 10
    case.sizes = (large // 10, large)


def callgrind(case: Case, side: str) -> float | None:
    """Instructions per instant under callgrind: the difference of two runs of the
    component as a process (C++: 100,000 and 200,000 instants; Python: 2,000 and 12,000,
    with a fixed hash seed), which start-up cancels from."""
    if shutil.which("valgrind") is None:
        return None
    import re

    target = case.target[side]
    cmd, sizes = ([str(target)], (100_000, 200_000)) if case.lang == "cpp" else \
        ([sys.executable, str(target)], (2_000, 12_000))
    period = PERIOD_MS.get(case.model, 1)
    counts = []
    for n in sizes:
        p = run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", *cmd,
                 "--clock", "virtual", "--until", f"{(n - 1) * period}ms"],
                env={**os.environ, "PYTHONHASHSEED": "0"})
        m = re.search(r"refs:\s+([\d,]+)", p.err)
        if p.status != 0 or m is None:
            return None
        counts.append(int(m[1].replace(",", "")))
    return (counts[1] - counts[0]) / (sizes[1] - sizes[0])


# ---------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Per-tick cost of the generated components of "
                                             "two hfsmc revisions, interleaved in one run.")
    ap.add_argument("--base", type=Path, help="source tree of the other revision")
    ap.add_argument("--here", type=Path, default=HERE.parent,
                    help="source tree compared with it (default: this one)")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--seconds", type=float, default=0.5, help="CPU of one timed run")
    ap.add_argument("--only", choices=["python", "cpp"], action="append")
    ap.add_argument("--no-callgrind", dest="callgrind", action="store_false",
                    help="skip the instruction counts (valgrind)")
    ap.add_argument("--json", type=Path, metavar="OUT",
                    help=f'merge the figures into OUT under the key "{KEY}"')
    ap.add_argument("--py-worker", nargs=2, metavar=("PATH", "N"), help=argparse.SUPPRESS)
    ns = ap.parse_args(argv)
    if ns.py_worker:
        return py_worker(Path(ns.py_worker[0]), int(ns.py_worker[1]))
    if ns.base is None:
        ap.error("--base is required")
    langs = ns.only or ["python", "cpp"]
    trees = {"base": ns.base.resolve(), "here": ns.here.resolve()}

    def log(s: str = "") -> None:
        print(s, flush=True)

    commits = {side: check_tree(tree) for side, tree in trees.items()}
    load_before = loadavg()
    info = machine()
    log(f"machine: {info['cpu']}, {info['cores']} cores; Python {info['python']}; base "
        f"{trees['base']} at {commits['base']}, here {trees['here']} at {commits['here']}; "
        f"load average {load_before}")
    cases = [Case("python", m) for m in PY_MODELS if "python" in langs] + \
        [Case("cpp", m) for m in CPP_MODELS if "cpp" in langs]
    for case in cases:
        for side in SIDES:
            case.target[side] = build(trees[side], side, case.lang, case.model)
        if case.lang == "python":
            py_calibrate(case, ns.seconds)
        else:
            cpp_calibrate(case, ns.seconds)
        if ns.callgrind:
            case.instructions = {side: callgrind(case, side) for side in SIDES}
    log(f"built {len(cases)} models on both sides into {WORK.relative_to(HERE.parent)}/; "
        f"{ns.rounds} rounds, interleaved")
    for r in range(ns.rounds):
        order = SIDES if r % 2 == 0 else SIDES[::-1]
        for case in cases:
            got: dict[str, float] = {}
            for side in order:
                exe = case.target[side]
                got[side] = py_timed(exe, case.sizes[1]) if case.lang == "python" else \
                    cpp_timed(exe, *case.sizes)
                case.ns[side].append(got[side])
            case.ratios.append(got["here"] / got["base"])
        log(f"  round {r + 1}: " + ", ".join(f"{c.lang} {c.model} {c.ratios[-1]:.3f}"
                                             for c in cases) + f" (load {loadavg()})")
    load_after = loadavg()
    rows: list[list[str]] = []
    out: dict[str, Any] = {}
    for case in cases:
        base, here = (statistics.median(case.ns[s]) for s in SIDES)
        ratio = statistics.median(case.ratios)
        ib, ih = (case.instructions.get(s) for s in SIDES)
        rows.append([case.lang, case.model, f"{base:,.1f}", f"{here:,.1f}", f"{ratio:.3f}",
                     f"{min(case.ratios):.3f}-{max(case.ratios):.3f}",
                     f"{min(case.ns['here']) / min(case.ns['base']):.3f}",
                     "-" if ib is None else f"{ib:,.1f}", "-" if ih is None else f"{ih:,.1f}",
                     "-" if not ib or ih is None else f"{ih / ib:.3f}"])
        out[f"{case.lang}_{case.model}"] = {
            "instants_per_run": list(case.sizes),
            "ns_cpu_per_instant": {s: [round(x, 2) for x in case.ns[s]] for s in SIDES},
            "ns_cpu_median": {"base": round(base, 2), "here": round(here, 2)},
            "ratio_median_of_rounds": round(ratio, 4),
            "ratio_of_best": round(min(case.ns["here"]) / min(case.ns["base"]), 4),
            "instructions_per_instant": {s: case.instructions.get(s) for s in SIDES}}
    log("\nns of CPU per instant (flat, nested: per transition), median of the rounds; "
        "here / base: median of the rounds' ratios, their range, and the ratio of the best")
    for line in table(rows, ["lang", "model", "base ns", "here ns", "here/base", "range",
                             "best/best", "base instr", "here instr", "instr ratio"]):
        log(line)
    log(f"\nload average before {load_before}, after {load_after}")
    if ns.json:
        merge_json(ns.json, KEY, {
            "description": "ns of CPU per instant of the generated components of two hfsmc "
                           "revisions, interleaved rounds (Python: in a child process, "
                           "process_time; C++: difference of two runs' wait4 CPU times), "
                           "median of the rounds; callgrind instructions per instant",
            "base": {"tree": str(trees["base"]), "commit": commits["base"]},
            "here": {"tree": str(trees["here"]), "commit": commits["here"]},
            "rounds": ns.rounds, "machine": info, "cases": out,
            "load_average": {"before": load_before, "after": load_after}})
        log(f"wrote {ns.json} (key \"{KEY}\")")
    return 0


if __name__ == "__main__":
    sys.exit(main())
