"""The editor's live side (docs/editor.md): the overlay of a running component's active
states (``hfsmc edit MODEL --monitor TARGET``, or the page's own Build and run), read by
the web view's monitor client (hfsmc/web/bridge.py), with editing paused while it is on;
and the run started from the page (hfsmc/editor/build.py).

The pages get ``live`` messages (what is lit, the component's status, whether editing is
paused, whether a run is on) and ``run_log`` messages (the run's output lines)."""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from hfsmc.editor.build import Run
from hfsmc.web.bridge import Bridge, Page, Picture

# What the page may ask of the live side; nothing else reaches this module.
OPS = ("live_resume", "live_watch", "run_start", "run_stop")
PAUSED = ("editing is paused while the running component is shown: Resume editing first "
          "(docs/editor.md)")


class _Quiet(io.StringIO):
    """Where the bridge's status lines go: the page shows them, not the terminal."""

    def write(self, s: str) -> int:
        return len(s)


async def _no_picture(structure: dict[str, Any]) -> Picture:
    return Picture(None, "")  # the editor draws its own canvas


class Live:
    """The overlay and the run of one editor; ``tell(message)`` sends to every page."""

    def __init__(self, model: Path, tell: Callable[[dict[str, Any]], Awaitable[None]],
                 target: tuple[str, int] | None = None) -> None:
        self.model = model
        self._tell = tell
        self.target = target  # --monitor's, watched again by "live_watch"
        self.bridge: Bridge | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self.active: list[str] = []
        self.run: Run | None = None
        self._said: str = ""

    @property
    def paused(self) -> bool:
        """Editing is paused while the overlay is on."""
        return self.bridge is not None

    # ----- what the pages are told

    def message(self) -> dict[str, Any]:
        b = self.bridge
        connected = b is not None and b.status == "connected"
        run = self.run
        return {"type": "live", "on": b is not None,
                "target": b.label if b is not None else None,
                "status": b.status if b is not None else None,
                "note": b.note if b is not None else None,
                "active": self.active if connected else [],
                "stopped": bool(b is not None and b.view.stop_reason),
                "can_watch": self.target is not None,
                "run": {"running": run.running, "stopping": run.stopping,
                        "status": run.status} if run is not None else None}

    async def tell(self) -> None:
        msg = self.message()
        text = json.dumps(msg)
        if text != self._said:
            self._said = text
            await self._tell(msg)

    def log_message(self) -> dict[str, Any]:
        return {"type": "run_log", "reset": True,
                "lines": list(self.run.log) if self.run is not None else []}

    # ----- what a page asks

    async def handle(self, op: str, saved: bool, conflict: bool) -> str | None:
        if op == "live_resume":
            await self.drop()
            return "editing resumed"
        if op == "live_watch":
            if self.target is None:
                return "no component to watch: start hfsmc edit with --monitor TARGET"
            await self.watch(*self.target)
            return None
        if op == "run_start":
            return await self.start_run(saved, conflict)
        if op == "run_stop":
            return self.run.stop() if self.run is not None else "no run to stop"
        return None

    async def start_run(self, saved: bool, conflict: bool) -> str | None:
        if self.run is not None and self.run.running:
            return "a run is on already: Stop it first (one run at a time)"
        if conflict:
            return "not run: the file changed on disk (Reload first)"
        if not saved:
            return f"not run: save first (the run builds {self.model.name} as saved)"
        self.run = Run(self.model, self._lines, self.watch, self._ended)
        await self._tell(self.log_message())
        await self.drop()  # a fresh overlay for the run, once it announces its monitor
        await self.run.start()
        await self.tell()
        return "built and running: the states light up as it runs; Stop is Ctrl+C"

    async def _lines(self, lines: list[dict[str, Any]]) -> None:
        await self._tell({"type": "run_log", "lines": lines})

    async def _ended(self, status: int) -> None:
        await self.tell()

    # ----- the overlay

    async def watch(self, host: str, port: int) -> None:
        """Show the component at ``host:port`` (and pause editing) until dropped."""
        await self.drop()
        self.bridge = Bridge(host, port, _no_picture, log=_Quiet())
        self._tasks = [asyncio.create_task(self.bridge.run()),
                       asyncio.create_task(self._follow(self.bridge))]
        await self.tell()

    async def _follow(self, bridge: Bridge) -> None:
        """The bridge's messages, as a page of the web view gets them, turned into what
        is lit (told when it changes)."""
        while True:
            page: Page = bridge.attach()
            while (text := await page.queue.get()) is not None:
                if '"type":"delta"' in text and '"enter"' not in text and '"exit"' not in text \
                        and '"stop"' not in text:
                    continue  # the clock only
                self.active = list(bridge.view.active)
                await self.tell()
            bridge.detach(page)  # dropped for falling behind: attach again

    async def drop(self) -> None:
        """The overlay off, editing back."""
        tasks, self._tasks, self.bridge, self.active = self._tasks, [], None, []
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t
        await self.tell()

    async def close(self) -> None:
        """The editor stops: the overlay off and the run ended."""
        await self.drop()
        if self.run is not None:
            await self.run.close()
