#!/usr/bin/env python3
"""Speed, timing and build time of the C++ component that ``hfsmc build -t cpp`` generates.

Three parts, each with the issue's targets:

* **Per-transition cost** of the generated C++ component against a
  hand-written ``switch``-based FSM of the same machine
  (``bench/cpp_baseline/``; generated <= 2x the baseline), against the same
  machines written with Boost.MSM and Boost.Statechart (peers in the same run:
  generated within 1.5x of MSM, faster than Statechart) and against the
  generated Python component (C++ >= 100x faster), on the machines of
  ``component.py``: a flat toggle and a three-level machine whose every
  transition crosses branches, each bare and with entry/exit counters
  (``bench/models/*.cpp.yaml``, the C++ twins of the Python models). All three
  run the same way, as processes: each round runs every program for a small
  and a large number of transitions and takes the difference of the wall
  times over the difference of the transitions, which cancels start-up
  (process creation, dynamic linking, Python's imports). The figure is the
  median of the rounds. Beside them, without a hand-written twin: a state with 8
  parallel regions at 10, 20, ..., 80 ms (``regions8.cpp.yaml``, ``regions8.yaml``),
  in C++ and in Python, per tick and per instant.
* **Real clock**: a 100 Hz component whose ``during`` compares
  ``std::chrono::steady_clock`` with the tick's logical time ``now()`` runs for
  60 s: p50/p99/max tick lateness (p99 <= 0.5 ms) and drift (< 1 ms), computed
  with ``component.py``'s functions. A bare C++ loop sleeping until the same
  deadlines is the control.
* **Build time** of a C++ example from a clean folder: ``hfsmc build -t cpp``,
  CMake configure (Release), compile.

Usage::

    python bench/cpp.py                          # full: about 10 minutes
    python bench/cpp.py --quick                  # about 3 minutes
    python bench/cpp.py --json bench/results.json
    python bench/cpp.py --only speed             # or: realtime, build (repeatable)
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from component import (  # bench/component.py, beside this script
    hfsmc_command,
    lateness_figures,
    ticks_of,
)
from report import finish_targets, hfsmc_revision, loadavg, machine, table, verdict

HERE = Path(__file__).resolve().parent
MODELS = HERE / "models"
BASELINE_SRC = HERE / "cpp_baseline"
EXAMPLES = HERE.parent / "examples"
WORK = HERE / "_work" / "cpp"
KEY = "cpp_component"

# Targets of the issue.
TARGET_VS_BASELINE = 2.0  # generated C++ / hand-written switch, at most
TARGET_VS_MSM = 1.5  # generated C++ / Boost.MSM, at most (and faster than Boost.Statechart)
TARGET_VS_PYTHON = 100.0  # generated Python / generated C++, at least
TARGET_P99_MS = 0.5  # tick lateness at 100 Hz
TARGET_DRIFT_MS = 1.0  # over 60 s
FIFO_PRIORITY = 10  # of the diagnostic run with the SCHED_FIFO policy
RT_PERIOD_MS = 10

CASES = ("flat", "nested")
VARIANTS = ("bare", "counted")
LEVELS = {"flat": 1, "nested": 3}  # states exited and entered by one transition
CONTENDERS = ("baseline", "cpp", "python")
# The same machines with Boost (bench/cpp_baseline/msm.cpp, statechart.cpp): built when
# the headers are there (Debian's libboost-dev), run and checked as the baseline is.
PEERS = ("msm", "statechart")
HAND_WRITTEN = ("baseline", *PEERS)
# regions8(.cpp).yaml: a state with 8 regions at 10, 20, ..., 80 ms under a 10 ms root; no
# hand-written twin. Timed per instant (every 10 ms) and per tick.
REGIONS_PERIODS_US = (10_000, *(10_000 * k for k in range(1, 9)))


@dataclass(frozen=True)
class Mode:
    """How long each part runs."""

    seconds_per_run: float  # of the large run of each pair
    rounds: int  # pairs of runs per program, interleaved; the median is kept
    realtime_s: int  # 100 Hz component on the real clock
    control_s: int  # bare C++ loop after it; SCHED_FIFO diagnosis
    builds: int  # clean builds of the example


FULL = Mode(seconds_per_run=1.0, rounds=7, realtime_s=60, control_s=20, builds=3)
QUICK = Mode(seconds_per_run=0.3, rounds=3, realtime_s=10, control_s=5, builds=1)


# ---------------------------------------------------------------------------
# Processes and builds
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Proc:
    wall_s: float
    cpu_s: float  # user + system time of the child, from wait4
    status: int
    out: str
    err: str


def run(cmd: list[str], cwd: Path | None = None, env: dict[str, str] | None = None) -> Proc:
    """Run ``cmd`` to its end; wall time around it, its CPU time from ``wait4``."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, cwd=cwd, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = code = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        return Proc(wall, usage.ru_utime + usage.ru_stime, code,
                    out.read().decode(errors="replace"), err.read().decode(errors="replace"))


def must(cmd: list[str], what: str, cwd: Path | None = None) -> Proc:
    p = run(cmd, cwd)
    if p.status != 0:
        sys.stderr.write((p.out + p.err)[-4000:])
        raise SystemExit(f"{what} failed (exit {p.status}): {' '.join(cmd)}")
    return p


@dataclass(frozen=True)
class CppBuild:
    exe: Path
    generate_s: float  # hfsmc build -t cpp
    configure_s: float  # cmake -S -B -DCMAKE_BUILD_TYPE=Release
    compile_s: float  # cmake --build
    compile_cpu_s: float  # CPU time of cmake --build and the compilers it waited for


def model_name(model: Path) -> str:
    m = re.search(r"^name:\s*(\w+)", model.read_text(encoding="utf-8"), re.M)
    if m is None:
        raise SystemExit(f"{model}: no `name:`")
    return m.group(1)


def build_cpp(model: Path, out: Path) -> CppBuild:
    """``hfsmc build -t cpp`` + CMake configure (Release) + build, each timed (wall)."""
    gen = must([*hfsmc_command(), "build", "-t", "cpp", str(model), "-o", str(out)],
               f"hfsmc build -t cpp {model.name}")
    conf = must(["cmake", "-S", str(out), "-B", str(out / "build"),
                 "-DCMAKE_BUILD_TYPE=Release"], f"cmake configure of {model.name}")
    comp = must(["cmake", "--build", str(out / "build")], f"cmake build of {model.name}")
    exe = out / "build" / model_name(model)
    if not exe.exists():
        raise SystemExit(f"{exe}: not built")
    return CppBuild(exe, gen.wall_s, conf.wall_s, comp.wall_s, comp.cpu_s)


def build_python(model: Path, out: Path) -> Path:
    must([*hfsmc_command(), "build", "-t", "python", str(model), "-o", str(out)],
         f"hfsmc build -t python {model.name}")
    return out / f"{model_name(model)}.py"


def build_baseline() -> Path:
    """The hand-written baselines and the control loop, with the same CMake Release flags."""
    out = WORK / "baseline"
    must(["cmake", "-S", str(BASELINE_SRC), "-B", str(out), "-DCMAKE_BUILD_TYPE=Release"],
         "cmake configure of bench/cpp_baseline")
    must(["cmake", "--build", str(out)], "cmake build of bench/cpp_baseline")
    return out


def compiler() -> str:
    p = run(["c++", "--version"])
    return p.out.splitlines()[0] if p.status == 0 and p.out else "unknown"


# ---------------------------------------------------------------------------
# Per-transition cost
# ---------------------------------------------------------------------------

@dataclass
class Program:
    """One contender on one case: how to take n transitions and check the work done."""

    name: str  # baseline, cpp, python
    case: str
    variant: str
    command: list[str]  # without the size
    check: Callable[[int, Proc], None]
    per: list[tuple[float, float]] = field(default_factory=list)  # (wall, cpu) s/transition
    sizes: tuple[int, int] = (0, 0)
    instructions: float | None = None  # per transition, under callgrind
    period_ms: int = 1  # of the root: the instants are 0, period, ..., (n-1) * period

    def argv(self, n: int) -> list[str]:
        """The command that takes n transitions: the baseline runs n ticks; a generated
        component under the virtual clock ticks at 0, 1, ..., n-1 ms (regions8: n instants,
        10 ms apart)."""
        if self.name in HAND_WRITTEN:
            return [*self.command, str(n)]
        return [*self.command, "--clock", "virtual", "--until", f"{(n - 1) * self.period_ms}ms"]

    def ns_wall(self) -> float:
        return statistics.median(w for w, _ in self.per) * 1e9

    def ns_cpu(self) -> float:
        return statistics.median(c for _, c in self.per) * 1e9

    def json(self) -> dict[str, Any]:
        walls = sorted(w * 1e9 for w, _ in self.per)
        return {"transitions_small_large": list(self.sizes), "rounds": len(self.per),
                "ns_per_transition_wall_median": round(self.ns_wall(), 2),
                "ns_per_transition_wall_min": round(walls[0], 2),
                "ns_per_transition_wall_max": round(walls[-1], 2),
                "ns_per_transition_cpu_median": round(self.ns_cpu(), 2),
                "instructions_per_transition": None if self.instructions is None
                else round(self.instructions, 1)}


def expected_counts(case: str, variant: str, n: int) -> tuple[int, int]:
    """Entries and exits after n transitions and the stop: the initial entries, then
    ``levels`` of each per transition, then the stop's exits."""
    levels = LEVELS[case]
    return (levels * (n + 1), levels * (n + 1)) if variant == "counted" else (0, 0)


def baseline_program(case: str, variant: str, bin_dir: Path, name: str = "baseline") -> Program:
    """The hand-written switch (``baseline``) or a Boost peer (``msm``, ``statechart``):
    N ticks from argv, the same checksum."""
    exe = bin_dir / f"{name}_{case}{'_counted' if variant == 'counted' else ''}"

    def check(n: int, p: Proc) -> None:
        m = re.search(r"t=(\d+) \w+=([AB]) .*n_entry=(\d+) n_exit=(\d+)", p.out)
        want_state = "AB"[n % 2]
        if m is None or int(m[1]) != n or m[2] != want_state or \
                (int(m[3]), int(m[4])) != expected_counts(case, variant, n):
            raise SystemExit(f"{exe.name} {n}: unexpected checksum {p.out.strip()!r}")

    return Program(name, case, variant, [str(exe)], check)


def component_program(name: str, case: str, variant: str, command: list[str]) -> Program:
    """A generated component; the C++ models log their counters in on_shutdown."""

    def check(n: int, p: Proc) -> None:
        if variant != "counted":
            return
        m = re.search(r"counters (\d+) (\d+)", p.err)
        if m is None:
            return  # the Python models do not log them (component.py checks them)
        if (int(m[1]), int(m[2])) != expected_counts(case, variant, n):
            raise SystemExit(f"{name} {case} {variant} {n}: counters {m[1]} {m[2]}, expected "
                             f"{expected_counts(case, variant, n)}")

    return Program(name, case, variant, command, check)


def check_trace(programs: list[Program]) -> None:
    """The generated components of one case, 10 ticks with ``--trace -``: 10 transitions,
    and the C++ and Python traces byte-identical but for log records (docs/semantics.md §14)."""
    traces: dict[str, list[str]] = {}
    for prog in programs:
        if prog.name in HAND_WRITTEN:
            continue
        p = must([*prog.argv(10), "--trace", "-"],
                 f"{prog.name} {prog.case} {prog.variant} trace")
        fires = p.out.count('"ev":"fire"')
        if fires != 10:
            raise SystemExit(f"{prog.name} {prog.case} {prog.variant}: {fires} transitions in "
                             "10 ticks, expected 10")
        # Without log records: the C++ counted models log their counters at the stop.
        traces[prog.name] = [r for r in p.out.splitlines() if '"ev":"log"' not in r]
    if traces.get("cpp") != traces.get("python"):
        print(f"  warning: {programs[0].case} {programs[0].variant}: the C++ and the Python "
              "traces differ", flush=True)


def timed(prog: Program, n: int) -> Proc:
    p = must(prog.argv(n), f"{prog.name} {prog.case} {prog.variant} ({n} transitions)")
    prog.check(n, p)
    return p


def calibrate(prog: Program, seconds: float) -> None:
    """Sizes for the pair of runs: the large one about ``seconds`` beyond start-up, the
    small one a tenth of it."""
    start = timed(prog, 1).wall_s
    n = {"baseline": 10_000_000, "msm": 10_000_000, "statechart": 1_000_000,
         "cpp": 1_000_000, "python": 20_000}[prog.name]
    p = timed(prog, n)
    while p.wall_s - start < 0.05 and n < 10**10:  # too short to tell the cost from start-up
        n *= 10
        p = timed(prog, n)
    large = max(10_000, int(seconds * n / max(p.wall_s - start, 1e-3))) // 10 * 10
    prog.sizes = (large // 10, large)


def speed(mode: Mode, bin_dir: Path, cpp: dict[str, Path], py: dict[str, Path],
          log: Callable[[str], None]) -> dict[tuple[str, str], dict[str, Program]]:
    results: dict[tuple[str, str], dict[str, Program]] = {}
    for case in CASES:
        for variant in VARIANTS:
            key = case if variant == "bare" else f"{case}_counted"
            progs = {
                "baseline": baseline_program(case, variant, bin_dir),
                "cpp": component_program("cpp", case, variant, [str(cpp[key])]),
                "python": component_program("python", case, variant,
                                            [sys.executable, str(py[key])])}
            for peer in PEERS:
                if (bin_dir / f"{peer}_{case}").exists():
                    progs[peer] = baseline_program(case, variant, bin_dir, peer)
            check_trace(list(progs.values()))
            for prog in progs.values():
                calibrate(prog, mode.seconds_per_run)
            for _ in range(mode.rounds):
                for prog in progs.values():  # interleaved: round 1 of each, then round 2...
                    small, large = prog.sizes
                    a, b = timed(prog, small), timed(prog, large)
                    prog.per.append(((b.wall_s - a.wall_s) / (large - small),
                                     (b.cpu_s - a.cpu_s) / (large - small)))
            for name, prog in progs.items():
                if name != "python":
                    prog.instructions = instructions(prog)
            results[(case, variant)] = progs
            log(f"  {case:6} {variant:7} ns/transition (wall, median of {mode.rounds}): " +
                ", ".join(f"{p.name} {p.ns_wall():,.1f}" for p in progs.values()))
    return results


def regions_speed(mode: Mode, cpp: Path, py: Path, log: Callable[[str], None]) -> dict[str, Program]:
    """regions8 in C++ and in Python, the same way as the machines above (per instant);
    their traces over 2 s must be identical."""
    progs = {"cpp": component_program("cpp", "regions8", "bare", [str(cpp)]),
             "python": component_program("python", "regions8", "bare", [sys.executable, str(py)])}
    traces = []
    for prog in progs.values():
        prog.period_ms = 10
        traces.append(must([*prog.argv(201), "--trace", "-"], f"{prog.name} regions8 trace").out)
    if traces[0] != traces[1] or traces[0].count('"ev":"fire"') == 0:
        print("  warning: regions8: the C++ and the Python traces differ", flush=True)
    for prog in progs.values():
        calibrate(prog, mode.seconds_per_run)
    for _ in range(mode.rounds):
        for prog in progs.values():
            small, large = prog.sizes
            a, b = timed(prog, small), timed(prog, large)
            prog.per.append(((b.wall_s - a.wall_s) / (large - small),
                             (b.cpu_s - a.cpu_s) / (large - small)))
    progs["cpp"].instructions = instructions(progs["cpp"])
    log(f"  regions8 (8 regions) ns/instant (wall, median of {mode.rounds}): " +
        ", ".join(f"{p.name} {p.ns_wall():,.1f}" for p in progs.values()) +
        f"; {ticks_per_instant(progs['cpp']):.2f} ticks an instant")
    return progs


def ticks_per_instant(prog: Program) -> float:
    """Ticks per instant of regions8 between the program's two run sizes."""
    small, large = prog.sizes
    return (ticks_of(REGIONS_PERIODS_US, large) - ticks_of(REGIONS_PERIODS_US, small)) / \
        (large - small)


def instructions(prog: Program, small: int = 100_000, large: int = 200_000) -> float | None:
    """Instructions per transition under callgrind (difference of two sizes), or None
    without valgrind. Unlike time, the count does not depend on the machine's load."""
    if shutil.which("valgrind") is None:
        return None
    counts = []
    for n in (small, large):
        p = must(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                  *prog.argv(n)], f"callgrind {prog.name} {prog.case} {prog.variant}")
        m = re.search(r"refs:\s+([\d,]+)", p.err)
        if m is None:
            return None
        counts.append(int(m[1].replace(",", "")))
    return (counts[1] - counts[0]) / (large - small)


def python_in_process(path: Path) -> dict[str, float]:
    """component.py's in-process figures of the Python component (best CPU), if present."""
    try:
        speed_json = json.loads(path.read_text(encoding="utf-8"))["python_component"]["speed"]
        return {k: float(v["hfsmc"].get("ns_per_transition_cpu", v["hfsmc"].get("ns_per_tick_cpu")))
                for k, v in speed_json.items()}
    except (OSError, KeyError, TypeError, ValueError):
        return {}


# ---------------------------------------------------------------------------
# Real clock: tick lateness, drift
# ---------------------------------------------------------------------------

def lateness_file(path: Path, period_ms: int, proc: Proc) -> dict[str, Any]:
    """``lateness_figures`` of "DEADLINE_US LATENESS_NS" lines; overruns from gaps."""
    deadline_us: list[int] = []
    late_ns: list[int] = []
    for line in path.read_text(encoding="ascii").splitlines():
        d, late = line.split()
        deadline_us.append(int(d))
        late_ns.append(int(late))
    if not late_ns:
        raise SystemExit(f"{path}: no tick recorded")
    period_us = period_ms * 1000
    overruns = sum((b - a) // period_us - 1 for a, b in itertools.pairwise(deadline_us))
    return lateness_figures({"late_ns": late_ns, "deadline_us": deadline_us,
                             "overruns": overruns, "end_t_us": deadline_us[-1],
                             "cpu_s": proc.cpu_s, "wall_s": proc.wall_s}, period_ms)


def realtime(mode: Mode, exe: Path, bin_dir: Path, log: Callable[[str], None]) -> dict[str, Any]:
    def component(seconds: int, prefix: list[str]) -> tuple[Proc, Path]:
        out = WORK / "rt_late.txt"
        out.unlink(missing_ok=True)
        return run([*prefix, str(exe), "--clock", "real", "--until", f"{seconds}s",
                    "--param", f"out={out}"]), out

    p, out = component(mode.realtime_s, [])
    if p.status != 0:
        sys.stderr.write(p.err[-4000:])
        raise SystemExit(f"{exe.name} --clock real: exit {p.status}")
    late = lateness_file(out, RT_PERIOD_MS, p)
    late["drift_ms"] = round(max(abs(late["median_late_last_tenth_ms"]),
                                 abs(late["theil_sen_over_run_ms"])), 4)
    ctl = run([str(bin_dir / "periodic"), str(RT_PERIOD_MS), str(mode.control_s)])
    ctl_file = WORK / "rt_control.txt"
    ctl_file.write_text(ctl.out, encoding="ascii")
    late["bare_loop"] = lateness_file(ctl_file, RT_PERIOD_MS, ctl)
    fifo: dict[str, Any] | None = None
    if shutil.which("chrt"):
        p, out = component(mode.control_s, ["chrt", "-f", str(FIFO_PRIORITY)])
        if p.status == 0 and out.exists():
            fifo = lateness_file(out, RT_PERIOD_MS, p)
            fifo["fifo_priority"] = FIFO_PRIORITY
    late["sched_fifo"] = fifo
    for label, f in (("component", late), ("bare C++ loop", late["bare_loop"]),
                     (f"component, SCHED_FIFO {FIFO_PRIORITY}", fifo)):
        if f is None:
            log(f"  {label}: not permitted here (needs CAP_SYS_NICE); skipped")
            continue
        lm = f["late_ms"]
        log(f"  {label}, {f['run_s']:g} s: {f['ticks']} ticks; lateness ms p50 {lm['p50']:.3f}, "
            f"p90 {lm['p90']:.3f}, p99 {lm['p99']:.3f}, p99.9 {lm['p999']:.3f}, max "
            f"{lm['max']:.3f}; overruns {f['overruns']}; median of the last tenth "
            f"{f['median_late_last_tenth_ms']:.3f} ms, trend {f['theil_sen_ms_per_minute']:+.4f} "
            f"ms/min (Theil-Sen); cpu {f['child_cpu_s']:.3f} s")
    return late


# ---------------------------------------------------------------------------
# Build time
# ---------------------------------------------------------------------------

def build_model() -> Path:
    """The largest C++ example (bytes of the model), else the largest C++ bench model."""
    examples = [m for m in EXAMPLES.glob("*/*.yaml")
                if m.stem == m.parent.name and
                re.search(r"^language:\s*cpp\b", m.read_text(encoding="utf-8"), re.M)]
    pool = examples or list(MODELS.glob("*.cpp.yaml"))
    return max(pool, key=lambda m: m.stat().st_size)


def build_time(mode: Mode, log: Callable[[str], None]) -> dict[str, Any]:
    model = build_model()
    runs: list[CppBuild] = []
    for _ in range(mode.builds):
        with tempfile.TemporaryDirectory(dir=WORK) as tmp:
            b = build_cpp(model, Path(tmp) / "out")
            runs.append(b)
            log(f"  {model.relative_to(HERE.parent)}: hfsmc build {b.generate_s:.2f} s, "
                f"configure {b.configure_s:.2f} s, compile {b.compile_s:.2f} s (CPU "
                f"{b.compile_cpu_s:.2f} s), total {b.generate_s + b.configure_s + b.compile_s:.2f} s")

    def med(get: Callable[[CppBuild], float]) -> float:
        return round(statistics.median(get(b) for b in runs), 3)

    return {"model": str(model.relative_to(HERE.parent)), "runs": len(runs),
            "generate_s": med(lambda b: b.generate_s),
            "configure_s": med(lambda b: b.configure_s),
            "compile_s": med(lambda b: b.compile_s),
            "compile_cpu_s": med(lambda b: b.compile_cpu_s),
            "total_s": med(lambda b: b.generate_s + b.configure_s + b.compile_s),
            "commands": ["hfsmc build -t cpp MODEL -o DIR",
                         "cmake -S DIR -B DIR/build -DCMAKE_BUILD_TYPE=Release",
                         "cmake --build DIR/build"],
            "each": [{"generate_s": round(b.generate_s, 3), "configure_s": round(b.configure_s, 3),
                      "compile_s": round(b.compile_s, 3),
                      "compile_cpu_s": round(b.compile_cpu_s, 3)} for b in runs]}


# ---------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------

def speed_report(results: dict[tuple[str, str], dict[str, Program]], in_process: dict[str, float],
                 targets: list[dict[str, Any]], log: Callable[[str], None],
                 regions: dict[str, Program] | None = None) -> dict[str, Any]:
    """Two tables: wall time (the targets' figure), then CPU time and instruction counts;
    regions8's rows per tick and per instant, without a hand-written twin or a target."""
    inproc_regions = in_process.get("regions8")
    rows: list[list[str]] = []
    rows_cpu: list[list[str]] = []
    rows_peers: list[list[str]] = []
    out: dict[str, Any] = {}
    for (case, variant), progs in results.items():
        base, cpp, py = (progs[n] for n in CONTENDERS)
        vs_base, vs_py = cpp.ns_wall() / base.ns_wall(), py.ns_wall() / cpp.ns_wall()
        ok_base, ok_py = vs_base <= TARGET_VS_BASELINE, vs_py >= TARGET_VS_PYTHON
        key = f"{case}_{variant}"
        inproc = in_process.get(key)
        ir_ratio = (cpp.instructions / base.instructions
                    if cpp.instructions and base.instructions else None)
        entry: dict[str, Any] = {name: p.json() for name, p in progs.items()}
        entry.update({"cpp_over_baseline": round(vs_base, 3), "python_over_cpp": round(vs_py, 1),
                      "cpp_over_baseline_cpu": round(cpp.ns_cpu() / base.ns_cpu(), 3),
                      "python_over_cpp_cpu": round(py.ns_cpu() / cpp.ns_cpu(), 1),
                      "cpp_over_baseline_instructions": None if ir_ratio is None
                      else round(ir_ratio, 2),
                      "python_in_process_ns_cpu": inproc,
                      "python_in_process_over_cpp_cpu": round(inproc / cpp.ns_cpu(), 1)
                      if inproc else None})
        out[key] = entry
        rows.append([case, variant, f"{base.ns_wall():,.2f}", f"{cpp.ns_wall():,.2f}",
                     f"{py.ns_wall():,.1f}", f"{vs_base:.2f}x {verdict(ok_base)}",
                     f"{vs_py:,.0f}x {verdict(ok_py)}"])
        rows_cpu.append([case, variant, f"{base.ns_cpu():,.2f}", f"{cpp.ns_cpu():,.2f}",
                         f"{py.ns_cpu():,.1f}", f"{cpp.ns_cpu() / base.ns_cpu():.2f}x",
                         f"{py.ns_cpu() / cpp.ns_cpu():,.0f}x",
                         "-" if base.instructions is None else f"{base.instructions:,.1f}",
                         "-" if cpp.instructions is None else f"{cpp.instructions:,.1f}",
                         "-" if ir_ratio is None else f"{ir_ratio:.1f}x",
                         f"{inproc:,.0f} ({inproc / cpp.ns_cpu():,.0f}x)" if inproc else "-"])
        targets.append({"target": f"{key}: generated C++ <= {TARGET_VS_BASELINE:g}x the "
                                  "hand-written switch", "value": round(vs_base, 3), "met": ok_base})
        targets.append({"target": f"{key}: generated C++ >= {TARGET_VS_PYTHON:g}x faster than "
                                  "the generated Python", "value": round(vs_py, 1), "met": ok_py})
        if all(peer in progs for peer in PEERS):
            msm, sc = progs["msm"], progs["statechart"]
            vs_msm, sc_over = cpp.ns_wall() / msm.ns_wall(), sc.ns_wall() / cpp.ns_wall()
            ok_msm, ok_sc = vs_msm <= TARGET_VS_MSM, sc_over > 1.0
            entry.update({"cpp_over_msm": round(vs_msm, 3), "statechart_over_cpp": round(sc_over, 3),
                          "cpp_over_msm_cpu": round(cpp.ns_cpu() / msm.ns_cpu(), 3),
                          "statechart_over_cpp_cpu": round(sc.ns_cpu() / cpp.ns_cpu(), 3)})

            def instr(p: Program) -> str:
                return "-" if p.instructions is None else f"{p.instructions:,.1f}"

            rows_peers.append([case, variant, f"{base.ns_wall():,.2f}", f"{msm.ns_wall():,.2f}",
                               f"{sc.ns_wall():,.2f}", f"{cpp.ns_wall():,.2f}",
                               f"{vs_msm:.2f}x {verdict(ok_msm)}", f"{sc_over:.2f}x {verdict(ok_sc)}",
                               f"{msm.ns_cpu():,.2f} / {sc.ns_cpu():,.2f} / {cpp.ns_cpu():,.2f}",
                               f"{instr(msm)} / {instr(sc)} / {instr(cpp)}"])
            targets.append({"target": f"{key}: generated C++ <= {TARGET_VS_MSM:g}x Boost.MSM",
                            "value": round(vs_msm, 3), "met": ok_msm})
            targets.append({"target": f"{key}: generated C++ faster than Boost.Statechart",
                            "value": round(sc_over, 3), "met": ok_sc})
    if regions:
        cpp, py = regions["cpp"], regions["python"]
        tpi = ticks_per_instant(cpp)
        entry = {name: p.json() for name, p in regions.items()}
        entry.update({"ticks_per_instant": round(tpi, 4),
                      "ns_per_tick_wall_median": {"cpp": round(cpp.ns_wall() / tpi, 2),
                                                  "python": round(py.ns_wall() / tpi, 2)},
                      "ns_per_tick_cpu_median": {"cpp": round(cpp.ns_cpu() / tpi, 2),
                                                 "python": round(py.ns_cpu() / tpi, 2)},
                      "instructions_per_tick": None if cpp.instructions is None
                      else round(cpp.instructions / tpi, 1),
                      "python_over_cpp": round(py.ns_wall() / cpp.ns_wall(), 1),
                      "python_over_cpp_cpu": round(py.ns_cpu() / cpp.ns_cpu(), 1)})
        out["regions8"] = entry
        for per, div in (("tick", tpi), ("instant", 1.0)):
            rows.append(["regions8", f"per {per}", "-", f"{cpp.ns_wall() / div:,.2f}",
                         f"{py.ns_wall() / div:,.1f}", "-",
                         f"{py.ns_wall() / cpp.ns_wall():,.0f}x"])
            rows_cpu.append(["regions8", f"per {per}", "-", f"{cpp.ns_cpu() / div:,.2f}",
                             f"{py.ns_cpu() / div:,.1f}", "-",
                             f"{py.ns_cpu() / cpp.ns_cpu():,.0f}x", "-",
                             "-" if cpp.instructions is None else f"{cpp.instructions / div:,.1f}",
                             "-", f"{inproc_regions:,.0f}" if inproc_regions and per == "tick"
                             else "-"])
    log("\nwall time, ns per transition (median of the rounds): the targets' figure")
    for line in table(rows, ["case", "actions", "switch", "C++", "Python",
                             f"C++/switch (<= {TARGET_VS_BASELINE:g})",
                             f"Python/C++ (>= {TARGET_VS_PYTHON:g})"]):
        log(line)
    log("\nCPU time of the children (wait4), ns per transition (median); instructions per "
        "transition (callgrind); Python in-process: component.py's figure from results.json")
    for line in table(rows_cpu, ["case", "actions", "switch", "C++", "Python", "C++/switch",
                                 "Python/C++", "switch instr", "C++ instr", "C++/switch instr",
                                 "Python in-process"]):
        log(line)
    if rows_peers:
        log("\nBoost peers (the same machines, bench/cpp_baseline/msm.cpp and statechart.cpp): "
            "wall ns per transition (median); CPU ns and callgrind instructions MSM / "
            "Statechart / C++")
        for line in table(rows_peers, ["case", "actions", "switch", "MSM", "Statechart", "C++",
                                       f"C++/MSM (<= {TARGET_VS_MSM:g})",
                                       "Statechart/C++ (> 1)", "CPU ns", "instructions"]):
            log(line)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="Time the generated C++ component: per-transition cost against a "
                    "hand-written switch FSM and the generated Python component; real-clock "
                    "lateness and drift at 100 Hz; build time of an example.")
    ap.add_argument("--quick", action="store_true",
                    help="shorter runs (10 s real-clock run, 3 rounds, one build)")
    ap.add_argument("--only", choices=["speed", "realtime", "build"], action="append",
                    help="run only this part (repeatable; default: all)")
    ap.add_argument("--json", type=Path, metavar="OUT",
                    help=f'merge the figures into OUT under the key "{KEY}"')
    ns = ap.parse_args(argv)
    mode = QUICK if ns.quick else FULL
    parts = set(ns.only or ["speed", "realtime", "build"])

    def log(s: str = "") -> None:
        print(s, flush=True)

    info, revision, cxx = machine(), hfsmc_revision(), compiler()
    load_before = loadavg()
    log(f"machine: {info['cpu']}, {info['cores']} cores, {info['memory_gib']} GiB; {cxx}; "
        f"Python {info['python']}; hfsmc {revision['version']} at {revision['commit']}"
        f"{' (modified)' if revision['dirty'] else ''}; load average {load_before}; "
        f"{'quick' if ns.quick else 'full'} mode")
    WORK.mkdir(parents=True, exist_ok=True)
    bin_dir = build_baseline()
    figures: dict[str, Any] = {
        "description": "generated C++ component (hfsmc build -t cpp, CMake Release): "
                       "ns/transition of the process (difference of the wall times of a small "
                       "and a large --clock virtual run over the difference of transitions, "
                       "median of the rounds) against a hand-written switch FSM and the "
                       "generated Python component measured the same way; real-clock tick "
                       "lateness and drift at 100 Hz; clean build time of an example",
        "mode": "quick" if ns.quick else "full", "machine": info, "compiler": cxx,
        "hfsmc": revision}
    targets: list[dict[str, Any]] = []

    if "speed" in parts:
        cpp: dict[str, Path] = {}
        py: dict[str, Path] = {}
        for key in ("flat", "flat_counted", "nested", "nested_counted", "regions8"):
            cpp[key] = build_cpp(MODELS / f"{key}.cpp.yaml", WORK / f"cpp_{key}").exe
            py[key] = build_python(MODELS / f"{key}.yaml", WORK / f"py_{key}")
        log("\n== per-transition cost (ns per transition: wall time of a large run minus a "
            f"small one, over the transitions between them; median of {mode.rounds} rounds) ==")
        results = speed(mode, bin_dir, cpp, py, log)
        regions = regions_speed(mode, cpp["regions8"], py["regions8"], log)
        in_process = python_in_process(ns.json or HERE / "results.json")
        figures["speed"] = speed_report(results, in_process, targets, log, regions)

    if "realtime" in parts:
        log(f"\n== real clock: 100 Hz component for {mode.realtime_s} s ==")
        exe = build_cpp(MODELS / "rt_100hz.cpp.yaml", WORK / "cpp_rt_100hz").exe
        late = realtime(mode, exe, bin_dir, log)
        p99, drift = late["late_ms"]["p99"], late["drift_ms"]
        ok_p99, ok_drift = p99 <= TARGET_P99_MS, drift < TARGET_DRIFT_MS
        log(f"  p99 {p99:.3f} ms (<= {TARGET_P99_MS:g}): {verdict(ok_p99)}; drift {drift:.3f} "
            f"ms over {late['run_s']:g} s (< {TARGET_DRIFT_MS:g}): {verdict(ok_drift)}")
        targets.append({"target": f"p99 tick lateness at 100 Hz <= {TARGET_P99_MS:g} ms",
                        "value": p99, "met": ok_p99})
        targets.append({"target": f"drift over {mode.realtime_s} s < {TARGET_DRIFT_MS:g} ms "
                                  "(median lateness of the last tenth of the ticks; Theil-Sen "
                                  "trend over the run)", "value": drift, "met": ok_drift})
        figures["lateness_100hz"] = late

    if "build" in parts:
        log("\n== build time from a clean folder (wall) ==")
        figures["build"] = build_time(mode, log)

    finish_targets(figures, targets, load_before, ns.json, KEY, log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
