"""The back ends a behaviour test runs a model in: each builds the component of a model
and says how to run it.  tests/test_conformance.py and tests/test_reliability.py run
their cases once per back end."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from tests.cppbuild import CppBuildError, Superbuild, model_name

ROOT = Path(__file__).resolve().parent.parent
TIMEOUT = 120.0  # seconds, for `hfsmc build`

# What AddressSanitizer, LeakSanitizer and UndefinedBehaviorSanitizer print when they find
# something: any of it in a C++ component's stderr fails the test.
SANITIZER_REPORT = re.compile(r"ERROR: (AddressSanitizer|LeakSanitizer)|runtime error: |"
                              r"Sanitizer")


class BuildError(Exception):
    """A back end could not build a component: the message holds its output."""


class Backend(Protocol):
    """Builds the component of a model and says how to run it."""

    @property
    def name(self) -> str:
        """Shown in test ids."""
        ...

    @property
    def model_suffix(self) -> str:
        """A case has a model for this back end when ``NN_name`` + this suffix exists."""
        ...

    def build(self, model: Path, out: Path) -> list[str]:
        """Build ``model`` into ``out``; return the command line that runs it."""
        ...


@dataclass(frozen=True)
class PythonBackend:
    """The Python component, built by `hfsmc build -t python`; ``isolated`` runs it with
    the standard library alone (``-I -S``: no site-packages, no hfsmc)."""

    name: str = "python"
    model_suffix: str = ".yaml"
    isolated: bool = False

    def build(self, model: Path, out: Path) -> list[str]:
        shown = model.relative_to(ROOT) if model.is_relative_to(ROOT) else model
        cmd = [sys.executable, "-m", "hfsmc", "build", "-t", "python", str(shown), "-o", str(out)]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT,
                              stdin=subprocess.DEVNULL)
        if proc.returncode != 0:
            raise BuildError(f"{shlex.join(cmd)} exited {proc.returncode}\n{proc.stderr}")
        flags = ["-I", "-S"] if self.isolated else []
        return [sys.executable, *flags, str(out / f"{model_name(model)}.py")]


class CppBackend:
    """The C++ component: every model ``twins()`` lists generated and compiled in one CMake
    project (tests/cppbuild.py, warnings are errors) the first time one is asked for, then
    reused; ``sanitize`` builds with AddressSanitizer and UndefinedBehaviorSanitizer."""

    model_suffix = ".cpp.yaml"

    def __init__(self, name: str, sanitize: bool, twins: Callable[[], list[Path]]) -> None:
        self.name = name
        self.sanitize = sanitize
        self._twins = twins
        self._projects: dict[Path, Superbuild] = {}

    def build(self, model: Path, out: Path) -> list[str]:
        """``out``'s parent folder holds the project of all the twins."""
        base = out.parent
        if base not in self._projects:
            self._projects[base] = Superbuild(base, self._twins(), sanitize=self.sanitize)
        try:
            return [str(self._projects[base].executable(model))]
        except CppBuildError as e:
            raise BuildError(str(e)) from None
