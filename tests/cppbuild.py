"""Build many generated C++ components at once, for the tests.

Each component is its own CMake project; the tests put the ones they need
side by side under one top-level ``CMakeLists.txt`` (``add_subdirectory``
each), so CMake configures once, the automaton-independent runtime library
is built once (the components share the ``hfsmc_runtime`` target), and the
compiler runs on both cores.  Warnings are errors in these builds
(``HFSMC_WERROR``); ``sanitize`` turns on ASan and UBSan (``HFSMC_SANITIZE``).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUILD_TIMEOUT = 1800.0


class CppBuildError(Exception):
    """A component (or the whole project) did not build: the message says why."""


def need_toolchain() -> None:
    missing = [t for t in ("cmake", "g++") if shutil.which(t) is None]
    if missing:
        raise CppBuildError(f"{', '.join(missing)} missing: `make deps` installs the C++ tool chain")


def model_name(model: Path) -> str:
    found = re.search(r"^name:\s*([A-Za-z_]\w*)\s*$", model.read_text("utf-8"), re.MULTILINE)
    if not found:
        raise CppBuildError(f"{model}: no `name:` line")
    return found.group(1)


def generate(model: Path, out: Path) -> None:
    """``hfsmc build -t cpp`` one model into ``out``."""
    cmd = [sys.executable, "-m", "hfsmc", "build", "-t", "cpp", str(model), "-o", str(out)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    if proc.returncode != 0:
        raise CppBuildError(f"{shlex.join(cmd)} exited {proc.returncode}\n{proc.stderr}")


class Superbuild:
    """Components generated from ``models`` into ``base``, compiled in one CMake project."""

    def __init__(self, base: Path, models: list[Path], sanitize: bool = False,
                 build_type: str = "Debug") -> None:
        self.base = base
        self.models = models
        self.sanitize = sanitize
        self.build_type = build_type
        self.folders: dict[Path, Path] = {}
        self.failed: dict[Path, str] = {}
        self.log = ""
        self._done = False

    def executable(self, model: Path) -> Path:
        self.build()
        if model in self.failed:
            raise CppBuildError(self.failed[model])
        exe = self.base / "_build" / self.folders[model].name / model_name(model)
        if not exe.is_file():
            errors = "\n".join(ln for ln in self.log.splitlines()
                               if self.folders[model].name in ln and "error" in ln)
            raise CppBuildError(f"{model.name}: no executable after the build\n{errors or self.log[-4000:]}")
        return exe

    def folder(self, model: Path) -> Path:
        self.build()
        return self.folders[model]

    def build(self) -> None:
        if self._done:
            return
        self._done = True
        need_toolchain()
        self.base.mkdir(parents=True, exist_ok=True)
        names: set[str] = set()
        for model in self.models:
            name = model_name(model)
            folder = self.base / (name if name not in names else f"{name}_{len(names)}")
            names.add(name)
            try:
                generate(model, folder)
            except CppBuildError as e:
                self.failed[model] = str(e)
                continue
            self.folders[model] = folder
        top = self.base / "CMakeLists.txt"
        top.write_text(
            "cmake_minimum_required(VERSION 3.16)\nproject(hfsmc_tests LANGUAGES CXX)\n"
            + "".join(f"add_subdirectory({f.name})\n" for f in self.folders.values()), "utf-8")
        build = self.base / "_build"
        # With the sanitizers each automaton is one unit (as in a Release build): the
        # slowest build of the suite, and the plain one compiles the two units apart.
        configure = ["cmake", "-S", str(self.base), "-B", str(build),
                     f"-DCMAKE_BUILD_TYPE={self.build_type}", "-DHFSMC_WERROR=ON",
                     f"-DHFSMC_SANITIZE={'ON' if self.sanitize else 'OFF'}",
                     f"-DHFSMC_UNITY={'ON' if self.sanitize else 'OFF'}",
                     # One precompiled set of the runtime's headers per list of drivers,
                     # shared by every component of the project: half of a component's
                     # compile time is parsing them.
                     "-DHFSMC_PCH=ON"]
        env = {**os.environ, "LC_ALL": "C"}
        proc = subprocess.run(configure, capture_output=True, text=True, timeout=BUILD_TIMEOUT, env=env)
        if proc.returncode != 0:
            raise CppBuildError(f"{shlex.join(configure)} failed\n{proc.stdout}{proc.stderr}")
        jobs = str(os.cpu_count() or 2)
        make = ["cmake", "--build", str(build), "-j", jobs, "--", "-k"]
        proc = subprocess.run(make, capture_output=True, text=True, timeout=BUILD_TIMEOUT, env=env)
        self.log = proc.stdout + proc.stderr
