"""`hfsmc build -t cpp --compile`: run CMake and map g++'s messages to the model.

The generated code puts a ``#line`` directive before every snippet line and
pads the line to its model column, so g++ already names the model file, line
and column of a mistake in a snippet; this module turns those messages into
hfsmc diagnostics (E144 errors, W209 warnings).  What it says about the
generated lines around a snippet, or inside a header a snippet's line
instantiated, is placed at that snippet too (``messages``).  Anything else is
a failure of the generated code or of the machine's set-up, reported as E150
with the compiler's own words.  ``hfsmc check`` reads g++'s messages with the
same function (``hfsmc.cxxcheck``).

A new build folder is configured for Ninja when it is installed (the component's
translation unit then compiles beside the runtime library, not after it), and
the build's steps are shown while it runs: a status line on a terminal, plain
lines otherwise (``Progress``).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from contextlib import suppress
from pathlib import Path
from typing import TextIO

from hfsmc.emit.cpp import LIBRARY_SOURCES
from hfsmc.errors import Diagnostic, Span

# g++'s messages, and the "required from here" line that precedes an error inside a
# template a snippet instantiated (sev is None for it).
_MESSAGE = re.compile(r"^(?P<file>[^:\n]+):(?P<line>\d+):(?P<col>\d+):"
                      r"(?: (?P<sev>error|fatal error|warning): (?P<msg>.*)|\s+required from here)$",
                      re.M)
# A #line into the model, or back into the generated file (HFSMC_SOURCE: src/NAME.cpp,
# HFSMC_HEADER: src/NAME.hpp), and the generated file's own name.
_LINE_DIRECTIVE = re.compile(
    r'^#line (?P<line>\d+) (?P<file>HFSMC_SOURCE|HFSMC_HEADER|"(?:[^"\\]|\\.)*")\s*$')
_DEFAULT_SOURCE = re.compile(r'^#define HFSMC_(?:SOURCE|HEADER) "((?:[^"\\]|\\.)*)"')
_TIMEOUT_S = 1800


def _run(cmd: list[str], progress: Progress | None = None) -> tuple[int, str]:
    """Run ``cmd``, its output collected (and its build steps shown by ``progress``)."""
    env = {**os.environ, "LC_ALL": "C"}  # plain quotes in messages
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, errors="replace", env=env)
    except OSError as e:
        return 127, f"{cmd[0]}: {e}"
    late = threading.Event()

    def stop() -> None:
        late.set()
        proc.kill()

    timer = threading.Timer(_TIMEOUT_S, stop)
    timer.start()
    out: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            out.append(line)
            if progress is not None:
                progress.line(line)
        code = proc.wait()
    finally:
        timer.cancel()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if late.is_set():
        return 124, f"{''.join(out)}\n{cmd[0]} took longer than {_TIMEOUT_S} s"
    return code, "".join(out)


def compile_component(folder: Path, model_file: str, build_type: str = "RelWithDebInfo",
                      jobs: int | None = None, progress: bool = True) -> list[Diagnostic]:
    """Configure (once) and build ``folder``'s CMake project; the diagnostics to show.

    With ``progress``, the build's steps are shown on stderr while it runs (``Progress``).
    """
    where = Span(model_file, 1, 1)
    if shutil.which("cmake") is None:
        return [Diagnostic("E150", "cmake is not installed: `make deps` installs it with g++, "
                           "Eigen, OpenCV and yaml-cpp", where)]
    build = folder / "build"
    shown = Progress(_component_name(folder, model_file)) if progress else None
    try:
        if not (build / "CMakeCache.txt").is_file():
            if shown is not None:
                shown.show("configuring (CMake)")
            code, out = _run(["cmake", "-S", str(folder), "-B", str(build), *_generator(),
                              f"-DCMAKE_BUILD_TYPE={build_type}"])
            if code != 0:
                return [Diagnostic("E150", "CMake could not configure the component", where,
                                   notes=tuple(_tail(out)))]
        jobs = jobs or os.cpu_count() or 1
        if shown is not None:
            shown.expect(ninja_plan(build), jobs)
        code, out = _run(["cmake", "--build", str(build), "-j", str(jobs)], shown)
    finally:
        if shown is not None:
            shown.close()
    diags = messages(out, model_file, _generated_sources(folder))
    if code != 0 and not any(d.severity == "error" for d in diags):
        diags.append(Diagnostic("E150", "the C++ build failed", where, notes=tuple(_tail(out))))
    return diags


def _generator() -> list[str]:
    """Ninja for a new build folder, when it is installed and no generator was chosen
    (CMAKE_GENERATOR): with Make, the component's unit waits for the runtime library."""
    if os.environ.get("CMAKE_GENERATOR") or shutil.which("ninja") is None:
        return []
    return ["-G", "Ninja"]


def _component_name(folder: Path, model_file: str) -> str:
    found = [p.name.removesuffix("_main.cpp") for p in (folder / "src").glob("*_main.cpp")]
    return found[0] if len(found) == 1 else Path(model_file).stem


# A build step: Ninja's "[3/6] Building CXX object ...", Make's "[ 50%] Linking ...".
_STEP = re.compile(r"^\[\s*(?:(?P<n>\d+)/(?P<of>\d+)|(?P<pct>\d+)%)\] (?P<what>.*?)\s*$")
_OBJECT = re.compile(r"^Building CXX object (?P<path>\S+?)\.(?:o|gch)$")
_LINK = re.compile(r"^Linking CXX (?:executable|static library|shared library) (?P<path>\S+)$")
_PCH_UNIT = re.compile(r"hfsmc_pch_\w*\.cpp")  # the empty unit that owns the precompiled headers
_PAST = {"compiling": "compiled", "precompiling": "precompiled", "linking": "linked",
         "configuring": "configured"}


def _parse(line: str) -> tuple[str, str] | None:
    """A build output line's step: its count ("[3/6]", "[ 50%]") and what it does, in a few
    words ("compiling NAME.cpp", "precompiling headers", "linking NAME", "configuring
    (CMake)"); None for any other line."""
    m = _STEP.match(line)
    if m is None:
        return None
    what = m["what"]
    count = f"[{m['n']}/{m['of']}]" if m["n"] else f"[{int(m['pct']):3d}%]"
    obj, link = _OBJECT.match(what), _LINK.match(what)
    if obj is not None:
        name = obj["path"].rsplit("/", 1)[-1]
        if name == "cmake_pch.hxx":
            return count, "precompiling headers"
        return None if _PCH_UNIT.fullmatch(name) else (count, f"compiling {name}")
    if link is not None:
        return count, f"linking {link['path'].rsplit('/', 1)[-1]}"
    if what.startswith("Re-running CMake"):
        return count, "configuring (CMake)"
    return None


def step(line: str) -> str | None:
    """A build output line's step in a few words, its count first ("[3/6] compiling
    x.cpp"); None for any other line."""
    found = _parse(line)
    return None if found is None else f"{found[0]} {found[1]}"


def ninja_plan(build: Path) -> list[str] | None:
    """The steps a Ninja build folder's next build will take (a dry run): the count before
    the first ("[0/6]"), then each in ``_parse``'s words; [] when there is nothing to do;
    None for a folder of another generator."""
    ninja = shutil.which("ninja")
    if ninja is None or not (build / "build.ninja").is_file():
        return None
    try:
        done = subprocess.run([ninja, "-C", str(build), "-n"], capture_output=True, text=True,
                              errors="replace", timeout=60, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    steps = [p for p in map(_parse, done.stdout.splitlines()) if p is not None]
    return [f"[0/{steps[-1][0].rpartition('/')[2]}", *(what for _, what in steps)] if steps else []


class Progress:
    """A build's steps shown on ``stream`` (stderr): on a terminal, one status line that
    changes in place and counts the seconds; otherwise, a plain line per step.

    Make prints a step as it starts; Ninja, off a terminal, as it ends. Given Ninja's plan
    (``expect``), the status line names the steps not done yet, and the plain lines say
    what was done ("compiled x.cpp")."""

    def __init__(self, name: str, stream: TextIO | None = None, tty: bool | None = None) -> None:
        self.name = name
        self.stream = stream if stream is not None else sys.stderr
        self.tty = _isatty(self.stream) if tty is None else tty
        self.started = time.monotonic()
        self._status = ""
        self._left: list[str] | None = None  # Ninja's steps not done yet
        self._jobs = 1
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None
        if self.tty:
            self._ticker = threading.Thread(target=self._tick, daemon=True)
            self._ticker.start()

    def expect(self, plan: list[str] | None, jobs: int) -> None:
        """The steps Ninja is about to run (``ninja_plan``), ``jobs`` at a time."""
        self._left = None if plan is None else plan[1:]
        self._jobs = max(jobs, 1)
        if plan and self.tty:
            self.show(f"{plan[0]} {self._running()}")

    def line(self, text: str) -> None:
        """One line of the build's output: shown if it is a step."""
        found = _parse(text)
        if found is None:
            return
        count, what = found
        if self._left is None:  # Make: the step starts
            self.show(f"{count} {what}")
            return
        if what in self._left:
            self._left.remove(what)
        verb, _, rest = what.partition(" ")
        done = f"{count} {_PAST.get(verb, verb)} {rest}"
        self.show(f"{done}; {self._running()}" if self.tty and self._left else done)

    def _running(self) -> str:
        """The steps likely running: the next ones left, links only after the compiles."""
        left = self._left or []
        compiles = [s for s in left if not s.startswith("linking")]
        return ", ".join((compiles or left)[:self._jobs])

    def show(self, status: str) -> None:
        with self._lock:
            self._status = status
            if self.tty:
                self._draw()
            else:
                self._write(f"{self.name}: {status}\n")

    def close(self) -> None:
        """Stop counting; on a terminal, erase the status line."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        with self._lock:
            if self.tty and self._status:
                self._write("\r\x1b[K")
            self._status = ""

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            with self._lock:
                if self._status:
                    self._draw()

    def _draw(self) -> None:
        width = shutil.get_terminal_size((80, 24)).columns
        text = f"{self.name}: {self._status} ({time.monotonic() - self.started:.0f} s)"
        self._write("\r\x1b[K" + text[:max(width - 1, 20)])

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed or broken stderr must not stop the build
            pass


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (OSError, ValueError):
        return False


# g++ names the type of a legacy ROS/ICE interface (runtime.hpp) when a snippet uses one.
UNAVAILABLE_NOTE = ("the interface is a legacy ROS topic or ICE proxy, which hfsmc components "
                    "cannot drive (W205): replace it with a `mavlink` or `camera` "
                    "interface, or with code of your own")


def messages(output: str, model_file: str, sources: Sequence[str] = ()) -> list[Diagnostic]:
    """g++'s errors and warnings: those in the model as its positions, the rest as E150.

    ``sources`` are the generated files (src/NAME.hpp, src/NAME.cpp): with them, a message
    on one of their lines next to a snippet (the brace closing the snippet's function, the line
    after it, a `when`'s wrapper) is placed at that snippet (``GeneratedLines``),
    and an error inside a header that a snippet's line instantiated ("required
    from here") at that line.  Once a message is placed in the model, errors
    outside it are taken for its consequences and left out.
    """
    generated = [GeneratedLines(s) for s in sources]
    models = {os.path.normpath(model_file): model_file}
    for g in generated:
        models.update((os.path.normpath(f), f) for f in g.files)
    out: list[Diagnostic] = []
    outside: list[Diagnostic] = []
    seen: set[tuple[str, int, int, str]] = set()
    placed: set[tuple[Span, str]] = set()
    here: Span | None = None  # the model line of the last "required from here"
    for m in _MESSAGE.finditer(output):
        file, line, col = m["file"], int(m["line"]), max(int(m["col"]), 1)
        path = os.path.normpath(file)
        if m["sev"] is None:  # "required from here"
            if path in models:
                here = Span(models[path], line, col)
            continue
        error = m["sev"] != "warning"
        key = (file, line, col, m["msg"])
        if key in seen:
            continue
        seen.add(key)
        span: Span | None = None
        notes: tuple[str, ...] = ()
        if path in models:
            span = Span(models[path], line, col)
        elif (lines := next((g for g in generated if g.generated(file)), None)) is not None:
            span = lines.position(line)
            notes = ("g++ met it in the code generated around the snippet",)
        elif here is not None:
            span = here
            notes = (f"in {file}:{line}, instantiated from this line",)
        here = None
        if "hfsmc::Unavailable" in m["msg"]:
            notes = (*notes, UNAVAILABLE_NOTE)
        if span is not None and (span, m["msg"]) not in placed:
            placed.add((span, m["msg"]))
            out.append(Diagnostic("E144" if error else "W209", m["msg"], span,
                                  "error" if error else "warning", notes))
        elif error:
            outside.append(Diagnostic("E150", "the generated C++ does not compile: "
                                      f"{m.group(0).strip()}", Span(model_file, 1, 1)))
    if not any(d.severity == "error" for d in out):
        out.extend(outside)
    return out


class GeneratedLines:
    """The model positions of the generated lines around each snippet.

    The generated code gives every snippet line a ``#line`` directive into the
    model and returns to the generated file after the snippet, so g++ places
    most mistakes in the model by itself.  A mistake it can only see at the next
    token (a missing ``;`` before the ``}`` that closes the snippet's function,
    a `when` cut short before the wrapper's ``)``) is reported on the first
    generated line of code after the snippet: that line stands for the end of
    the snippet's last line.  The generated line just before a snippet, when it
    opens a parenthesis (a `when`'s ``static_cast<bool>(``), stands for the
    snippet's start.
    """

    def __init__(self, source: str) -> None:
        self.name = ""  # HFSMC_SOURCE's or HFSMC_HEADER's default: "src/NAME.cpp"
        self.files: set[str] = set()  # the model files the #line directives name
        self._at: dict[int, Span] = {}
        file: str | None = None  # the model file of the current line, None: generated
        base = 0  # generated line number of the current model #line directive
        first = 0  # model line of the directive
        last: Span | None = None  # the end of the last non-blank snippet line so far
        after: Span | None = None  # the position the next generated code line stands for
        shift = 0  # g++'s line number of a generated line minus its line in ``source``
        code_before, code_text = 0, ""  # the last generated line of code (not blank, no comment)
        opener = 0  # a generated line that opens a `(` the snippet starting now continues
        for g, text in enumerate(source.split("\n"), 1):
            d = _LINE_DIRECTIVE.match(text)
            if d is not None:
                target = d["file"]
                if target in ("HFSMC_SOURCE", "HFSMC_HEADER"):
                    after, file, last = last, None, None
                    shift = int(d["line"]) - g - 1  # g++ numbers the next line d["line"]
                    continue
                name = _c_string(target[1:-1])
                if file is None:
                    opener = code_before if code_text.endswith("(") else 0
                file, base, first = name, g, int(d["line"])
                self.files.add(name)
                continue
            if file is not None:
                body = _code_part(text)
                if body.strip():
                    last = Span(file, first + g - base - 1, len(body.rstrip()) + 1)
                    if opener:
                        self._at[opener] = Span(file, last.line, len(body) - len(body.lstrip()) + 1)
                        opener = 0
                continue
            stripped = text.strip()
            if not self.name:
                found = _DEFAULT_SOURCE.match(text)
                if found:
                    self.name = _c_string(found[1])
            if stripped and not stripped.startswith("//"):
                if after is not None:
                    self._at[g + shift] = after
                    after = None
                code_before, code_text = g + shift, text.rstrip()

    def generated(self, file: str) -> bool:
        """Whether g++ names this generated file with ``file``."""
        if file == "<stdin>":
            return True
        if not self.name:
            return False
        path, name = os.path.normpath(file), os.path.normpath(self.name)
        return path == name or path.endswith(os.sep + name)

    def position(self, line: int) -> Span | None:
        """The model position a generated line stands for, if it is next to a snippet."""
        return self._at.get(line)


def _c_string(body: str) -> str:
    """The text of a C string literal's body as ``cpp_string`` writes it (octal escapes)."""
    raw = re.sub(rb"\\([0-7]{1,3}|.)", lambda m: bytes([int(m[1], 8)]) if m[1][:1].isdigit()
                 else m[1], body.encode("utf-8", "surrogateescape"))
    return raw.decode("utf-8", "replace")


def _code_part(line: str) -> str:
    """``line`` without a trailing ``//`` comment (one outside string and char literals)."""
    quote = ""
    k = 0
    while k < len(line):
        ch = line[k]
        if quote:
            if ch == "\\":
                k += 1
            elif ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif line.startswith("//", k):
            return line[:k]
        k += 1
    return line


def _generated_sources(folder: Path) -> list[str]:
    """The texts of the component's own generated files (src/NAME.hpp, src/NAME.cpp)."""
    found = [p for p in sorted((folder / "src").glob("*.[ch]pp"))
             if p.name not in LIBRARY_SOURCES and not p.name.endswith("_main.cpp")]
    out = []
    for p in found:
        with suppress(OSError):  # gone meanwhile: its messages are placed without it
            out.append(p.read_text("utf-8", errors="replace"))
    return out


def _tail(text: str, n: int = 20) -> list[str]:
    return text.strip().splitlines()[-n:]
