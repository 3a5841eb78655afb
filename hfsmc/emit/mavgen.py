"""The MAVLink C headers a C++ component needs (docs/cpp.md), made by pymavlink's mavgen.

The ``mavlink`` interface of C++ components (``templates/cpp/hfsmc/mavlink.hpp``)
includes ``mavlink/ardupilotmega/mavlink.h`` from the component's ``include/``.
mavgen writes every dialect the ardupilotmega XML includes, and more files
than a build reads (test suites, the fixed headers for other uses); only the
files reached by ``#include "..."`` from the dialect's ``mavlink.h`` are kept.

mavgen runs in process on the message definitions shipped with pymavlink, so
no network is needed. Its output is deterministic except for the date it
stamps in each ``version.h`` (``MAVLINK_BUILD_DATE``): that is replaced by the
pymavlink version, so the same pymavlink gives the same bytes on any day.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.metadata
import io
import re
import tempfile
from pathlib import Path, PurePosixPath

DIALECT = "ardupilotmega"
PREFIX = PurePosixPath("include/mavlink")  # keys: paths relative to the component folder
_INCLUDE = re.compile(rb'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)
_BUILD_DATE = re.compile(rb'^(#define MAVLINK_BUILD_DATE )"[^"\n]*"', re.MULTILINE)


class MavgenError(RuntimeError):
    """pymavlink is missing or its generator failed (the output is not written)."""


def mavlink_headers() -> dict[str, bytes]:
    """MAVLink 2 C headers of the ardupilotmega dialect and what it includes, keyed
    ``include/mavlink/ardupilotmega/mavlink.h`` and so on, in sorted order.

    Made once per process (a fresh copy of the dict each call); the same bytes
    on every run with the same pymavlink."""
    return dict(_generate())


@functools.cache
def _generate() -> tuple[tuple[str, bytes], ...]:
    try:
        from pymavlink.generator import mavgen, mavparse
    except ImportError as e:
        raise MavgenError(f"pymavlink is needed for the MAVLink C headers: {e}") from None
    xml = Path(mavgen.__file__).resolve().parent.parent / "dialects" / "v20" / f"{DIALECT}.xml"
    if not xml.is_file():
        raise MavgenError(f"pymavlink ships no {xml}")
    with tempfile.TemporaryDirectory(prefix="hfsmc-mavgen-") as tmp:
        said = io.StringIO()  # mavgen prints its progress: keep it for a failure only
        opts = mavgen.Opts(tmp, wire_protocol=mavparse.PROTOCOL_2_0, language="C",
                           validate=False)
        try:
            with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
                ok = mavgen.mavgen(opts, [str(xml)])
        except Exception as e:  # mavgen raises whatever its parser meets
            raise MavgenError(f"mavgen failed on {xml.name}: {e}\n{said.getvalue()}") from e
        if not ok:
            raise MavgenError(f"mavgen failed on {xml.name}\n{said.getvalue()}")
        files = _needed(Path(tmp), PurePosixPath(DIALECT, "mavlink.h"))
    stamp = f'"pymavlink {importlib.metadata.version("pymavlink")}"'.encode()
    return tuple((str(PREFIX / path), _BUILD_DATE.sub(rb"\1" + stamp, data))
                 for path, data in sorted(files.items()))


def _needed(root: Path, top: PurePosixPath) -> dict[PurePosixPath, bytes]:
    """``top`` and every file it includes with quotes, transitively (paths under ``root``).
    A conditional include counts: what a macro switches on must be there."""
    found: dict[PurePosixPath, bytes] = {}
    todo = [top]
    while todo:
        path = todo.pop()
        if path in found:
            continue
        file = root / path
        if not file.is_file():
            continue  # a header the build supplies (MAVLINK_USE_... hooks), not mavgen's
        found[path] = data = file.read_bytes()
        for name in _INCLUDE.findall(data):
            target = _normalise(path.parent / name.decode("ascii"))
            if target is not None:
                todo.append(target)
    return found


def _normalise(path: PurePosixPath) -> PurePosixPath | None:
    """``a/../b.h`` → ``b.h``; None for a path that leaves the root."""
    parts: list[str] = []
    for part in path.parts:
        if part == "..":
            if not parts:
                return None
            parts.pop()
        elif part != ".":
            parts.append(part)
    return PurePosixPath(*parts)
