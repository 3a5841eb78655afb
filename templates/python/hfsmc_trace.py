# hfsmc_trace.py: the records a component writes: its trace file.
# Copied unchanged into every component folder; standard library only.
"""--trace FILE: the run's records as JSON lines (docs/semantics.md §13), and a value as
the records and the live views show it (its repr, cut at 80 characters)."""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Callable
from typing import IO, Any


class Trace:
    """JSON lines (docs/semantics.md §13). A failing write (a full disk) is said once, then ignored."""

    def __init__(self, target: str) -> None:
        self.target = target
        self.broken = False
        self.out: IO[str] = sys.stdout if target == "-" else open(  # noqa: SIM115
            target, "w", encoding="ascii", newline="\n", buffering=1 << 16)

    def write(self, rec: dict[str, Any]) -> None:
        if not self.broken:
            self._io(self.out.write, json.dumps(rec, separators=(",", ":")) + "\n")

    def flush(self) -> None:
        if not self.broken:
            self._io(self.out.flush)

    def close(self) -> None:
        self.flush()
        if self.out is not sys.stdout:
            with contextlib.suppress(OSError):
                self.out.close()

    def _io(self, fn: Callable[..., object], *args: object) -> None:
        try:
            fn(*args)
        except (OSError, ValueError) as e:
            self.broken = True
            sys.stderr.write(f"trace: cannot write to {self.target}: {e}; "
                             "the component goes on without its trace\n")


def short(value: object) -> str:
    try:
        text = repr(value)
    except Exception as e:  # a user type with a broken __repr__
        text = f"<repr failed: {type(e).__name__}>"
    return text if len(text) <= 80 else text[:77] + "..."
