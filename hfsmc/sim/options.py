"""What the two simulators' command lines share (`hfsmc sim`, `hfsmc sim --robot`): option
types, the one-line error, and the outputs opened before the loop (the lockstep server, the
truth log)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import IO, Any

from hfsmc.sim import lockstep


class OutputError(Exception):
    """An output that cannot be opened: the one line to say (exit status 2)."""


def seconds(text: str) -> float:
    """An option's seconds (>= 0)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"expected seconds (>= 0), not {text!r}")
    return v


def speedup(text: str) -> float:
    """--speedup's rate (> 0)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive rate (10: ten times real time), "
                                         f"not {text!r}")
    return v


def fail(text: str) -> int:
    """Say a usage or start error in one line; the exit status."""
    print(f"hfsmc: error: {text}", file=sys.stderr)
    return 2


def open_outputs(args: Any, close: Callable[[], None]
                 ) -> tuple[lockstep.Server | None, IO[str] | None]:
    """The lockstep server (``--lockstep``) and the truth log (``--truth-log``). On a failure
    ``close`` (what the caller opened before) and what was opened here are closed, and
    OutputError says why."""
    server = None
    if args.lockstep is not None:
        try:
            server = lockstep.Server(args.lockstep)
        except (ValueError, OSError) as e:
            close()
            raise OutputError(f"--lockstep {args.lockstep}: {e}") from None
    try:
        truth_log = None if args.truth_log is None else open(args.truth_log, "w")  # noqa: SIM115
    except OSError as e:
        close()
        if server is not None:
            server.close()
        raise OutputError(f"--truth-log {args.truth_log}: {e.strerror or e}") from None
    return server, truth_log
