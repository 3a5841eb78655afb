"""The live terminal view of a running hfsmc component.

Copied beside every generated Python component, and imported by ``hfsmc
view``: standard library only, ``rich`` imported lazily (without it, or
without a terminal, the view prints one plain line per transition).

- ``ViewState`` (in ``hfsmc_viewstate``, re-exported here): what a viewer
  knows. The one model fed by the component's observer calls, by the monitor
  protocol and by trace replay.
- ``render``: a ``ViewState`` as a rich tree of the hierarchy and a side panel.
- ``Display``: the observer behind the component's ``--display``.
- ``run_viewer``: the display loop behind ``hfsmc view``.

The automaton thread only puts items on a queue; one thread of this module
owns the ``ViewState`` and the terminal, so the two never share data.

On a terminal: active states green with their time in state, the states a
stop left yellow, others dim; a parallel state (``‖``) holds its regions as
named groups (``[Watch 200 ms history]``) with their states; a state whose
sub-automaton is used from another file names it (``TakeOff · lib/takeoff.yaml``);
autofocus folds inactive composite states (key ``a`` toggles it; ``q`` quits
``hfsmc view``); lines the component prints go above the tree. Plain lines:
``  0.000  start NAME in PATH``, then ``  1.350  FROM -> TO  (name)`` per transition
(only those inside the focus state with ``--focus``), ``interrupt (REASON) -> STATE`` and ``stop (REASON)``.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import queue
import select
import sys
import threading
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from rich.console import RenderableType
    from rich.text import Text

if __package__:
    from . import hfsmc_driverview as _driverview
    from . import hfsmc_ros2view as _ros2view
    from .hfsmc_viewstate import (
        EVENTS,
        RECENT,
        Item,
        PlainLines,
        ViewState,
        check_record,
        clean,
        infer_structure,
        readable,
    )
else:  # copied beside the generated component, where the modules are top level
    import hfsmc_driverview as _driverview  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2view as _ros2view  # type: ignore[import-not-found, no-redef]
    from hfsmc_viewstate import (  # type: ignore[import-not-found, no-redef]
        EVENTS,
        RECENT,
        Item,
        PlainLines,
        ViewState,
        check_record,
        clean,
        infer_structure,
        readable,
    )

__all__ = ["EVENTS", "RECENT", "Display", "Item", "PlainLines", "ViewState", "check_record",
           "clean", "fit", "infer_structure", "readable", "render", "run_viewer"]

REFRESH_S = 0.25  # the live view redraws at 4 Hz
STALE_S = 2.0  # a topic whose latest message is older is shown yellow

# -- the rich view -------------------------------------------------------------------------
def _dur(ms: int) -> str:
    ms = max(ms, 0)
    if ms < 60_000:
        return f"{ms / 1000:.1f}s"
    m, s = divmod(ms // 1000, 60)
    return f"{m}m{s:02d}s" if m < 60 else f"{m // 60}h{m % 60:02d}m"


def _lit(view: ViewState, path: str) -> bool:
    if path in view.regions:
        path = path.rpartition("/")[0]
    return path in view.active or (view.stop_reason is not None and path in view.stopped_in)


def _period(view: ViewState, path: str) -> str:
    return f"{view.periods[path]} ms" + (" history" if path in view.history else "") \
        if path in view.periods else ("history" if path in view.history else "")


def _region_label(view: ViewState, path: str, collapsed: int) -> Text:
    """A region: ``[Watch 200 ms history]``, green while its state is active."""
    from rich.text import Text

    owner = path.rpartition("/")[0]
    style = "green" if owner in view.active else \
        "yellow" if view.stop_reason is not None and owner in view.stopped_in else "dim"
    label = Text(" ".join(x for x in ("[" + clean(path.rpartition("/")[2]), _period(view, path)) if x)
                 + "]", style=style)
    if collapsed:
        label.append(f"  ▸ {collapsed} states", style="dim")
    label.no_wrap, label.overflow = True, "ellipsis"
    return label


def _label(view: ViewState, path: str, collapsed: int) -> Text:
    from rich.text import Text

    if path in view.regions:
        return _region_label(view, path, collapsed)
    name = clean(path.rpartition("/")[2] or view.name)
    if any(c in view.regions for c in view.children.get(path, ())):
        name += " ‖"  # a parallel state: its children are its regions
    # The file its sub-automaton is used from, if it is (``● TakeOff · lib/takeoff.yaml  1.2s``).
    used = f" · {clean(view.uses[path])}" if path in view.uses else ""
    if path in view.active:
        label = Text(f"● {name}", style="bold green")
        label.append(used, style="dim")
        label.append(f"  {_dur(view.t_ms - view.active[path])}", style="green")
    elif view.stop_reason is not None and path in view.stopped_in:
        label = Text(f"■ {name}", style="bold yellow")
        label.append(used, style="dim")
        label.append(f"  {_dur(view.t_ms - view.stopped_in[path])}, at stop", style="yellow")
    else:
        label = Text(f"○ {name}", style="dim")
        label.append(used, style="dim")
    if path in view.final:
        label.append("  final", style="dim italic")
    if path in view.periods:
        label.append(f"  {view.periods[path]} ms" + (" history" if path in view.history else ""),
                     style="dim")
    if collapsed:
        regions = name.endswith(" ‖")
        label.append(f"  ▸ {collapsed} {'regions' if regions else 'states'}", style="dim")
    label.no_wrap, label.overflow = True, "ellipsis"  # one line per state, whatever the width
    return label


def _status(view: ViewState) -> Text:
    from rich.text import Text

    if view.stop_reason is not None:
        text = Text(f"stopped ({clean(view.stop_reason)})", style="bold yellow")
    elif view.interrupt is not None:
        text = Text(f"interrupt ({clean(view.interrupt['reason'])}) -> {clean(view.interrupt['to'])}",
                    style="bold red")
    elif view.started:
        text = Text("running", style="bold green")
    else:
        text = Text("not started", style="dim")
    if view.note:
        text.append(f"; {clean(view.note)}", style="bold")
    return text


def _tree(view: ViewState, focus: str, autofocus: bool, max_rows: int = 1 << 30
          ) -> tuple[RenderableType, int]:
    """The tree of states, and its height: at most ``max_rows`` lines (then `…`)."""
    from rich.text import Text
    from rich.tree import Tree

    if focus and focus not in view.children:
        tree = Tree(Text(clean(view.name or "?"), style="bold"))
        tree.add(Text(f"no state {clean(focus)}", style="yellow"))
        return tree, 2
    title = _label(view, focus, 0) if focus else Text(clean(view.name or "?"), style="bold")
    if not focus and "" in view.periods:
        title.append(f"  {view.periods['']} ms", style="dim")
    tree = Tree(title, guide_style="dim")
    shown = _walk(view, focus, autofocus)
    cut = len(shown) + 1 > max(max_rows, 2)
    if cut:
        shown = shown[:max(max_rows, 2) - 2]
    nodes: dict[str, Tree] = {focus: tree}
    for parent, child, expand in shown:
        grand = view.children[child]
        nodes[child] = nodes[parent].add(_label(view, child, 0 if expand else len(grand)))
    if cut:
        tree.add(Text("…", style="dim"))
    return tree, len(shown) + 1 + cut


def fit(free: int, want: dict[str, int]) -> dict[str, int]:
    """How many lines of each panel section (``transitions``, ``logs``, ``variables``: the
    items it has) fit in ``free`` lines, a heading each: the longer history is cut first,
    down to one line each, then the variables, then whole sections."""
    keep = dict(want)

    def total() -> int:
        return sum(k + 1 for k in keep.values() if k)

    while total() > free:
        history = [s for s in ("transitions", "logs") if keep[s] > 1]
        if history:
            keep[max(history, key=lambda s: keep[s])] -= 1
        elif keep["variables"] > 1:
            keep["variables"] -= 1
        else:
            dropped = next((s for s in ("logs", "transitions", "variables") if keep[s]), None)
            if dropped is None:
                break
            keep[dropped] = 0
    return keep


def _autofocus(autofocus: bool, keys: str | None) -> str:
    """The autofocus line: the key hint only when keys are read (``keys``: why not)."""
    state = "on" if autofocus else "off"
    return f"{state} (a: {'off' if autofocus else 'on'})" if keys is None else \
        f"{state} (no keys: {keys})"


def _one_line(text: str, style: str = "") -> Text:
    from rich.text import Text

    return Text(text, style=style, no_wrap=True, overflow="ellipsis")


def _walk(view: ViewState, focus: str, autofocus: bool) -> list[tuple[str, str, bool]]:
    """The states (and regions) the tree shows, depth first in model order: (parent, path,
    expanded). A region is expanded with its state: autofocus follows every region."""
    out: list[tuple[str, str, bool]] = []

    def visit(path: str) -> None:
        for child in view.children[path]:
            grand = view.children[child]
            expand = bool(grand) and (not autofocus or _lit(view, child) or not view.started)
            out.append((path, child, expand))
            if expand:
                visit(child)

    visit(focus)
    return out


def _rate(x: object) -> str:
    return f"{x:.1f} Hz" if isinstance(x, int | float) and not isinstance(x, bool) else "– Hz"


def ros2_rows(msg: dict[str, Any]) -> list[tuple[list[str], str]]:
    """A ``ros2`` message as the terminal view's rows: (cells, style), the node first,
    then ``<-`` per subscription (rate, age, count, matched publishers, dropped) and ``->``
    per publication (rate, count, matched subscribers). Red: a subscription that never got
    a message or has no publisher, a publication nobody subscribes to, dropped samples;
    yellow: a message older than STALE_S."""
    ns = clean(msg.get("namespace") or "/")
    node = f"{ns.rstrip('/')}/{clean(msg.get('node'))}"
    rows = [([f"ros2 {clean(msg.get('name'))}", node, f"domain {clean(msg.get('domain'))}",
              clean(msg.get("distro")), "", ""], "bold")]
    for s in msg.get("subscriptions", ()):
        age = s.get("age")
        style = ""
        if not s.get("count") or not s.get("publishers"):
            style = "red"
        elif isinstance(age, int | float) and age > STALE_S:
            style = "yellow"
        seen = f"{age:.2f} s ago" if isinstance(age, int | float) else "never"
        extra = f"  {s['dropped']} dropped" if s.get("dropped") else ""
        rows.append(([f"<- {clean(s.get('name'))}", clean(s.get("topic")), _rate(s.get("rate")),
                      seen, f"n {clean(s.get('count'))}",
                      f"{clean(s.get('publishers'))} pub{extra}"],
                     "red" if extra else style))
    for p in msg.get("publications", ()):
        rows.append(([f"-> {clean(p.get('name'))}", clean(p.get("topic")), _rate(p.get("rate")),
                      "", f"n {clean(p.get('count'))}", f"{clean(p.get('subscribers'))} sub"],
                     "" if p.get("subscribers") else "red"))
    return rows


def _ros2_part(view: ViewState) -> tuple[list[RenderableType], int]:
    """The ros2 interfaces' topics, and the lines they take."""
    from rich.table import Table

    parts: list[RenderableType] = []
    lines = 0
    for name in sorted(view.ros2):
        table = Table.grid(padding=(0, 2))
        for _ in range(6):
            table.add_column(no_wrap=True)
        for cells, style in ros2_rows(view.ros2[name]):
            table.add_row(*cells, style=style)
            lines += 1
        parts.append(table)
    for name in sorted(view.drivers):  # a user driver's snapshot: field, value
        table = Table.grid(padding=(0, 2))
        table.add_column(no_wrap=True, style="magenta")
        table.add_column(no_wrap=True, overflow="ellipsis")
        title, *rows = _driverview.driver_rows(view.drivers[name])
        table.add_row(clean(title[0]), "", style="bold")
        for field, value in rows:
            table.add_row(clean(field), clean(value))
        lines += 1 + len(rows)
        parts.append(table)
    return parts, lines


def _panel(view: ViewState, autofocus: bool, free: int = 1 << 30, keys: str | None = None
           ) -> RenderableType:
    """The side panel in at most ``free`` lines (its frame included)."""
    from rich.console import Group
    from rich.panel import Panel
    from rich.table import Table
    from rich.text import Text

    facts = Table.grid(padding=(0, 2))
    facts.add_column(style="bold")
    facts.add_column()
    time_row = Text(f"{view.t_ms / 1000:.3f} s")
    if view.sim_rate is not None:  # --clock sim: the simulator's time, and how fast it runs
        time_row.append(" simulated, ")
        time_row.append(f"{view.sim_rate:.1f}× real time", style="bold cyan")
    facts.add_row("time", time_row)
    facts.add_row("status", _status(view))
    if view.interrupt is not None:
        i = view.interrupt
        facts.add_row("interrupt", f"{clean(i['reason'])} at {i['t'] / 1000:.3f} s -> {clean(i['to'])}")
    facts.add_row("overruns", Text(str(view.overruns), style="bold red" if view.overruns else ""))
    facts.add_row("autofocus", _autofocus(autofocus, keys))
    names = view.variable_names + sorted(set(view.values) - set(view.variable_names))
    topics, topic_lines = _ros2_part(view)
    keep = fit(free - 2 - facts.row_count - topic_lines, {"transitions": len(view.transitions),
                                             "logs": len(view.logs), "variables": len(names)})
    parts: list[RenderableType] = [facts, *topics]
    if keep["transitions"]:
        rows = Table.grid(padding=(0, 1))
        for tr in list(reversed(view.transitions))[:keep["transitions"]]:
            line = _one_line(f"{tr['t'] / 1000:8.3f}  {clean(tr['from'])} -> {clean(tr['to'])}")
            if tr.get("name"):
                line.append(f"  {clean(tr['name'])}", style="cyan")
            rows.add_row(line)
        parts += [Text("recent transitions", style="bold"), rows]
    if keep["variables"]:
        rows = Table.grid(padding=(0, 1))
        rows.add_column(no_wrap=True, min_width=max(len(clean(n)) for n in names))
        rows.add_column(no_wrap=True, overflow="ellipsis")
        shown = names if keep["variables"] == len(names) else names[:keep["variables"] - 1]
        for n in shown:
            rows.add_row(_one_line(clean(n), "magenta"),
                         _one_line(clean(readable(view.values.get(n, "?")))))
        if len(shown) < len(names):
            rows.add_row(_one_line(f"… {len(names) - len(shown)} more", "dim"))
        parts += [Text("variables", style="bold"), rows]
    if keep["logs"]:
        rows = Table.grid(padding=(0, 1))
        rows.add_column(no_wrap=True, min_width=8)
        rows.add_column(no_wrap=True, min_width=min(max(len(clean(lg["state"]) or "on_shutdown")
                                                        for lg in view.logs), 30))
        rows.add_column(no_wrap=True, overflow="ellipsis")
        for lg in list(view.logs)[-keep["logs"]:]:
            where = clean(lg["state"]) or "on_shutdown"
            msg = (_one_line(f"error in {clean(lg['error'])}", "red") if "error" in lg
                   else _one_line(clean(lg["msg"])))
            rows.add_row(Text(f"{lg['t'] / 1000:8.3f}"), Text(where, style="dim"), msg)
        parts += [Text("log", style="bold"), rows]
    return Panel(Group(*parts), title=clean(view.name or "hfsmc"), title_align="left", expand=False)


def render(view: ViewState, focus: str | None = None, autofocus: bool = True,
           width: int = 120, height: int | None = None, keys: str | None = None
           ) -> RenderableType:
    """The view as rich renderables: the tree, and the panel beside (or below) it, in
    ``height - 1`` lines at most when a height is given (the last line stays free for
    the cursor). ``keys``: why keys are not read, if they are not (the autofocus line)."""
    from rich.console import Group
    from rich.table import Table

    rows = (height - 1) if height else 1 << 30
    focus = (focus or "").strip("/")
    if width < 100:
        # Under the tree, the panel keeps its frame, its facts and up to 6 lines of its
        # sections; the tree may take the rest (and leaves what it does not use).
        items = [len(view.transitions), len(view.logs),
                 len(set(view.variable_names) | set(view.values))]
        panel_min = 2 + 4 + (view.interrupt is not None) + min(sum(n + 1 for n in items if n), 6) \
            + sum(1 + len(m.get("subscriptions", ())) + len(m.get("publications", ()))
                  for m in view.ros2.values()) \
            + sum(1 + len(m.get("fields", ())) for m in view.drivers.values())
        tree, used = _tree(view, focus, autofocus, max(rows - panel_min, 2))
        return Group(tree, _panel(view, autofocus, rows - used, keys))
    tree, _ = _tree(view, focus, autofocus, rows)
    panel = _panel(view, autofocus, rows, keys)
    grid = Table.grid(padding=(0, 3))
    grid.add_column(min_width=30)
    grid.add_column()
    grid.add_row(tree, panel)
    return grid


def _rich_missing() -> bool:
    try:
        import rich  # noqa: F401
    except ImportError:
        return True
    return False


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


# -- terminal plumbing -------------------------------------------------------------------------
class _Keys:
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


class _QueueWriter:
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
        return _isatty(self.original)

    def fileno(self) -> int:
        return self.original.fileno()


# -- the display loop ------------------------------------------------------------------------
class _Screen:
    """Owns a ViewState and the terminal; consumes items until ("end" | "error" | quit)."""

    def __init__(self, focus: str | None, autofocus: bool, stream: TextIO, live: bool,
                 quit_key: bool) -> None:
        self.view = ViewState()
        self.focus, self.autofocus, self.stream = focus, autofocus, stream
        self.live, self.quit_key = live, quit_key
        self.plain = PlainLines(focus)
        self.keys: str | None = "stdin is not a terminal"  # why keys are not read, if not
        self.poll: Callable[[], list[Item]] | None = None  # items to apply before each redraw

    def run(self, q: queue.SimpleQueue[Item]) -> tuple[int, str | None]:
        """(exit status, closing message) once the source ends or the user quits."""
        return self._run_live(q) if self.live else self._run_plain(q)

    def _run_plain(self, q: queue.SimpleQueue[Item]) -> tuple[int, str | None]:
        while True:
            kind, payload = q.get()
            if kind in ("end", "error"):
                self._write(self.plain.lines(self.view, kind, payload))
                return (0 if kind == "end" else 1), payload
            if kind == "text":
                continue
            try:
                self._write(self.plain.lines(self.view, kind, payload))
                self.view.apply(kind, payload)
            except Exception:  # malformed data (from a remote component, say): skip it
                continue

    def _write(self, lines: list[str]) -> None:
        if lines:
            try:
                self.stream.write("".join(line + "\n" for line in lines))
                self.stream.flush()
            except (OSError, ValueError):  # a closed pipe must not stop the component
                pass

    def _run_live(self, q: queue.SimpleQueue[Item]) -> tuple[int, str | None]:
        from rich.console import Console
        from rich.live import Live
        from rich.text import Text

        console = Console(file=self.stream, highlight=False)
        result: tuple[int, str | None] | None = None
        with Live(console=console, auto_refresh=False, redirect_stdout=False,
                  redirect_stderr=False, vertical_overflow="crop") as live:
            due = 0.0
            while result is None:
                try:
                    kind, payload = q.get(timeout=max(due - time.monotonic(), 0.0))
                except queue.Empty:
                    kind, payload = "tick", None
                if kind in ("end", "error"):
                    self.view.note = payload if kind == "end" else None
                    result = (0 if kind == "end" else 1), payload
                elif kind == "text":
                    console.print(Text.from_ansi(payload), soft_wrap=True)
                elif kind == "keys":
                    self.keys, due = payload, 0.0
                elif kind == "key":
                    if payload in ("a", "A"):
                        self.autofocus, due = not self.autofocus, 0.0
                    elif payload in ("q", "Q") and self.quit_key:
                        result = 0, None
                else:
                    with contextlib.suppress(Exception):  # malformed data: skipped
                        self.view.apply(kind, payload)
                if result is not None or time.monotonic() >= due:
                    for polled in self.poll() if self.poll is not None else ():
                        with contextlib.suppress(Exception):
                            self.view.apply(*polled)
                    live.update(render(self.view, self.focus, self.autofocus, console.width,
                                       console.height, self.keys), refresh=True)
                    due = time.monotonic() + REFRESH_S
        return result


class Display:
    """The ``--display`` observer: a live tree on a terminal, plain lines otherwise.

    Every observer call only puts an item on a queue; the display thread owns
    the view and the terminal, and ``close`` returns within about a second.
    """

    def __init__(self, focus: str | None = None, autofocus: bool = True,
                 stream: TextIO | None = None) -> None:
        self._stream = stream if stream is not None else sys.stdout
        self._focus, self._autofocus = focus, autofocus
        self._q: queue.SimpleQueue[Item] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._keys: _Keys | None = None
        self._writers: list[tuple[str, _QueueWriter]] = []
        self._ros2: dict[str, Any] = {}
        self._drivers: dict[str, Any] = {}
        self._rates = _ros2view.Rates()
        self._t_ms = 0

    def watch(self, interfaces: dict[str, Any]) -> None:
        """The component's interface objects (before ``start``): a live ros2 node's topics
        and a user driver's snapshot are shown under the panel's facts, as the monitor
        sends them."""
        for name, obj in interfaces.items():
            with contextlib.suppress(Exception):  # an interface it cannot drive raises on use
                if _driverview.is_driver(obj):
                    self._drivers[name] = obj
                elif callable(getattr(obj, "views", None)) and callable(getattr(obj, "publish", None)):
                    self._ros2[name] = obj

    def _poll(self) -> list[Item]:
        """On the display's thread, at each redraw: the ros2 nodes' topics, the drivers'
        snapshots."""
        now = time.monotonic()
        out: list[Item] = []
        for name, node in self._ros2.items():
            with contextlib.suppress(Exception):
                out.append(("ros2", _ros2view.ros2_message(name, self._t_ms, node.views(),
                                                           self._rates, now)))
        for name, driver in self._drivers.items():
            with contextlib.suppress(Exception):
                out.append(("driver", _driverview.driver_message(name, self._t_ms, driver)))
        return out

    def start(self, structure: dict[str, Any]) -> None:
        live = _isatty(self._stream)
        if live and _rich_missing():
            print("display: the rich package is not installed; printing one line per transition",
                  file=sys.stderr, flush=True)
            live = False
        screen = _Screen(self._focus, self._autofocus, self._stream, live, quit_key=False)
        if self._ros2 or self._drivers:
            screen.poll = self._poll
        self._q.put(("structure", structure))
        if live:
            self._keys = _Keys(self._q.put)
            self._keys.start()
            screen.keys = self._keys.why
            # Lines the component prints (logs, errors) would tear the live tree apart:
            # they are printed above it instead.
            for name in ("stdout", "stderr"):
                current = getattr(sys, name)
                if _isatty(current):
                    writer = _QueueWriter(self._q.put, current)
                    setattr(sys, name, writer)
                    self._writers.append((name, writer))
        self._thread = threading.Thread(target=screen.run, args=(self._q,), name="hfsmc-display",
                                        daemon=True)
        self._thread.start()
        # Should the component die without closing its observers, the screen and the
        # terminal are still put back (and its last words, queued, printed).
        atexit.register(self.close)

    def record(self, rec: dict[str, Any]) -> None:
        self._q.put(("record", rec))

    def sample(self, t_ms: int, values: dict[str, str], overruns: int,
               rate: float | None = None) -> None:
        self._t_ms = t_ms
        self._q.put(("sample", (t_ms, values, overruns, rate)))

    def close(self) -> None:
        atexit.unregister(self.close)
        if self._thread is None:
            return
        for _, writer in self._writers:
            writer.flush()
        self._q.put(("end", None))
        self._thread.join(0.7)
        if self._keys is not None:
            self._keys.stop()
        for name, writer in reversed(self._writers):
            if getattr(sys, name) is writer:
                setattr(sys, name, writer.original)
        if self._writers and not self._thread.is_alive():
            self._drain_text()
        self._writers = []
        self._thread = None

    def _drain_text(self) -> None:
        """Text printed after the display thread ended goes to the real stderr."""
        while True:
            try:
                kind, payload = self._q.get_nowait()
            except queue.Empty:
                return
            if kind == "text":
                print(payload, file=sys.stderr)


def run_viewer(source: Iterable[Item], focus: str | None = None, autofocus: bool = True,
               stream: TextIO | None = None, stop: Callable[[], None] | None = None) -> int:
    """Show ``source``'s items (structure, records, samples, snapshots) until it ends.

    The loop of ``hfsmc view``: the source is read by a daemon thread; this
    thread draws. Returns the exit status: 0 when the source ended (its
    message goes to stderr), 1 on a source error, 130 on Ctrl-C; ``q`` quits.
    ``stop`` is called on the way out (to close a connection, say).
    """
    out = stream if stream is not None else sys.stdout
    q: queue.SimpleQueue[Item] = queue.SimpleQueue()

    def pump() -> None:
        try:
            for item in source:
                q.put(item)
        except Exception as e:  # the source's own errors end the view with a message
            q.put(("error", f"{type(e).__name__}: {e}"))
        q.put(("end", None))

    live = _isatty(out) and not _rich_missing()
    keys = _Keys(q.put) if live else None
    threading.Thread(target=pump, name="hfsmc-view-source", daemon=True).start()
    status, message = 130, None
    try:
        screen = _Screen(focus, autofocus, out, live, quit_key=True)
        if keys is not None:
            keys.start()
            screen.keys = keys.why
        status, message = screen.run(q)
    except KeyboardInterrupt:
        pass
    finally:
        if keys is not None:
            keys.stop()
        if stop is not None:
            stop()
    if message:
        print(f"hfsmc view: {'error: ' if status else ''}{clean(message)}", file=sys.stderr)
    return status
