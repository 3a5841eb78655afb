""""Build and run" from the editor's page (docs/editor.md): the saved model run as
``hfsmc run MODEL -- --monitor 127.0.0.1:0`` does, in the model's folder, its stdout and
stderr lines passed to the page, its monitor port read from its own announcement, Stop
as Ctrl+C (SIGINT: the component goes through ``on_interrupt``), then, asked again, a
kill. One run at a time; the run ends when the editor ends, as `hfsmc run` ends on Ctrl+C:
the editor waits for its `on_interrupt` (a landing is never cut short), and kills it only on
a second Ctrl+C, saying that a vehicle may be left armed. The page gives no argument: the
command line is fixed here.

And the C++ check at save: g++ ``-fsyntax-only`` over the generated code, as ``hfsmc
check`` does for a ``language: cpp`` model."""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
import signal
import sys
from collections import deque
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from hfsmc.edit.session import EditSession
from hfsmc.errors import Diagnostic

LOG_LINES = 2000  # kept for a page opened late; older lines are dropped
LINE_LIMIT = 4000  # characters of one line shown; the rest is cut
KILLED = "run killed (SIGKILL): a vehicle it drove may still be armed, or moving"
_ANNOUNCE = re.compile(r"^monitor: listening on (\S+):(\d+)$")


def command(model: Path) -> list[str]:
    """The fixed command line of a run: nothing in it comes from the page."""
    return [sys.executable, "-m", "hfsmc", "run", str(model), "--",
            "--monitor", "127.0.0.1:0"]


class Run:
    """One run of the model: its process, its log, and what it told of its monitor."""

    def __init__(self, model: Path, on_lines: Callable[[list[dict[str, Any]]], Awaitable[None]],
                 on_monitor: Callable[[str, int], Awaitable[None]],
                 on_end: Callable[[int], Awaitable[None]]) -> None:
        self.model = model
        self.log: deque[dict[str, Any]] = deque(maxlen=LOG_LINES)
        self.proc: asyncio.subprocess.Process | None = None
        self.status: int | None = None
        self.stopping = False
        self._on_lines, self._on_monitor, self._on_end = on_lines, on_monitor, on_end
        self._task: asyncio.Task[None] | None = None

    @property
    def running(self) -> bool:
        return self.proc is not None and self.status is None

    async def start(self) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = await asyncio.create_subprocess_exec(
            *command(self.model), cwd=self.model.parent, env=env,
            stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE, start_new_session=True)
        await self._say("run", f"$ hfsmc run {self.model.name} -- --monitor 127.0.0.1:0 "
                        f"(pid {self.proc.pid})")
        self._task = asyncio.create_task(self._watch())

    async def _say(self, stream: str, text: str) -> None:
        line = {"stream": stream, "text": text[:LINE_LIMIT]}
        self.log.append(line)
        await self._on_lines([line])

    async def _read(self, stream: asyncio.StreamReader, name: str) -> None:
        announced = False
        while True:
            try:
                raw = await stream.readline()
            except (ValueError, asyncio.LimitOverrunError):  # a line beyond the limit
                raw = await stream.read(1 << 16)
            if not raw:
                return
            text = raw.decode("utf-8", "replace").rstrip("\r\n")
            await self._say(name, text)
            m = _ANNOUNCE.match(text) if name == "err" and not announced else None
            if m:
                announced = True
                await self._on_monitor(m[1], int(m[2]))

    async def _watch(self) -> None:
        assert self.proc is not None and self.proc.stdout and self.proc.stderr
        await asyncio.gather(self._read(self.proc.stdout, "out"),
                             self._read(self.proc.stderr, "err"))
        self.status = await self.proc.wait()
        why = f"killed by {signal.Signals(-self.status).name}" if self.status < 0 \
            else f"exit status {self.status}"
        await self._say("run", f"the run ended: {why}")
        await self._on_end(self.status)

    def stop(self) -> str:
        """Ctrl+C the first time (the component goes through on_interrupt), a kill the next."""
        if not self.running or self.proc is None:
            return "no run to stop"
        sig = signal.SIGKILL if self.stopping else signal.SIGINT
        self.stopping = True
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, sig)
        return "stopping the run (SIGINT: through on_interrupt; Stop again kills it)" \
            if sig == signal.SIGINT else KILLED

    async def close(self, log: Any = None) -> None:
        """End the run with the editor as Ctrl+C ends `hfsmc run`: SIGINT, then wait for the
        run (its on_interrupt may be landing a drone); a second SIGINT or SIGTERM to the
        editor kills it, and says so on ``log`` (stderr)."""
        log = log if log is not None else sys.stderr
        if self.running and self.proc is not None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGINT)
            again = asyncio.Event()
            loop = asyncio.get_running_loop()
            for sig in (signal.SIGINT, signal.SIGTERM):
                with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                    loop.add_signal_handler(sig, again.set)
            ended = asyncio.ensure_future(self.proc.wait())
            waiting = asyncio.ensure_future(again.wait())
            done, _ = await asyncio.wait({ended, waiting}, timeout=0.5,
                                         return_when=asyncio.FIRST_COMPLETED)
            if not done:
                print(f"hfsmc edit: waiting for the run of {self.model.name} to stop through "
                      "its on_interrupt (Ctrl+C again kills it)", file=log, flush=True)
                done, _ = await asyncio.wait({ended, waiting},
                                             return_when=asyncio.FIRST_COMPLETED)
            if ended not in done:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                print(f"hfsmc edit: {self.model.name}: {KILLED}", file=log, flush=True)
                await ended
            waiting.cancel()
        if self._task is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._task, 2.0)
            if not self._task.done():
                self._task.cancel()


def check_cxx(session: EditSession) -> tuple[list[Diagnostic], str | None]:
    """The saved model's diagnostics with g++'s over a C++ model's snippets (``hfsmc check``
    does the same), and a note when g++ could not check them."""
    from hfsmc.pipeline import compile_file

    result = compile_file(session.path, session.text, cxx=True)
    note = "; ".join(n.split(": ", 1)[-1] for n in result.notes) or None
    return list(result.diagnostics), note
