"""`hfsmc build -t cpp --compile`: run CMake and map g++'s messages to the model.

The generated code puts a ``#line`` directive before every snippet line and
pads the line to its model column, so g++ already names the model file, line
and column of a mistake in a snippet; this module turns those messages into
hfsmc diagnostics (E144 errors, W209 warnings).  Anything the compiler says
about other files is a failure of the generated code or of the machine's
set-up, reported as E150 with the compiler's own words.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

from hfsmc.errors import Diagnostic, Span

_MESSAGE = re.compile(r"^(?P<file>[^:\n]+):(?P<line>\d+):(?P<col>\d+): "
                      r"(?P<sev>error|fatal error|warning): (?P<msg>.*)$", re.M)
_TIMEOUT_S = 1800


def _run(cmd: list[str]) -> tuple[int, str]:
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, errors="replace",
                              timeout=_TIMEOUT_S, check=False,
                              env={**os.environ, "LC_ALL": "C"})  # plain quotes in messages
    except subprocess.TimeoutExpired:
        return 124, f"{cmd[0]} took longer than {_TIMEOUT_S} s"
    return proc.returncode, proc.stdout + proc.stderr


def compile_component(folder: Path, model_file: str, build_type: str = "RelWithDebInfo",
                      jobs: int | None = None) -> list[Diagnostic]:
    """Configure (once) and build ``folder``'s CMake project; the diagnostics to show."""
    where = Span(model_file, 1, 1)
    if shutil.which("cmake") is None:
        return [Diagnostic("E150", "cmake is not installed: `make deps` installs it with g++, "
                           "Eigen, OpenCV and yaml-cpp", where)]
    build = folder / "build"
    if not (build / "CMakeCache.txt").is_file():
        code, out = _run(["cmake", "-S", str(folder), "-B", str(build),
                          f"-DCMAKE_BUILD_TYPE={build_type}"])
        if code != 0:
            return [Diagnostic("E150", "CMake could not configure the component", where,
                               notes=tuple(_tail(out)))]
    code, out = _run(["cmake", "--build", str(build), "-j", str(jobs or os.cpu_count() or 1)])
    diags = messages(out, model_file)
    if code != 0 and not any(d.severity == "error" for d in diags):
        diags.append(Diagnostic("E150", "the C++ build failed", where, notes=tuple(_tail(out))))
    return diags


def messages(output: str, model_file: str) -> list[Diagnostic]:
    """g++'s errors and warnings: those in the model as its positions, the rest as E150."""
    out: list[Diagnostic] = []
    seen: set[tuple[str, int, int, str]] = set()
    model = os.path.normpath(model_file)
    for m in _MESSAGE.finditer(output):
        file, line, col = m["file"], int(m["line"]), int(m["col"])
        error = m["sev"] != "warning"
        key = (file, line, col, m["msg"])
        if key in seen:
            continue
        seen.add(key)
        if os.path.normpath(file) == model:
            out.append(Diagnostic("E144" if error else "W209", m["msg"],
                                  Span(model_file, line, max(col, 1)),
                                  "error" if error else "warning"))
        elif error:
            out.append(Diagnostic("E150", f"the generated C++ does not compile: {m.group(0)}",
                                  Span(model_file, 1, 1)))
    return out


def _tail(text: str, n: int = 20) -> list[str]:
    return text.strip().splitlines()[-n:]
