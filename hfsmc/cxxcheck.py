"""`hfsmc check` of a C++ model: g++ ``-fsyntax-only`` over the generated code.

The code is what ``hfsmc build -t cpp`` writes (``#line`` directives into the
model included): the automaton's class (src/NAME.hpp) and its two units
(src/NAME.cpp, src/NAME_main.cpp), handed to g++ as one translation unit in
which each keeps its name and lines, so g++'s messages are read by the same
function as those of ``build --compile`` (``hfsmc.cppcompile.messages``) and
point into the model: E144 errors, W209 warnings.  It is compiled against the
real headers: the runtime and drivers of ``templates/cpp/hfsmc``, the MAVLink
headers of ``hfsmc.emit.mavgen`` for a ``mavlink`` interface, Eigen and OpenCV.

Two caches under ``$HFSMC_CACHE_DIR`` (default ``$XDG_CACHE_HOME/hfsmc/cxx``,
that is ``~/.cache/hfsmc/cxx``) keep a warm check short:

- ``pch/KEY/``: the runtime and driver headers a model includes, copied, and
  precompiled (``pch.hpp.gch``) by the first check after the one that made
  the folder; KEY hashes the compiler's identity, the flags, the list of headers
  and their content (the pymavlink version stands for the MAVLink headers,
  which mavgen makes the same for the same version).  All models with the
  same interface types share one; the few newest are kept.
- ``out/KEY``: g++'s output for one translation unit (KEY adds the unit's text
  to the header key), so an unchanged model is not compiled again.

Both are written under a temporary name and renamed into place, so that
concurrent checks never see half a file; a lock keeps two of them from
precompiling the same headers at once.  Changes to system headers (a new
OpenCV) are not part of the keys: deleting the folder resets both caches.
"""

from __future__ import annotations

import fcntl
import hashlib
import importlib.metadata
import os
import re
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field, replace
from functools import cache
from importlib.resources import files
from pathlib import Path

from hfsmc.cppcompile import messages
from hfsmc.errors import Diagnostic, EmitError, Span
from hfsmc.ir import Model

CACHE_ENV = "HFSMC_CACHE_DIR"
FLAGS = ("-std=c++17", "-Wall", "-Wextra")  # the warnings of the generated CMakeLists.txt
_SYSTEM_DIRS = ("/usr/include/eigen3", "/usr/include/opencv4")  # without pkg-config
_RUNTIME_INCLUDE = re.compile(r'^#include "(hfsmc/[A-Za-z0-9_]+\.hpp)"$', re.M)
_KEEP_PCH = 4  # precompiled header sets kept (each 50-200 MB)
_KEEP_OUTPUTS = 256
_PCH_GRACE_S = 600  # never delete a header set used this recently (a check may be reading it)
_TIMEOUT_S = 600
_GCH = "pch.hpp.gch"
_MADE_HERE: set[Path] = set()  # header sets this process made (and so precompiles not)


@dataclass
class CxxCheck:
    """What g++ said about the model, or why it was not asked."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    note: str | None = None  # the C++ was not checked, and why (not an error of the model)


def cache_dir() -> Path:
    """Where the precompiled headers and g++'s outputs are kept."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "hfsmc" / "cxx"


def check_cpp(model: Model) -> CxxCheck:
    """Compile the model's translation unit with ``-fsyntax-only``; its diagnostics."""
    name = os.environ.get("CXX") or "g++"
    compiler = shutil.which(name)
    if compiler is None:
        what = "g++ is not installed" if name == "g++" else f"CXX names {name}, which is not found"
        return CxxCheck(note=f"{what}: C++ snippets are compiled only by "
                        "`hfsmc build --compile` (`make deps` installs g++)")
    from hfsmc.emit import cpp

    try:
        sources = cpp.component_sources(model)
    except EmitError as e:
        return CxxCheck(list(e.diagnostics))
    source = sources.unit()
    toolchain = _toolchain(compiler)
    try:  # a user's driver headers, a ros2 interface's messages and class
        own = cpp.generated_headers(model)
    except EmitError as e:
        return CxxCheck(list(e.diagnostics))
    headers = tuple(h for h in _runtime_headers(source) if h not in own)  # a user's driver
    pch_key = _digest(toolchain, *headers, _mavlink_stamp(headers), _runtime_digest())
    key = _digest(pch_key, source, *sorted(own.items()))
    root = cache_dir()
    output = _cached(root / "out" / key)
    if output is None:
        def compile_in(pch: Path) -> tuple[int, str]:
            folder = _header_set(pch, pch_key, headers, compiler)
            with tempfile.TemporaryDirectory(prefix="hfsmc-drivers-") as drivers:
                for inc, text in own.items():  # the model's own headers, beside the set's
                    (Path(drivers) / inc).parent.mkdir(parents=True, exist_ok=True)
                    (Path(drivers) / inc).write_text(text, "utf-8")
                return _run([compiler, *toolchain.flags, "-fsyntax-only",
                             "-I", str(folder / "include"), "-I", drivers,
                             "-include", str(folder / "pch.hpp"), "-x", "c++", "-"], source)

        try:
            code, text = compile_in(root / "pch")
        except OSError:  # a cache that cannot be written (read-only home): a folder for once
            with tempfile.TemporaryDirectory(prefix="hfsmc-cxx-") as tmp:
                code, text = compile_in(Path(tmp))
        output = f"{code}\n{text}"
        if "fatal error" not in text and code != 124:  # a missing header may be installed later
            _store(root / "out", key, output)
    code_text, _, text = output.partition("\n")
    return _result(model, (sources.header, sources.code), int(code_text or 1), text)


def _result(model: Model, sources: tuple[str, ...], code: int, text: str) -> CxxCheck:
    diags = _with_use_sites(model, messages(text, model.file, sources))
    missing = re.search(r"^(\S+?):\d+:\d+: fatal error: (\S+): No such file or directory$",
                        text, re.M)
    if missing and not any(d.code == "E144" for d in diags):
        # Eigen or OpenCV not installed: the machine's set-up, not the model's mistake
        return CxxCheck(note=f"C++ snippets not checked: {missing[2]} is missing "
                        "(`make deps` installs g++, Eigen, OpenCV and yaml-cpp)")
    if code != 0 and not any(d.severity == "error" for d in diags):
        tail = tuple(text.strip().splitlines()[-20:])
        diags.append(Diagnostic("E150", "g++ -fsyntax-only failed on the generated C++",
                                Span(model.file, 1, 1), notes=tail))
    return CxxCheck(diags)


def _with_use_sites(model: Model, diags: list[Diagnostic]) -> list[Diagnostic]:
    """A message in a used file's snippet notes where that file is used from."""
    sites: dict[str, set[Span]] = {}
    for auto in model.automata():
        if auto.instance is not None:
            sites.setdefault(auto.instance.file, set()).add(auto.instance.span)
    out = []
    for d in diags:
        used = sites.get(d.span.file)
        if used:
            note = "used from " + ", ".join(str(s) for s in sorted(used))
            d = replace(d, notes=(*d.notes, note))
        out.append(d)
    return out


@dataclass(frozen=True)
class _Toolchain:
    identity: str  # the compiler's path, its version text and the binary's mtime
    flags: tuple[str, ...]

    def __str__(self) -> str:
        return f"{self.identity}\n{' '.join(self.flags)}"


@cache
def _toolchain(compiler: str) -> _Toolchain:
    _code, version = _run([compiler, "--version"], "")
    try:
        stamp = str(os.stat(compiler).st_mtime_ns)
    except OSError:
        stamp = ""
    return _Toolchain(f"{os.path.realpath(compiler)} {stamp}\n{version.strip()}",
                      (*FLAGS, *_system_includes()))


def _system_includes() -> tuple[str, ...]:
    """Eigen's and OpenCV's include flags (as CMake's find_package finds them on Debian)."""
    if shutil.which("pkg-config"):
        code, out = _run(["pkg-config", "--cflags-only-I", "eigen3", "opencv4"], "")
        if code == 0:
            return tuple(out.split())
    return tuple(f"-I{d}" for d in _SYSTEM_DIRS if os.path.isdir(d))


def _runtime_headers(source: str) -> tuple[str, ...]:
    """The runtime and driver headers the unit includes, in its order (user imports aside:
    a header set is then shared by every model with the same interface types)."""
    return tuple(_RUNTIME_INCLUDE.findall(source))


def _mavlink_stamp(headers: tuple[str, ...]) -> str:
    if "hfsmc/mavlink.hpp" not in headers:
        return ""
    try:
        return f"pymavlink {importlib.metadata.version('pymavlink')}"
    except importlib.metadata.PackageNotFoundError:
        return "no pymavlink"


def _runtime_files() -> dict[str, bytes]:
    """Every header of templates/cpp/hfsmc (what a component's include/hfsmc holds)."""
    folder = files("hfsmc.templates").joinpath("cpp").joinpath("hfsmc")
    return {f"hfsmc/{f.name}": f.read_bytes() for f in folder.iterdir()
            if f.name.endswith(".hpp")}


def _runtime_digest() -> str:
    return _digest(*(f"{name}\0{data.hex()}" for name, data in sorted(_runtime_files().items())))


def _digest(*parts: object) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(str(part).encode("utf-8", "surrogateescape") + b"\0")
    return h.hexdigest()[:32]


def _cached(path: Path) -> str | None:
    try:
        text = path.read_text("utf-8", errors="replace")
    except OSError:
        return None
    _touch(path)
    return text


def _store(folder: Path, key: str, text: str) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{key}.", dir=folder)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, folder / key)
    except OSError:
        return  # a cache that cannot be written only costs time
    _prune(folder, _KEEP_OUTPUTS, 0.0, lambda p: p.unlink(missing_ok=True))


def _header_set(folder: Path, key: str, headers: tuple[str, ...], compiler: str) -> Path:
    """The folder of a header set: include/ (runtime, MAVLink headers) and pch.hpp.

    Made once, under a lock, and renamed into place.  The check that makes it
    compiles without a precompiled header, and so does every other unit of
    the same process (one run over many models, as in CI, does not pay for
    one); the first later process that uses it makes pch.hpp.gch: someone is
    checking again, after an edit (``_precompile``)."""
    done = folder / key
    if (done / "pch.hpp").is_file():
        _touch(done)
        if not (done / _GCH).is_file() and done not in _MADE_HERE:
            _precompile(done, folder / f".{key}.lock", compiler)
        return done
    folder.mkdir(parents=True, exist_ok=True)
    with _locked(folder / f".{key}.lock"):
        if not (done / "pch.hpp").is_file():
            tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=folder))
            try:
                _fill(tmp, headers)
                os.rename(tmp, done)
                _MADE_HERE.add(done)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
    _prune(folder, _KEEP_PCH, _PCH_GRACE_S, lambda p: shutil.rmtree(p, ignore_errors=True))
    return done


def _fill(tmp: Path, headers: tuple[str, ...]) -> None:
    """Copy the runtime headers (and the MAVLink ones if needed) into ``tmp``; write pch.hpp."""
    include = tmp / "include"
    for name, data in _runtime_files().items():
        (include / name).parent.mkdir(parents=True, exist_ok=True)
        (include / name).write_bytes(data)
    if "hfsmc/mavlink.hpp" in headers:
        from hfsmc.emit.mavgen import MavgenError, mavlink_headers

        try:
            generated = mavlink_headers()
        except MavgenError:
            generated = {}  # g++ then says which header is missing
        for path, data in generated.items():
            target = tmp / path  # "include/mavlink/..."
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
    (tmp / "pch.hpp").write_text("".join(f'#include "{h}"\n' for h in headers), "utf-8")


def _precompile(done: Path, lock: Path, compiler: str) -> None:
    """Make ``done``/pch.hpp.gch, renamed into place; nothing when g++ cannot (Eigen or
    OpenCV missing: it is tried again next time)."""
    with _locked(lock):
        if (done / _GCH).is_file():
            return
        fd, tmp = tempfile.mkstemp(prefix=".pch.", suffix=".tmp", dir=done)
        os.close(fd)
        try:
            code, _out = _run([compiler, *_toolchain(compiler).flags, "-I", str(done / "include"),
                               "-x", "c++-header", str(done / "pch.hpp"), "-o", tmp], "")
            if code == 0:
                os.replace(tmp, done / _GCH)
        finally:
            Path(tmp).unlink(missing_ok=True)


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    with open(path, "a+b") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _touch(path: Path) -> None:
    with suppress(OSError):
        os.utime(path)


def _prune(folder: Path, keep: int, grace_s: float, remove: Callable[[Path], object]) -> None:
    """Remove all but the ``keep`` most recently used entries (none used within grace_s)."""
    try:
        entries = [p for p in folder.iterdir() if not p.name.startswith(".")]
        if len(entries) <= keep:
            return
        entries.sort(key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:
        return
    now = time.time()
    for p in entries[keep:]:
        try:
            if now - p.stat().st_mtime >= grace_s:
                remove(p)
        except OSError:
            continue


def _run(cmd: list[str], stdin: str) -> tuple[int, str]:
    try:
        proc = subprocess.run(cmd, input=stdin, capture_output=True, text=True, errors="replace",
                              timeout=_TIMEOUT_S, check=False,
                              env={**os.environ, "LC_ALL": "C"})  # plain quotes in messages
    except subprocess.TimeoutExpired:
        return 124, f"{cmd[0]} took longer than {_TIMEOUT_S} s"
    except OSError as e:
        return 127, f"{cmd[0]}: {e}"
    return proc.returncode, proc.stdout + proc.stderr
