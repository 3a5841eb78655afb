"""The base of a user's Python driver (``type: driver``; docs/drivers.md).

Copied beside a generated Python component whose model names a driver of its own. A
driver derives from :class:`Driver`, declares its ``KIND``, its ``SNAPSHOT`` (each field
with its "nothing yet" value), its ``OPTIONS`` (each with its default) as literals, and
marks what snippets call: ``@query`` methods read the instant's snapshot
(``self.value(field)``), ``@command`` methods send. hfsmc reads that declaration
without importing the file (hfsmc/drivers.py); the runtime then uses one class for the
live driver and for its fake:

- live: ``connect`` makes it and calls ``open()`` (its socket, its thread:
  ``start_thread``); when an instant begins the runtime calls ``snapshot()``, which
  asks ``read()`` for the latest state (called from the automaton's thread: the driver
  guards what its own thread shares with it) and keeps it until the next instant;
- recorded: the snapshot of every instant goes to the recording (channel
  ``/hfsmc/interface/NAME``, schema ``hfsmc.KIND.Snapshot``), every command too;
- fake (``hfsmc replay``, ``hfsmc test``): made by ``fake`` without ``open()``; its
  snapshot comes from the script, and a command is recorded but its body never runs.

Hooks a driver may use beyond that, which the built-in ``camera`` (hfsmc_camera.py) and
``mavlink`` (hfsmc_mavlink.py) are built on: queries that name the field they read
(``@query(reads=)``), commands that check their own arguments and report their outcome
(``@command(checked=, ack=)``, ``tell``), options read its own way (``read_options``),
runtime methods snippets may call (``PUBLIC``), the live views' feed (``VIEW``), images
beside the snapshot (``FRAMES``, ``hold_image``, ``image``), the simulator's clock
(``LOCKSTEP``, ``now``, ``lockstep_sent``, ``lockstep_sync``) and a reader that
reconnects (``keep_connected``, ``tell_down``, ``tell_up``).
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar, overload

F = TypeVar("F", bound=Callable[..., Any])
_TRUE = {"true", "yes", "on", "1"}
_FALSE = {"false", "no", "off", "0"}


@overload
def query(fn: F) -> F: ...
@overload
def query(fn: None = None, *, names: dict[str, str] | None = None,
          reads: str | None = None) -> Callable[[F], F]: ...
def query(fn: F | None = None, *, names: dict[str, str] | None = None,
          reads: str | None = None) -> Any:
    """Mark a method as a query of the instant's snapshot. ``names={"param": "option"}``:
    that argument must be one of the names the option lists (``check`` finds a literal
    that is not; a computed one fails when called). ``reads="field"``: the one snapshot field
    it reads (``"frame"``: a FRAMES driver's image), so that a replay whose recording lacks
    only other fields answers it (``Driver.lacks``); without it any lacking field counts."""
    def mark(f: F) -> F:
        @functools.wraps(f)
        def method(self: Driver, *args: Any, **kwargs: Any) -> Any:
            self._named(f, names, args, kwargs)
            self._asked(f.__name__, reads)
            return f(self, *args, **kwargs)
        method.hfsmc_kind = "query"  # type: ignore[attr-defined]
        return method  # type: ignore[return-value]
    return mark(fn) if fn is not None else mark


@overload
def command(fn: F) -> F: ...
@overload
def command(fn: None = None, *, names: dict[str, str] | None = None, ack: bool = False,
            checked: bool = False) -> Callable[[F], F]: ...
def command(fn: F | None = None, *, names: dict[str, str] | None = None, ack: bool = False,
            checked: bool = False) -> Any:
    """Mark a method as a command: told to the recording (or the playback) with its
    arguments, then run, live only (a fake sends nothing).

    ``checked=True``: the method checks and converts its arguments itself, tells them
    with ``self.tell(name, args)`` and then sends; it runs in a fake too (where what it
    calls to send does nothing, and what it says of the command, a pending
    acknowledgement, is the same as live). ``ack=True``: the driver reports the
    command's outcome (``last_ack``; hfsmc reads it from the declaration)."""
    def mark(f: F) -> F:
        sig = inspect.signature(f)
        if checked:
            @functools.wraps(f)
            def told(self: Driver, *args: Any, **kwargs: Any) -> Any:
                self._named(f, names, args, kwargs)
                return f(self, *args, **kwargs)
            told.hfsmc_kind = "command"  # type: ignore[attr-defined]
            told.hfsmc_ack = ack  # type: ignore[attr-defined]
            return told  # type: ignore[return-value]

        @functools.wraps(f)
        def method(self: Driver, *args: Any, **kwargs: Any) -> Any:
            self._named(f, names, args, kwargs)
            bound = sig.bind(self, *args, **kwargs)
            bound.apply_defaults()
            if self.on_command is not None:
                self.on_command(f.__name__, list(bound.args[1:]))
            return f(self, *args, **kwargs) if self.live else None
        method.hfsmc_kind = "command"  # type: ignore[attr-defined]
        method.hfsmc_ack = ack  # type: ignore[attr-defined]
        return method  # type: ignore[return-value]
    return mark(fn) if fn is not None else mark


def _option(kind: str, key: str, default: Any, value: Any) -> Any:
    """An option's value as its default's type (the model and NAME.yaml give text)."""
    if isinstance(default, bool):
        text = str(value).strip().lower()
        if text in _TRUE or text in _FALSE:
            return text in _TRUE
        raise ValueError(f"option `{key}` is true or false, not `{value}`")
    if isinstance(default, (int, float)):
        try:
            number = float(value) if isinstance(default, float) else int(str(value), 0)
        except ValueError:
            raise ValueError(f"option `{key}` is a number, not `{value}`") from None
        return number
    if isinstance(default, tuple):
        return tuple(n for n in str(value).replace(",", " ").strip("[]()").split()
                     if n) if isinstance(value, str) else tuple(value)
    return str(value)


def _field(default: Any, value: Any) -> Any:
    """A snapshot field from a script (JSON) as the live driver gives it."""
    if isinstance(default, float) and isinstance(value, (str, int)) and not isinstance(value, bool):
        return float(value)  # "inf", "nan", "-inf" too
    if isinstance(default, tuple) and isinstance(value, list):
        return tuple(_field(default[0] if default else None, v) for v in value)
    return value


class Driver:
    """What every user driver is (docs/drivers.md, "Python")."""

    KIND = ""
    SNAPSHOT: ClassVar[dict[str, Any]] = {}
    OPTIONS: ClassVar[dict[str, Any]] = {}
    ATTRIBUTES_FROM: tuple[str, ...] = ()
    DEFAULT_URL: str | None = None
    # The live views' feed of it: "driver" (its snapshot's fields, docs/drivers.md) or
    # "vehicle" (the mavlink vehicle panel, which reads the vehicle's queries).
    VIEW: ClassVar[str] = "driver"
    # Runtime methods a snippet may call too (``check`` knows them, as queries):
    # "close", "warning_at_stop".
    PUBLIC: ClassVar[tuple[str, ...]] = ()
    # The snapshot field that numbers the driver's images ("": it gives none). A driver
    # with images hands each instant's to ``hold_image``; a snippet gets it from
    # ``image()``, which tells the recording each image once (/hfsmc/frame/NAME); a script
    # names them as files (``frame``, ``crc32``); the live views show the latest one a
    # snippet obtained instead of the fields.
    FRAMES = ""
    # The driver follows ``hfsmc sim``'s clock with --clock sim (``lockstep_sync``).
    LOCKSTEP = False
    RECONNECT_MIN_S = 0.2  # keep_connected: the first pause after the link ends
    RECONNECT_MAX_S = 2.0  # ... doubling up to this one while nothing comes

    def __init__(self, name: str, url: str | None, options: dict[str, Any],
                 playback: Any = None, sim: Any = None) -> None:
        self.name = name
        self.sim = sim  # --clock sim: the simulator's clock (LOCKSTEP drivers only)
        self.url = url if url is not None else self.DEFAULT_URL
        self.options = self.read_options(options)
        self.on_command: Callable[[str, list[Any]], None] | None = None
        self.playback = playback
        self.live = playback is None
        self.lacks: Any = None  # a fake: what the script lacks at this instant
        self.quiet = False
        self._snap: dict[str, Any] = dict(self.SNAPSHOT)
        self._scripted: dict[str, Any] = dict(self.SNAPSHOT)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._down = False  # said that the link is down (tell_down)
        self.on_frame: Callable[[int, Any, Any], None] | None = None
        self._image: Any = None  # the instant's image and its encoding as it came
        self._encoded: Any = None
        self._seen: Any = None  # the latest image a snippet obtained
        self._told = 0  # the number of the last image told to on_frame
        self._scripted_frame: dict[str, Any] = {}  # a fake: the script's `frame`, `crc32`

    # -- made by the runtime ----------------------------------------------------------
    @classmethod
    def connect(cls, name: str, url: str | None, options: dict[str, Any],
                sim: Any = None) -> Driver:
        """The live driver: made, then opened (its socket, its thread)."""
        driver = cls(name, url, options, sim=sim if cls.LOCKSTEP else None)
        driver.open()
        return driver

    @classmethod
    def fake(cls, name: str, url: str | None, options: dict[str, Any], playback: Any) -> Driver:
        """The driver fed from a script: never opened, it sends nothing (even without a
        playback: a test double)."""
        driver = cls(name, url, options, playback)
        driver.live = False
        return driver

    @classmethod
    def snapshot_schema(cls) -> dict[str, Any]:
        """The JSON Schema of the recorded snapshot, from SNAPSHOT's defaults."""
        def kind(v: Any) -> Any:
            if isinstance(v, bool):
                return {"type": "boolean"}
            if isinstance(v, int):
                return {"type": "integer"}
            if isinstance(v, float):
                return {"type": ["number", "string"]}
            if isinstance(v, (tuple, list)):
                return {"type": "array"}
            return {"type": ["string", "null"]} if v is None or isinstance(v, str) else {}
        return {"title": f"What the automaton saw of a {cls.KIND} during one instant",
                "type": "object",
                "properties": {"t": {"type": "integer"},
                               **{k: kind(v) for k, v in cls.SNAPSHOT.items()}}}

    # -- what a driver writes ---------------------------------------------------------
    def open(self) -> None:
        """Live only: connect to the device; start the thread that listens to it."""

    def read(self) -> dict[str, Any]:
        """Live only: the latest state, some or all of SNAPSHOT's fields (called from the
        automaton's thread once per instant: guard what the driver's thread shares)."""
        return {}

    def close(self) -> None:
        """Stop the driver's threads (each is waited for 1 s at most)."""
        self._stop.set()
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(timeout=1.0)

    def warning_at_stop(self) -> str | None:
        """Something the device is left doing when the component stops, or None."""
        return None

    def attribute(self, name: str) -> Any:
        """``iface.NAME`` for a NAME listed by an option of ATTRIBUTES_FROM."""
        raise AttributeError(name)

    def read_options(self, options: dict[str, Any]) -> dict[str, Any]:
        """The driver's options: the declared ones, each as its default's type (an
        undeclared one, or a value that is not of that type, is a ValueError). A driver
        that says and replaces a bad option instead (the built-in mavlink) overrides it."""
        unknown = [k for k in options if k not in self.OPTIONS]
        if unknown:
            raise ValueError(f"no option `{unknown[0]}` (options: "
                             f"{', '.join(self.OPTIONS) or 'none'})")
        return {k: _option(self.KIND, k, d, options.get(k, d)) for k, d in self.OPTIONS.items()}

    # -- helpers for the driver -------------------------------------------------------
    def tell(self, call: str, args: list[Any]) -> None:
        """A ``@command(checked=True)``: tell the recording (or the playback) the command
        with its checked arguments, before sending it."""
        if self.on_command is not None:
            self.on_command(call, args)

    def value(self, field: str) -> Any:
        """A field of the instant's snapshot."""
        return self._snap[field]

    def say(self, text: str) -> None:
        """One line on stderr, `NAME: text` (as the built-in drivers say theirs)."""
        with contextlib.suppress(ValueError, OSError):  # stderr closed at exit: nothing to tell
            sys.stderr.write(f"{self.name}: {text}\n")
            sys.stderr.flush()

    def start_thread(self, fn: Callable[[], None], what: str = "reader") -> None:
        """Run ``fn`` in a daemon thread until ``close`` (``self.stopping()`` tells it)."""
        t = threading.Thread(target=fn, name=f"{self.name}-{what}", daemon=True)
        self._threads.append(t)
        t.start()

    def stopping(self) -> bool:
        return self._stop.is_set()

    def wait(self, seconds: float) -> bool:
        """Sleep in the driver's thread, cut short by ``close``; whether it is stopping."""
        return self._stop.wait(seconds)

    def now(self) -> float:
        """Seconds on the driver's clock: the simulator's with --clock sim, else monotonic."""
        return time.monotonic() if self.sim is None else float(self.sim.now())

    def tell_down(self, text: str) -> None:
        """Say ``text`` once when the link goes down (not again until ``tell_up``)."""
        if not self._down:
            self._down = True
            self.say(text)

    def tell_up(self, text: str) -> None:
        """Say ``text`` once when the link is back after ``tell_down``."""
        if self._down and not self.stopping():
            self._down = False
            self.say(text)

    def keep_connected(self, attempt: Callable[[], bool | None],
                       down: Callable[[bool], str]) -> None:
        """The body of a reader thread that reconnects: ``attempt()`` connects and reads
        until the link ends, and returns whether anything came (None: try again at once).
        Then ``down(got)`` is said once (``tell_down``) and it waits before the next try,
        RECONNECT_MIN_S doubling up to RECONNECT_MAX_S while nothing comes."""
        pause = self.RECONNECT_MIN_S
        while not self.stopping():
            got = attempt()
            if self.stopping():
                return
            if got is None:
                continue
            if got:
                pause = self.RECONNECT_MIN_S
            self.tell_down(down(got))
            self.wait(pause)
            pause = min(pause * 2, self.RECONNECT_MAX_S)

    # -- images beside the snapshot (FRAMES) ------------------------------------------
    def hold_image(self, image: Any, encoded: Any = None) -> None:
        """Live, in ``read()``: the image of the instant that begins, and its bytes as the
        device sent them (kept by ``--record``; None: the recording encodes it as PNG)."""
        self._image, self._encoded = image, encoded

    def image(self) -> Any:
        """The instant's image (None before the first); the first time a snippet obtains
        one it is told to the recording, and it is what the live views show."""
        img = self._image
        if img is not None:
            self._seen = img  # for the monitor's viewers (one assignment: no lock)
            number = int(self._snap[self.FRAMES])
            if number != self._told and self.on_frame is not None:  # each image once
                self._told = number
                self.on_frame(number, img, self._encoded)
        return img

    def _last_seen(self) -> Any:
        """The latest image a snippet obtained; None before any (hfsmc_monitor.py)."""
        return self._seen

    # -- the simulator's clock (LOCKSTEP) ---------------------------------------------
    def lockstep_sent(self) -> int:
        """--clock sim: what the driver sent the simulator in all (datagrams)."""
        return 0

    def lockstep_sync(self, t_us: int, step: dict[str, Any]) -> str | None:
        """--clock sim, before the instant at ``t_us``: wait (bounded) until the driver
        holds what the simulator says it sent (``step``); why not, or None."""
        return None

    def names(self, option: str) -> tuple[str, ...]:
        """The names an option lists."""
        value = self.options.get(option, ())
        return tuple(value) if isinstance(value, (tuple, list)) else tuple(
            n for n in str(value).replace(",", " ").split() if n)

    # -- the runtime's side -----------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        if self.live:
            got = self.read()
            odd = [k for k in got if k not in self.SNAPSHOT]
            if odd:
                raise KeyError(f"{self.KIND} driver: read() gave `{odd[0]}`, which SNAPSHOT "
                               "does not declare")
            self._snap = {**self._snap, **got}
        else:
            self._snap = dict(self._scripted)
            if self.FRAMES:  # the script names its images as files
                file = self._scripted_frame.get("frame")
                self._image = None if file is None or self.playback is None else \
                    self.playback.image(self.name, str(file), self._scripted_frame.get("crc32"),
                                        self._snap[self.FRAMES])
        return self._snap

    def view_fields(self) -> dict[str, Any]:
        """The snapshot of the latest instant, for the live views (their thread reads it:
        the runtime replaces the dict at each instant, never changes it in place)."""
        return self._snap

    def apply(self, values: dict[str, Any]) -> None:
        """A fake: the script's entry over the fields (unknown fields are an error)."""
        for k, v in values.items():
            if self.FRAMES and k in ("frame", "crc32"):
                self._scripted_frame[k] = v
                continue
            if k not in self.SNAPSHOT:
                raise ValueError(f"the {self.KIND} interface has no snapshot field `{k}` "
                                 f"(fields: {', '.join(self.SNAPSHOT)})")
            self._scripted[k] = _field(self.SNAPSHOT[k], v)

    def _asked(self, query: str, field: str | None = None) -> None:
        lacks = self.lacks
        if lacks is None or self.quiet or self.playback is None:
            return
        if isinstance(lacks, str) or field is None:
            self.playback.asked(self.name, query, lacks if isinstance(lacks, str) else "field",
                                None)
        elif field in lacks:  # the recording lacks the very field this query reads
            self.playback.asked(self.name, query, field,
                                self._snap.get(self.FRAMES) if field == "frame" else None)

    def _named(self, fn: Callable[..., Any], names: dict[str, str] | None,
               args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        if not names:
            return
        bound = inspect.signature(fn).bind(self, *args, **kwargs).arguments
        for param, option in names.items():
            given = bound.get(param)
            if given is not None and given not in self.names(option):
                raise ValueError(f"{self.name}.{fn.__name__}: `{given}` is not one of "
                                 f"{option}: {', '.join(self.names(option)) or 'none'}")

    def __getattr__(self, attr: str) -> Any:
        """Only for a name the class does not have: say which interface lacks it."""
        options = self.__dict__.get("options") or {}
        for option in type(self).ATTRIBUTES_FROM:
            if attr in self.names(option) and options:
                return self.attribute(attr)
        name = self.__dict__.get("name", "?")
        raise AttributeError(f"the {type(self).KIND} interface `{name}` has no method or "
                             f"attribute `{attr}` (docs/drivers.md)", name=attr, obj=self)

    def __repr__(self) -> str:
        return f"<{self.KIND} {self.name}{'' if self.live else ' (playback)'}>"

