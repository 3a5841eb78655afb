"""The terminal under the live view of a running hfsmc component (``hfsmc_view``).

Copied beside every generated Python component, and imported by ``hfsmc view``:
standard library only. ``Keys`` reads single keys in cbreak mode (only from a terminal in
the foreground, its settings restored at the end); ``QueueWriter`` stands in for
sys.stdout and sys.stderr so that what the component prints goes above the tree.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import select
import sys
import threading
from collections.abc import Callable
from typing import Any, TextIO

if __package__:
    from .hfsmc_viewstate import Item
else:  # copied beside the generated component, where the modules are top level
    from hfsmc_viewstate import Item  # type: ignore[import-not-found, no-redef]


def isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


class Keys:
    """Single keys from the terminal (cbreak mode), put on the queue as ("key", ch).

    Only when stdin is a terminal and this process is in its foreground; the
    terminal's settings are restored by ``stop`` (and at exit, as a safety net).
    """

    def __init__(self, put: Callable[[Item], None]) -> None:
        self._put = put
        self.why: str | None = "not started"  # why keys are not read (None: they are)
        self._old: list[Any] | None = None
        self._fd = -1
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        try:
            import termios
            import tty

            fd = sys.stdin.fileno()
            if not os.isatty(fd):
                self.why = "stdin is not a terminal"
                return
            if os.tcgetpgrp(fd) != os.getpgrp():
                self.why = "in the background"
                return
            self._fd, self._old = fd, termios.tcgetattr(fd)
            tty.setcbreak(fd, termios.TCSANOW)
        except (ImportError, OSError, ValueError, AttributeError):
            self._old = None
            self.why = "stdin is not a terminal"
            return
        self.why = None
        atexit.register(self.stop)
        self._thread = threading.Thread(target=self._run, name="hfsmc-keys", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                # In the background (Ctrl-Z, bg) reading would stop the process: the keys
                # wait, and the panel says so, until the job is in the foreground again.
                foreground = os.tcgetpgrp(self._fd) == os.getpgrp()
                self._say(None if foreground else "in the background")
                if not foreground:
                    self._stop.wait(0.1)
                    continue
                ready, _, _ = select.select([self._fd], [], [], 0.1)
                if ready and os.tcgetpgrp(self._fd) == os.getpgrp():
                    data = os.read(self._fd, 64)
                    if not data:
                        self._say("stdin closed")
                        return
                    for ch in data.decode("utf-8", "replace"):
                        self._put(("key", ch))
        except (OSError, ValueError):
            self._say("stdin closed")

    def _say(self, why: str | None) -> None:
        if why != self.why:
            self.why = why
            self._put(("keys", why))  # the panel says so at the next frame

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(0.2)
        if self._old is not None:
            import signal
            import termios

            # Sent to the background meanwhile: tcsetattr would stop the process on
            # SIGTTOU unless the signal is blocked (POSIX lets the call through then).
            blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTTOU})
            with contextlib.suppress(OSError, termios.error):
                termios.tcsetattr(self._fd, termios.TCSADRAIN, self._old)
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
            self._old = None
        atexit.unregister(self.stop)


class QueueWriter:
    """Stands in for sys.stdout / sys.stderr under the live view: whole lines go on the
    queue as ("text", line) and the display thread prints them above the tree."""

    def __init__(self, put: Callable[[Item], None], original: TextIO) -> None:
        self._put, self.original, self._buf = put, original, ""
        self.encoding = getattr(original, "encoding", "utf-8")

    def write(self, s: str) -> int:
        self._buf += s
        if "\n" in self._buf:
            done, _, self._buf = self._buf.rpartition("\n")
            self._put(("text", done))
        return len(s)

    def flush(self) -> None:
        if self._buf:
            self._put(("text", self._buf))
            self._buf = ""

    def isatty(self) -> bool:
        return isatty(self.original)

    def fileno(self) -> int:
        return self.original.fileno()
