#!/usr/bin/env python3
"""How long a person waits for a C++ component to build (issue 19, item 3).

examples/follow_colors_cpp (OpenCV, Eigen and MAVLink headers: the heaviest C++
example) is generated with ``hfsmc build -t cpp`` into fresh folders under
bench/_work/cppbuild/ and built with CMake as ``hfsmc build --compile`` and
``hfsmc run`` build it (RelWithDebInfo, both cores), in these set-ups:

* **plain**: the generated project built without what speeds it up: the Make
  generator, no precompiled headers, no ccache (``-G "Unix Makefiles"
  -DHFSMC_PCH=OFF -DHFSMC_CCACHE=OFF``).
* **now**: Ninja (when installed), the runtime and driver headers precompiled,
  through ccache (when installed) with a cache of its own under the work folder:
  a clean build with the cache empty (a machine's first component), a clean
  build of the same model in another folder (the runtime library and the
  precompiled headers come from the cache: any later component with the same
  drivers), then a rebuild after a change of one snippet's text.
* **now, without precompiled headers** (``-DHFSMC_PCH=OFF``): clean (cache warm)
  and rebuild, to show what the precompiled headers bring.
* with ``--base TREE`` (a checkout of another revision, set up as for
  ``bench/compare.py``), **base**: the project that tree generates, built as
  **now** (Ninja, precompiled headers, ccache): a clean build that fills the
  cache, a clean build with the cache warm and a rebuild after the same snippet
  change, in the same run.

Each step's wall time and the CPU time of its processes (compilers included,
from ``getrusage(RUSAGE_CHILDREN)``), and the units compiled (from CMake's build
log, ``hfsmc.cppcompile.step``). Targets (issue 19): clean build <= 10 s (cache
warm) and rebuild after a snippet change <= 2 s, wall, on the 2-core machine.

Usage::

    python bench/cppbuild.py
    python bench/cppbuild.py --json bench/results.json
    python bench/cppbuild.py --base /tmp/benchold   # and another revision's project
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from compare import check_tree, tree_env
from report import finish_targets, hfsmc_revision, loadavg, machine, table

from hfsmc.cppcompile import step

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

WORK = HERE / "_work" / "cppbuild"
KEY = "cpp_build"
MODEL = "follow_colors_cpp"
CLEAN_TARGET_S = 10.0
REBUILD_TARGET_S = 2.0
_SNIPPET = re.compile(r'do: log\("link back(?: \d+)?"\);')  # one transition's snippet


@dataclass
class Step:
    what: str
    wall_s: float
    cpu_s: float
    units: list[str]

    def row(self) -> list[str]:
        return [self.what, f"{self.wall_s:.1f}", f"{self.cpu_s:.1f}",
                ", ".join(self.units) or "-"]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(cmd: list[str], env: dict[str, str], cwd: Path | None = None) -> str:
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1800, check=False,
                          cwd=cwd)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{done.stdout[-3000:]}{done.stderr[-3000:]}")
    return done.stdout + done.stderr


def generate(model: Path, folder: Path, tree: Path | None = None) -> None:
    """``hfsmc build -t cpp`` of this tree, or of another one (``--base``)."""
    env = dict(os.environ) if tree is None else tree_env(tree)
    _run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp", str(model), "-o", str(folder)], env,
         tree)  # in the tree: `-m` imports hfsmc from the working directory first


def build(what: str, folder: Path, env: dict[str, str], options: list[str]) -> Step:
    """Configure (when new) and build ``folder``: the step's figures."""
    started, cpu = time.monotonic(), _cpu()
    log = ""
    if not (folder / "build" / "CMakeCache.txt").is_file():
        log += _run(["cmake", "-S", str(folder), "-B", str(folder / "build"),
                     "-DCMAKE_BUILD_TYPE=RelWithDebInfo", *options], env)
    log += _run(["cmake", "--build", str(folder / "build"), "-j", str(os.cpu_count() or 2)], env)
    units = [said.split("] ", 1)[1].removeprefix("compiling ")
             for said in map(step, log.splitlines())
             if said is not None and "compiling" in said]
    return Step(what, time.monotonic() - started, _cpu() - cpu, units)


def change_snippet(model: Path, n: int) -> None:
    text = model.read_text("utf-8")
    changed, count = _SNIPPET.subn(f'do: log("link back {n}");', text)
    if count != 1:
        sys.exit(f"{model}: the snippet this bench changes is not there")
    model.write_text(changed, "utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Time clean C++ builds and rebuilds after a "
                                             "snippet change of examples/follow_colors_cpp.")
    ap.add_argument("--json", type=Path, metavar="OUT",
                    help=f'merge the figures into OUT under the key "{KEY}"')
    ap.add_argument("--base", type=Path, metavar="TREE",
                    help="also build the project another hfsmc tree generates (bench/compare.py "
                         "says how to set one up)")
    ns = ap.parse_args(argv)
    base_rev = check_tree(ns.base) if ns.base is not None else None
    for tool in ("cmake", "g++"):
        if shutil.which(tool) is None:
            sys.exit(f"{tool} missing: `make deps` installs the C++ tool chain")

    def log(s: str = "") -> None:
        print(s, flush=True)

    load_before = loadavg()
    shutil.rmtree(WORK, ignore_errors=True)
    (WORK / "examples").mkdir(parents=True)
    for d in (MODEL, "lib"):  # a copy whose snippet the bench changes (`use:` ../lib)
        shutil.copytree(ROOT / "examples" / d, WORK / "examples" / d)
    model = WORK / "examples" / MODEL / f"{MODEL}.yaml"
    env = {**os.environ, "CCACHE_DIR": str(WORK / "ccache"), "LC_ALL": "C"}
    env.pop("CMAKE_GENERATOR", None)
    ninja = ["-G", "Ninja"] if shutil.which("ninja") else []
    ccache = shutil.which("ccache") is not None
    steps: list[Step] = []

    # Every source generated first, so that all set-ups build the same code; a snippet
    # change then replaces the files of src/ it changed, as `hfsmc build` does.
    text = model.read_text("utf-8")
    generate(model, WORK / "generated")
    for n in (1, 2, 3):
        change_snippet(model, n)
        generate(model, WORK / f"changed{n}")
    if ns.base is not None:
        model.write_text(text, "utf-8")
        generate(model, WORK / "base_generated", ns.base)
        change_snippet(model, 4)
        generate(model, WORK / "base_changed4", ns.base)

    def folder(name: str, side: str = "") -> Path:
        f = WORK / name
        shutil.copytree(WORK / f"{side}generated", f)
        return f

    def change(f: Path, n: int, side: str = "") -> Path:
        for new in sorted((WORK / f"{side}changed{n}" / "src").iterdir()):
            old = f / "src" / new.name
            if old.read_bytes() != new.read_bytes():  # as `hfsmc build` rewrites changed files
                shutil.copyfile(new, old)
        return f

    before = folder("before")
    steps.append(build("plain: clean", before, env,
                       ["-G", "Unix Makefiles", "-DHFSMC_PCH=OFF", "-DHFSMC_CCACHE=OFF"]))
    steps.append(build("plain: rebuild after a snippet change", change(before, 1), env, []))

    steps.append(build("now: clean, cache empty", folder("cold"), env, ninja))
    warm = folder("warm")
    steps.append(build("now: clean, cache warm", warm, env, ninja))
    steps.append(build("now: rebuild after a snippet change", change(warm, 2), env, []))

    nopch = folder("nopch")
    steps.append(build("no PCH: clean, cache warm", nopch, env, [*ninja, "-DHFSMC_PCH=OFF"]))
    steps.append(build("no PCH: rebuild after a snippet change", change(nopch, 3), env, []))

    if ns.base is not None:
        steps.append(build(f"base ({base_rev}): clean, cache empty", folder("base_cold", "base_"),
                           env, ninja))
        base = folder("base_warm", "base_")
        steps.append(build(f"base ({base_rev}): clean, cache warm", base, env, ninja))
        steps.append(build(f"base ({base_rev}): rebuild after a snippet change",
                           change(base, 4, "base_"), env, []))

    log(f"C++ build of examples/{MODEL} (RelWithDebInfo, -j{os.cpu_count()}; "
        f"generator {'Ninja' if ninja else 'Make'}, ccache {'yes' if ccache else 'not installed'})")
    for line in table([s.row() for s in steps], ["step", "wall s", "CPU s", "units compiled"]):
        log(line)
    by = {s.what: s for s in steps}
    clean, rebuild = by["now: clean, cache warm"], by["now: rebuild after a snippet change"]
    figures: dict[str, Any] = {
        "description": f"C++ build of examples/{MODEL}: wall and CPU seconds of a clean build "
                       "(plain: Make, no PCH, no ccache; now: Ninja, PCH, ccache with the cache "
                       "empty, then warm; base: another tree's project, as now) and of a rebuild "
                       "after a snippet change",
        "machine": machine(), "hfsmc": hfsmc_revision(), "base": base_rev,
        "generator": "Ninja" if ninja else "Make",
        "ccache": ccache,
        "steps": [{"what": s.what, "wall_s": round(s.wall_s, 2), "cpu_s": round(s.cpu_s, 2),
                   "units": s.units} for s in steps]}
    targets = [
        {"target": f"clean build (cache warm) <= {CLEAN_TARGET_S:g} s wall",
         "value": round(clean.wall_s, 2), "met": clean.wall_s <= CLEAN_TARGET_S},
        {"target": f"rebuild after a snippet change <= {REBUILD_TARGET_S:g} s wall",
         "value": round(rebuild.wall_s, 2), "met": rebuild.wall_s <= REBUILD_TARGET_S}]
    finish_targets(figures, targets, load_before, ns.json, KEY, log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
