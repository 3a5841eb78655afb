"""The ``camera`` interface of Python components (docs/interfaces.md): the latest frame
of an OpenCV capture, without blocking the automaton.

Copied beside a generated component that declares an interface of type
``camera``; the runtime imports it and calls ``connect(name, url, options)``.
OpenCV is imported with the module: without it the import fails and the
runtime turns the interface into one that says "cannot be loaded" when used.

The URL is anything ``cv2.VideoCapture`` opens: MJPEG over HTTP
(``http://127.0.0.1:8554/bottom.mjpg``), a device number (``0``), a file
(replayed at its frame rate, from the start again at its end). A daemon
grabber reads frames as they come and keeps only the latest, as one
immutable tuple (frame, time, number, JPEG) replaced whole, so ``frame()`` and ``age()``
return at once. When the stream drops, the grabber says so once on stderr
and reconnects with a growing pause (0.2 s, doubling up to 2 s); it says so
again when frames are back. An MJPEG stream is read as the JPEG of each frame
and decoded here (``cv2.imdecode``): a recording keeps that JPEG as it came, so
a replay computes on the same pixels (docs/recording.md).

With ``--clock sim`` (lockstep with ``hfsmc sim``) the grabber reads the MJPEG stream
itself (HTTP, no FFmpeg buffering), with each part's ``X-Frame`` and ``X-Time-Us``
headers: before each instant the automaton's thread waits until it holds the frame the
simulator names; ``count()`` is that frame's number and ``age()`` its simulated age.

Options: ``size: WxH`` resizes every frame (``320x240``).
"""

from __future__ import annotations

import atexit
import contextlib
import math
import os
import re
import sys
import threading
import time
import urllib.parse
from collections.abc import Callable, Iterator
from http.client import HTTPConnection, HTTPException
from typing import Any

import cv2
import numpy as np

DEFAULT_URL = "0"  # the first video device
BACKOFF_MIN_S = 0.2
BACKOFF_MAX_S = 2.0
STALE_S = 1.0  # ok() is false when the latest frame is older than that
OPEN_TIMEOUT_MS = 3000  # a network stream that does not answer: give up and retry
READ_TIMEOUT_MS = 2000  # a network stream that stops sending: drop it and reconnect
FRAME_WAIT_S = 10.0  # lockstep: the frame the simulator names is that late at most
_SIZE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_quiet_lock = threading.Lock()  # OpenCV's log level is global: grabbers share the lowering
_quiet_depth = 0
_quiet_saved = 0


def connect(name: str, url: str | None, options: dict[str, str], sim: Any = None) -> Camera:
    """Start grabbing frames from ``url``; returns at once. ``sim``: the simulator's clock
    (hfsmc_simclock.SimClock), which the camera then follows."""
    return Camera(name, url or DEFAULT_URL, options, sim)


NO_FRAME: dict[str, Any] = {"count": 0, "age": math.inf}  # the snapshot before any frame


class CameraQueries:
    """What snippets call. Queries return the snapshot taken when the instant began
    (docs/recording.md); the first time a snippet obtains a frame it is told to
    ``on_frame`` (a recording)."""

    name: str
    _snap: dict[str, Any]
    _frame: Any
    _seen: Any
    _jpeg: Any  # the frame's JPEG as the camera sent it, or None
    _told: int = 0  # the number of the last frame told to on_frame
    on_frame: Callable[[int, Any, Any], None] | None

    def __getattr__(self, attr: str) -> Any:
        """Only for a name the class does not have: say which interface lacks it, not
        which Python class."""
        name = self.__dict__.get("name", "?")
        raise AttributeError(f"the camera interface `{name}` has no method or attribute "
                             f"`{attr}` (docs/interfaces.md)", name=attr, obj=self)

    def frame(self) -> Any:
        """The latest frame when the instant began (an H x W x 3 BGR numpy array); None
        before the first. The same array until a newer one comes: copy it before drawing
        on it for keeps."""
        img = self._frame
        if img is not None:
            self._seen = img  # for the monitor's viewers (one assignment: no lock)
            count = int(self._snap["count"])
            if count != self._told and self.on_frame is not None:  # each frame once
                self._told = count
                self.on_frame(count, img, self._jpeg)
        return img

    def _last_seen(self) -> Any:
        """The latest frame a snippet obtained with ``frame()``; None before any. For the
        monitor (hfsmc_monitor.py), which sends it to the viewers that ask for frames."""
        return self._seen

    def age(self) -> float:
        """Seconds since the latest frame arrived (when the instant began); inf before the first."""
        return float(self._snap["age"])

    def ok(self) -> bool:
        """Frames are coming: the latest is less than a second old."""
        return self.age() < STALE_S

    def count(self) -> int:
        """Frames received so far (a new one since the last instant when it has grown)."""
        return int(self._snap["count"])


class Camera(CameraQueries):
    """The latest frame of a video stream (BGR numpy arrays)."""

    def __init__(self, name: str, url: str, options: dict[str, str], sim: Any = None) -> None:
        # FFmpeg's own messages (connection refused, ...) at every retry would
        # drown ours; it reads this when first used, so before any capture opens.
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET
        self.name = name
        self.url = url
        self._cv2: Any = cv2
        self._size: tuple[int, int] | None = None
        for key in sorted(options):
            if key == "size" and (m := _SIZE.match(str(options[key]))) and int(m[1]) and int(m[2]):
                self._size = (int(m[1]), int(m[2]))
            elif key == "size":
                self._say(f"option size: `{options[key]}` is not WxH (320x240): frames kept as they come")
            else:
                self._say(f"unknown option `{key}` ignored (options: size)")
        # (frame, monotonic time, its number, its JPEG or None), replaced whole by the grabber
        self._latest: tuple[Any, float, int, Any] | None = None
        self._raw: bool | None = None  # MJPEG read as JPEG packets: None until tried
        self._jpeg: Any = None  # the snapshot's frame as JPEG, when it came so
        self._count = 0
        self._snap: dict[str, Any] = NO_FRAME
        self._frame: Any = None  # the snapshot's frame
        self._seen: Any = None  # the latest frame a snippet obtained
        self.on_frame: Callable[[int, Any, Any], None] | None = None
        self._down = False  # said on stderr that the stream is down
        self._stop = threading.Event()
        self._sim = sim
        self._arrived = threading.Condition()  # lockstep: a frame has come
        self._held: tuple[Any, float, int, Any] | None = None  # lockstep: the frame synced
        if sim is not None and not url.startswith("http://"):
            self._say(f"--clock sim needs the simulator's MJPEG stream (http://...), not {url}")
            raise SystemExit(1)
        run = self._run if sim is None else self._run_stamped
        self._thread = threading.Thread(target=run, name=f"camera {name}", daemon=True)
        self._thread.start()
        atexit.register(self.close)

    def lockstep_sent(self) -> int:
        return 0

    def lockstep_sync(self, t_us: int, step: dict[str, Any]) -> str | None:
        """Lockstep, before the instant at ``t_us``: wait until the frame numbered
        ``step["frame"]`` has come (0: the camera is down, nothing to wait for)."""
        want = int(step["frame"])
        if want <= 0:
            return None
        with self._arrived:
            ok = self._arrived.wait_for(
                lambda: self._latest is not None and self._latest[2] >= want, FRAME_WAIT_S)
            if not ok:
                return (f"{self.name}: the simulator's frame {want} did not come in "
                        f"{FRAME_WAIT_S:g} s from {self.url}")
            self._held = self._latest
        return None

    def __repr__(self) -> str:
        return f"<camera {self.name} {self.url}>"

    def snapshot(self) -> dict[str, Any]:
        """Read the stream once for the instant that begins; queries return this."""
        latest = self._latest if self._sim is None else self._held
        if latest is None:
            return self._snap
        self._frame, self._jpeg = latest[0], latest[3]
        now = time.monotonic() if self._sim is None else self._sim.now()
        self._snap = {"count": latest[2], "age": now - latest[1]}
        return self._snap

    def close(self) -> None:
        """Stop the grabber (also run at exit)."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)

    # -- the grabber thread ----------------------------------------------------
    def _run(self) -> None:
        pause = BACKOFF_MIN_S
        while not self._stop.is_set():
            cap = self._open()
            try:
                got = cap is not None and self._grab(cap)
            finally:
                if cap is not None:
                    cap.release()
            if self._stop.is_set():
                return
            if self._raw is False and not got:  # not MJPEG after all: decoded frames, at once
                continue
            pause = self._reconnect_after(got, pause)

    def _reconnect_after(self, got: bool, pause: float) -> float:
        """The stream ended (``got``: after frames came): say so once, wait before trying
        again, doubling the wait while nothing comes; the next wait."""
        if got:
            pause = BACKOFF_MIN_S
        if not self._down:
            self._down = True
            self._say(f"stream {'lost' if got or self._count else 'not available'} "
                      f"at {self.url}: reconnecting")
        self._stop.wait(pause)
        return min(pause * 2, BACKOFF_MAX_S)

    def _open(self) -> Any:
        cv2 = self._cv2
        with _quiet(cv2):  # a failed open warns each retry; the drop is said once by us
            try:
                if self.url.isdigit():
                    cap = cv2.VideoCapture(int(self.url))
                elif os.path.exists(self.url):
                    cap = cv2.VideoCapture(self.url)
                else:  # a network stream: bounded waits, so a dead server is noticed
                    cap = cv2.VideoCapture(self.url, cv2.CAP_FFMPEG,
                                           [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, OPEN_TIMEOUT_MS,
                                            cv2.CAP_PROP_READ_TIMEOUT_MSEC, READ_TIMEOUT_MS])
                    # MJPEG: take each frame's JPEG as it came (recorded as is, decoded here).
                    if self._raw is not False and cap.isOpened():
                        self._raw = bool(cap.set(cv2.CAP_PROP_FORMAT, -1))
            except cv2.error:
                return None
        if not cap.isOpened():
            cap.release()
            return None
        return cap

    def _grab(self, cap: Any) -> bool:
        """Read frames until the stream ends; whether any came."""
        cv2 = self._cv2
        fps = cap.get(cv2.CAP_PROP_FPS) if os.path.exists(self.url) else 0.0
        step = 1.0 / fps if 0 < fps < 1000 else 0.0  # a file plays at its rate
        got = False
        raw = bool(self._raw)  # tried on network streams only (_open)
        while not self._stop.is_set():
            try:
                ok, img = cap.read()
            except cv2.error:
                ok, img = False, None
            if not ok or img is None:
                return got
            jpeg = None
            if raw:
                if img.ndim != 2 or img.shape[0] != 1 or bytes(img[0, :2]) != b"\xff\xd8":
                    self._raw = False  # another codec: open it again, decoded by OpenCV
                    return got
                jpeg = img
                img = cv2.imdecode(jpeg, cv2.IMREAD_COLOR)
                if img is None:  # a damaged frame: the next one will do
                    continue
            if self._size is not None and (img.shape[1], img.shape[0]) != self._size:
                img = cv2.resize(img, self._size, interpolation=cv2.INTER_AREA)
                jpeg = None  # the automaton sees other pixels than the JPEG's
            self._count += 1
            self._latest = (img, time.monotonic(), self._count, jpeg)
            if not got:
                got = True
                if self._down and not self._stop.is_set():
                    self._down = False
                    self._say(f"stream back at {self.url}")
            if step:
                self._stop.wait(step)
        return got

    # -- the grabber of stamped frames (lockstep) -------------------------------
    def _run_stamped(self) -> None:
        """Read the simulator's MJPEG parts and their stamps, reconnecting as _run does."""
        pause = BACKOFF_MIN_S
        while not self._stop.is_set():
            got = False
            with contextlib.suppress(OSError, HTTPException, ValueError):
                got = self._read_stamped()
            if self._stop.is_set():
                return
            pause = self._reconnect_after(got, pause)

    def _read_stamped(self) -> bool:
        """One connection's frames until it ends; whether any came."""
        u = urllib.parse.urlsplit(self.url)
        conn = HTTPConnection(u.hostname or "127.0.0.1", u.port or 80,
                              timeout=READ_TIMEOUT_MS / 1000)
        got = False
        try:
            conn.request("GET", u.path or "/")
            resp = conn.getresponse()
            if resp.status != 200:
                return False
            while not self._stop.is_set():
                headers: dict[str, str] = {}
                line = resp.readline()
                while line.strip() == b"" or line.startswith(b"--"):
                    if not line:
                        return got
                    line = resp.readline()
                while line.strip():
                    key, _, value = line.decode("latin-1").partition(":")
                    headers[key.strip().lower()] = value.strip()
                    line = resp.readline()
                    if not line:
                        return got
                length = int(headers.get("content-length", "-1"))
                if length < 0:
                    return got  # not the simulator's stream
                data = resp.read(length)
                number, t_us = int(headers.get("x-frame", 0)), int(headers.get("x-time-us", 0))
                jpeg: Any = np.frombuffer(data, dtype=np.uint8)
                img = self._cv2.imdecode(jpeg, self._cv2.IMREAD_COLOR) if number > 0 else None
                if img is None:
                    continue  # a damaged frame, or one without its stamp: the next will do
                if self._size is not None and (img.shape[1], img.shape[0]) != self._size:
                    img = self._cv2.resize(img, self._size, interpolation=self._cv2.INTER_AREA)
                    jpeg = None  # the automaton sees other pixels than the JPEG's
                self._count = number
                with self._arrived:
                    self._latest = (img, t_us / 1e6, number, jpeg)
                    self._arrived.notify_all()
                if not got:
                    got = True
                    if self._down and not self._stop.is_set():
                        self._down = False
                        self._say(f"stream back at {self.url}")
        finally:
            conn.close()
        return got

    def _say(self, text: str) -> None:
        with contextlib.suppress(ValueError, OSError):  # stderr closed at exit: nothing to tell
            sys.stderr.write(f"{self.name}: {text}\n")
            sys.stderr.flush()


@contextlib.contextmanager
def _quiet(cv2: Any) -> Iterator[None]:
    """OpenCV's warnings off while a capture opens (unless OPENCV_LOG_LEVEL is set)."""
    global _quiet_depth, _quiet_saved
    if "OPENCV_LOG_LEVEL" in os.environ:
        yield
        return
    with _quiet_lock:
        if _quiet_depth == 0:
            _quiet_saved = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
        _quiet_depth += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_depth -= 1
            if _quiet_depth == 0:
                cv2.utils.logging.setLogLevel(_quiet_saved)
