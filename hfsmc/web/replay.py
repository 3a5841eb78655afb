"""The web view of a recorded run (``hfsmc view --web PORT --replay TRACE``): docs/web.md.

``Replay`` is a ``Bridge`` whose records come from a trace file instead of a
monitor. It keeps one position in the trace for every page (a seek in one
browser moves them all) and is told by the pages to play, pause, change speed,
step to the next or previous transition, or seek. What is active at an instant
is computed here, in ``view_at``, from the trace's ``enter`` and ``exit``
records (and the others a viewer applies), never by the page.

The variables come from the trace's ``variables`` records (a component's
``--trace-variables``, docs/component.md): at an instant, the values the last
records up to it gave. A trace without them shows no variables, and the page
says so.
"""

from __future__ import annotations

import asyncio
import bisect
import contextlib
import json
import math
from collections.abc import Awaitable, Callable
from typing import Any, TextIO

# The component's own module, shipped as the data package hfsmc.templates (see hfsmc/commands/view.py).
from hfsmc.templates.python import hfsmc_viewstate as viewstate  # type: ignore[import-not-found]
from hfsmc.web.bridge import Bridge, Picture

TICK_S = 0.1  # while playing, the pages' clock moves on this often
SPEED_MIN, SPEED_MAX = 0.01, 1000.0
COMMAND_LIMIT = 256  # characters: a page's command is short; longer text is ignored


def view_at(structure: dict[str, Any] | None, records: list[dict[str, Any]], t_ms: int) -> Any:
    """The viewer's state (a ``ViewState``) at ``t_ms``: every record up to it applied."""
    view = viewstate.ViewState(structure)
    for rec in records:
        if int(rec["t"]) > t_ms:
            break
        view.apply_record(rec)
    view.advance(t_ms)
    return view


def active_at(structure: dict[str, Any] | None, records: list[dict[str, Any]],
              t_ms: int) -> list[str]:
    """The states active at ``t_ms``, outermost first as they were entered."""
    return list(view_at(structure, records, t_ms).active)


class Replay(Bridge):
    """A trace played to the pages; ``command`` takes what a page's controls send."""

    def __init__(self, records: list[dict[str, Any]], structure: dict[str, Any], name: str,
                 paint: Callable[[dict[str, Any]], Awaitable[Picture]], *, speed: float = 1.0,
                 autofocus: bool = True, log: TextIO | None = None) -> None:
        super().__init__("", 0, paint, autofocus=autofocus, log=log)
        # Records in time order (a trace's are; stable for equal times).
        self.records = sorted(records, key=lambda r: int(r["t"]))
        self._times = [int(r["t"]) for r in self.records]
        self.label = name
        self.watching = f"replay of {name}"
        self._structure = structure
        self.end = self._times[-1] if self._times else 0
        self.fires = sorted({int(r["t"]) for r in self.records if r.get("ev") == "fire"})
        self.position = 0  # ms into the trace
        self.playing = False
        self.speed = speed if speed > 0 else 1.0
        self._next = 0  # index of the next record to apply while playing
        self._wake = asyncio.Event()
        self.status = "replay"
        self.has_variables = any(r.get("ev") == "variables" for r in self.records)
        self.note = (f"replay of {name}: {len(self.records)} records, {self.end / 1000:.3f} s"
                     + ("" if self.has_variables else "; the trace has no variable records, so no "
                        "variables are shown"))
        self.view = view_at(structure, [], 0)

    # -- what the pages are told ---------------------------------------------------------------
    def model_message(self) -> dict[str, Any]:
        msg = super().model_message()
        msg["replay"] = {"trace": self.label, "end": self.end, "fires": self.fires,
                         "variables": self.has_variables}
        return msg

    def state_message(self) -> dict[str, Any]:
        msg = super().state_message()
        msg["replay"] = self._where()
        return msg

    def _where(self) -> dict[str, Any]:
        return {"t": self.position, "playing": self.playing, "speed": self.speed,
                "end": self.end}

    def _tell_position(self) -> None:
        self._broadcast({"type": "replay", **self._where()})

    def _seek(self, t_ms: int) -> None:
        """Show the instant ``t_ms``: the view rebuilt from the records up to it."""
        self.position = max(0, min(int(t_ms), self.end))
        self.view = view_at(self._structure, self.records, self.position)
        self._next = bisect.bisect_right(self._times, self.position)
        self._pending.fired, self._pending.logs = [], []
        self._broadcast(self.state_message())

    # -- the pages' controls ----------------------------------------------------------------
    def command(self, text: str) -> None:
        """Apply one command a page sent (docs/web.md); anything else is ignored."""
        if len(text) > COMMAND_LIMIT:
            return
        try:
            msg = json.loads(text)
        except ValueError:
            return
        if not isinstance(msg, dict):
            return
        what = msg.get("do")
        if what == "play":
            if self.position >= self.end:
                self._seek(0)
            self.playing = True
        elif what == "pause":
            self.playing = False
        elif what == "speed":
            x = msg.get("speed")
            if not isinstance(x, (int, float)) or isinstance(x, bool) or not math.isfinite(x):
                return
            self.speed = min(max(float(x), SPEED_MIN), SPEED_MAX)
        elif what == "seek":
            t = msg.get("t")
            if not isinstance(t, (int, float)) or isinstance(t, bool) or not math.isfinite(t):
                return
            self.playing = False
            self._seek(int(t))
        elif what in ("next", "previous"):
            self.playing = False
            self._seek(self.step(what == "next"))
        else:
            return
        self._tell_position()
        self._wake.set()

    def step(self, forward: bool) -> int:
        """The time of the next (or previous) transition from the position; the end (or 0)
        when there is none."""
        if forward:
            i = bisect.bisect_right(self.fires, self.position)
            return self.fires[i] if i < len(self.fires) else self.end
        i = bisect.bisect_left(self.fires, self.position)
        return self.fires[i - 1] if i > 0 else 0

    # -- playing ------------------------------------------------------------------------------
    async def run(self) -> None:
        """Draw the picture, then play while told to, until cancelled."""
        picture = await self._paint(self._structure)
        self.structure, self.picture = self._structure, picture
        self._broadcast(self.model_message())
        self._seek(0)
        loop = asyncio.get_running_loop()
        while True:
            if not self.playing:
                self._wake.clear()
                await self._wake.wait()
                continue
            start_pos, start = self.position, loop.time()
            while self.playing:
                self._wake.clear()
                pos = start_pos + int((loop.time() - start) * 1000 * self.speed)
                self._play_to(min(pos, self.end))
                if self.position >= self.end:
                    self.playing = False
                    self._tell_position()
                    break
                speed = self.speed
                nxt = self._times[self._next] if self._next < len(self._times) else self.end
                wait = min(TICK_S, max((nxt - self.position) / 1000 / speed, 0.0))
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._wake.wait(), wait)
                if self._wake.is_set():  # a command: start again from where it left us
                    break

    def _play_to(self, t_ms: int) -> None:
        """Apply the records up to ``t_ms`` as the monitor would send them, then tell the pages.

        Each instant of the trace is its own delta, so that a state entered and left
        between two ticks (at a high speed) is still drawn.
        """
        while self._next < len(self.records) and self._times[self._next] <= t_ms:
            instant = self._times[self._next]
            while self._next < len(self.records) and self._times[self._next] == instant:
                self._apply("record", self.records[self._next])
                self._next += 1
            self._flush()
        self.view.advance(t_ms)
        self.position = t_ms
        self._flush()
        self._tell_position()
