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
from collections.abc import Iterator
from http.client import HTTPConnection, HTTPException
from typing import Any, ClassVar

import cv2
import numpy as np

try:  # beside the component, or in the hfsmc package
    from .hfsmc_driver import Driver, query
except ImportError:
    from hfsmc_driver import Driver, query  # type: ignore[import-not-found, no-redef]

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
    camera = Camera.connect(name, url, options, sim)
    assert isinstance(camera, Camera)
    return camera


class Camera(Driver):
    """The latest frame of a video stream (BGR numpy arrays): a driver on the base of
    every driver (hfsmc_driver.Driver, docs/drivers.md), with its images (FRAMES), the
    simulator's clock (LOCKSTEP) and a grabber that reconnects (keep_connected).
    Queries return the snapshot taken when the instant began (docs/recording.md)."""

    KIND = "camera"
    DEFAULT_URL = DEFAULT_URL
    SNAPSHOT: ClassVar[dict[str, Any]] = {"count": 0, "age": math.inf}  # before any frame
    OPTIONS: ClassVar[dict[str, Any]] = {"size": ""}
    FRAMES = "count"
    PUBLIC = ("close",)
    LOCKSTEP = True
    RECONNECT_MIN_S = BACKOFF_MIN_S
    RECONNECT_MAX_S = BACKOFF_MAX_S
    url: str  # DEFAULT_URL when none is given (open)

    def __init__(self, name: str, url: str | None, options: dict[str, Any],
                 playback: Any = None, sim: Any = None) -> None:
        self._size: tuple[int, int] | None = None
        if playback is None:  # a fake keeps no options: its frames are the script's
            for key in sorted(options):
                if key == "size" and (m := _SIZE.match(str(options[key]))) and int(m[1]) \
                        and int(m[2]):
                    self._size = (int(m[1]), int(m[2]))
                elif key == "size":
                    _say(name, f"option size: `{options[key]}` is not WxH (320x240): frames "
                               "kept as they come")
                else:
                    _say(name, f"unknown option `{key}` ignored (options: size)")
        super().__init__(name, url, {k: v for k, v in options.items() if k in self.OPTIONS}
                         if playback is None else {}, playback, sim)

    @query(reads="frame")
    def frame(self) -> Any:
        """The latest frame when the instant began (an H x W x 3 BGR numpy array); None
        before the first. The same array until a newer one comes: copy it before drawing
        on it for keeps."""
        return self.image()

    @query(reads="age")
    def age(self) -> float:
        """Seconds since the latest frame arrived (when the instant began); inf before the first."""
        return float(self._snap["age"])

    @query(reads="age")
    def ok(self) -> bool:
        """Frames are coming: the latest is less than a second old."""
        return float(self._snap["age"]) < STALE_S

    @query(reads="count")
    def count(self) -> int:
        """Frames received so far (a new one since the last instant when it has grown)."""
        return int(self._snap["count"])

    def open(self) -> None:
        """Start the grabber (the runtime's ``connect``)."""
        # FFmpeg's own messages (connection refused, ...) at every retry would
        # drown ours; it reads this when first used, so before any capture opens.
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET
        self.url = str(self.url or DEFAULT_URL)
        self._cv2: Any = cv2
        # (frame, its time, its number, its JPEG or None), replaced whole by the grabber
        self._latest: tuple[Any, float, int, Any] | None = None
        self._raw: bool | None = None  # MJPEG read as JPEG packets: None until tried
        self._count = 0
        self._arrived = threading.Condition()  # lockstep: a frame has come
        self._held: tuple[Any, float, int, Any] | None = None  # lockstep: the frame synced
        if self.sim is not None and not self.url.startswith("http://"):
            self.say(f"--clock sim needs the simulator's MJPEG stream (http://...), not {self.url}")
            raise SystemExit(1)
        self.start_thread(self._run if self.sim is None else self._run_stamped, "grabber")
        atexit.register(self.close)

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
        return f"<camera {self.name} {self.url}>" if self.live else super().__repr__()

    def read(self) -> dict[str, Any]:
        """The stream's latest frame for the instant that begins; queries return this."""
        latest = self._latest if self.sim is None else self._held
        if latest is None:
            return {}
        self.hold_image(latest[0], latest[3])
        return {"count": latest[2], "age": self.now() - latest[1]}

    def close(self) -> None:
        """Stop the grabber (also run at exit)."""
        super().close()

    # -- the grabber thread ----------------------------------------------------
    def _run(self) -> None:
        self.keep_connected(self._attempt, self._lost)

    def _attempt(self) -> bool | None:
        """One capture's frames until it ends: whether any came (None: not MJPEG after
        all, opened again at once for decoded frames)."""
        cap = self._open()
        try:
            got = cap is not None and self._grab(cap)
        finally:
            if cap is not None:
                cap.release()
        return None if self._raw is False and not got and not self.stopping() else got

    def _lost(self, got: bool) -> str:
        return (f"stream {'lost' if got or self._count else 'not available'} at {self.url}: "
                "reconnecting")

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
        while not self.stopping():
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
                self.tell_up(f"stream back at {self.url}")
            if step:
                self.wait(step)
        return got

    # -- the grabber of stamped frames (lockstep) -------------------------------
    def _run_stamped(self) -> None:
        """Read the simulator's MJPEG parts and their stamps, reconnecting as _run does."""
        self.keep_connected(self._attempt_stamped, self._lost)

    def _attempt_stamped(self) -> bool:
        got = False
        with contextlib.suppress(OSError, HTTPException, ValueError):
            got = self._read_stamped()
        return got

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
            while not self.stopping():
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
                    self.tell_up(f"stream back at {self.url}")
        finally:
            conn.close()
        return got


def _say(name: str, text: str) -> None:
    """A line before the driver is made (its options)."""
    with contextlib.suppress(ValueError, OSError):  # stderr closed at exit: nothing to tell
        sys.stderr.write(f"{name}: {text}\n")
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
