"""MJPEG over HTTP on loopback: the simulated camera's stream, as IP cameras serve it.

``GET /bottom.mjpg`` answers ``multipart/x-mixed-replace`` and then one part per
published frame, each with its ``Content-Type: image/jpeg`` and
``Content-Length`` headers, which is what FFmpeg's ``mpjpeg`` demuxer (OpenCV's
``VideoCapture`` on an ``http://`` URL) reads. ``GET /snapshot.jpg`` answers the
latest frame alone. Every client has its own thread; one that stops reading or
goes away holds up no one else.

A frame published with headers carries them in its part (the simulator in lockstep
sends ``X-Frame: K`` and ``X-Time-Us: T``, the frame's number and the simulated
time it was rendered for: schemas/lockstep.md); MJPEG readers skip headers they
do not know.

A paused server looks like a camera that has dropped: streams are cut (the
reader sees the end of its stream) and new requests get ``503`` until it
resumes.

It answers only its own machine's programs (docs/worlds.md, "The camera"): a request
whose ``Host`` is not a loopback name (a page under a name a DNS server pointed at
127.0.0.1) gets ``403``, a browser page of another origin may not embed the frames
(``Cross-Origin-Resource-Policy``), and beyond MAX_CLIENTS connections at once a new
one is answered ``503`` and closed without a thread of its own.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from hfsmc.hosts import host_name, is_loopback, is_unspecified, normal_name

log = logging.getLogger("hfsmc.sim.mjpeg")

STREAM_PATH = "/bottom.mjpg"
SNAPSHOT_PATH = "/snapshot.jpg"
BOUNDARY = "hfsmcframe"
CLIENT_TIMEOUT = 5.0  # seconds a client may take to send its request or to take a frame
MAX_CLIENTS = 16  # connections served at once; more are answered 503 and closed
BUSY = (b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: text/plain\r\nConnection: close\r\n"
        b"\r\ntoo many camera clients at once\n")
HEADERS = {"Cache-Control": "no-store", "X-Content-Type-Options": "nosniff",
           "Cross-Origin-Resource-Policy": "same-origin"}


class _Frames:
    """The latest frame and the clients waiting for the next one."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.jpeg: bytes | None = None
        self.head = b""  # the extra header lines of the latest frame's part
        self.seq = 0
        self.paused = False
        self.closed = False
        self.sockets: set[socket.socket] = set()

    def publish(self, jpeg: bytes, head: bytes = b"") -> None:
        with self.cond:
            self.jpeg = jpeg
            self.head = head
            self.seq += 1
            self.cond.notify_all()

    def next_after(self, seq: int, timeout: float) -> tuple[int, bytes, bytes] | None:
        """The first frame newer than ``seq`` with its part's extra header lines; None when
        the stream is to end. (seq, b"", b"") when none came within ``timeout``."""
        with self.cond:
            self.cond.wait_for(lambda: self.seq != seq or self.paused or self.closed, timeout)
            if self.paused or self.closed:
                return None
            if self.seq == seq or self.jpeg is None:
                return (seq, b"", b"")
            return (self.seq, self.jpeg, self.head)

    def cut(self) -> None:
        """End every connection now, even one stuck writing to a client that does not read."""
        with self.cond:
            self.cond.notify_all()
            sockets = list(self.sockets)
        for s in sockets:
            with contextlib.suppress(OSError):  # already gone
                s.shutdown(socket.SHUT_RDWR)


class _HttpServer(ThreadingHTTPServer):
    daemon_threads = True
    frames: _Frames
    names: frozenset[str] = frozenset()  # besides loopback names, the Host names answered
    active = 0  # connections being served (their threads)
    count_lock = threading.Lock()

    def process_request(self, request: Any, client_address: Any) -> None:
        with self.count_lock:
            busy = self.active >= MAX_CLIENTS
            if not busy:
                self.active += 1
        if busy:  # answered here, on the server's thread: a short write to an empty socket
            with contextlib.suppress(OSError):
                request.settimeout(0.5)
                request.sendall(BUSY)
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            with self.count_lock:
                self.active -= 1

    def handle_error(self, request: Any, client_address: Any) -> None:
        # A client that hangs up mid-frame is ordinary; anything else is worth a line.
        log.debug("camera client %s: connection ended with an error", client_address,
                  exc_info=True)


class _Handler(BaseHTTPRequestHandler):
    server: _HttpServer
    protocol_version = "HTTP/1.0"  # one request per connection; the stream ends with it
    timeout = CLIENT_TIMEOUT
    server_version = "hfsmc-sim-camera"

    def setup(self) -> None:
        super().setup()
        frames = self.server.frames
        with frames.cond:
            frames.sockets.add(self.connection)

    def finish(self) -> None:
        frames = self.server.frames
        with frames.cond:
            frames.sockets.discard(self.connection)
        with contextlib.suppress(OSError):
            super().finish()

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("camera %s: " + format, self.address_string(), *args)

    def end_headers(self) -> None:
        for key, value in HEADERS.items():
            self.send_header(key, value)
        super().end_headers()

    def do_GET(self) -> None:
        given = self.headers.get("Host")
        name = host_name(given)
        if given is not None and (name is None or not (is_loopback(name) or name in self.server.names)):
            self.send_error(403, "not a name this camera answers to")
            return
        path = self.path.split("?", 1)[0]
        if path not in (STREAM_PATH, SNAPSHOT_PATH):
            self.send_error(404, "no such stream: try " + STREAM_PATH)
            return
        frames = self.server.frames
        if frames.paused or frames.closed:
            self.send_error(503, "camera not available")
            return
        if path == SNAPSHOT_PATH:
            self._snapshot()
        else:
            self._stream()

    def _snapshot(self) -> None:
        jpeg = self.server.frames.jpeg
        if jpeg is None:
            self.send_error(503, "no frame yet")
            return
        self.send_response(200)
        self.send_header("Content-Type", "image/jpeg")
        self.send_header("Content-Length", str(len(jpeg)))
        self.end_headers()
        self.wfile.write(jpeg)

    def _stream(self) -> None:
        self.send_response(200)
        self.send_header("Content-Type", f"multipart/x-mixed-replace; boundary={BOUNDARY}")
        self.send_header("Connection", "close")
        self.end_headers()
        frames = self.server.frames
        seq = 0  # the latest frame goes out at once
        try:
            while True:
                got = frames.next_after(seq, CLIENT_TIMEOUT)
                if got is None:
                    return
                seq, jpeg, extra = got
                if jpeg:
                    head = (f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\n"
                            f"Content-Length: {len(jpeg)}\r\n").encode("ascii")
                    self.wfile.write(head + extra + b"\r\n" + jpeg + b"\r\n")
        except OSError:
            return  # the client went away, or the stream was cut


class MjpegServer:
    """Serves published JPEG frames over HTTP on ``host``; port 0 picks a free port."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self._frames = _Frames()
        self._httpd = _HttpServer((host, port), _Handler, bind_and_activate=False)
        self._httpd.frames = self._frames
        self._httpd.count_lock = threading.Lock()
        named = normal_name(host)
        self._httpd.names = frozenset([named] if named and not is_unspecified(named) else [])
        self._thread: threading.Thread | None = None
        self.host = host

    def start(self) -> None:
        """Bind and serve in a thread of its own."""
        try:
            self._httpd.server_bind()
            self._httpd.server_activate()
        except OSError:
            self._httpd.server_close()
            raise
        self._thread = threading.Thread(target=self._httpd.serve_forever, args=(0.1,),
                                        name="hfsmc-mjpeg", daemon=True)
        self._thread.start()

    @property
    def port(self) -> int:
        port: int = self._httpd.server_address[1]
        return port

    def url(self, path: str = STREAM_PATH) -> str:
        return f"http://{self.host}:{self.port}{path}"

    def publish(self, jpeg: bytes, headers: dict[str, str] | None = None) -> None:
        """The newest frame: streams send it next (with ``headers`` in its part), snapshots
        return it."""
        head = "".join(f"{k}: {v}\r\n" for k, v in (headers or {}).items()).encode("ascii")
        self._frames.publish(jpeg, head)

    @property
    def paused(self) -> bool:
        return self._frames.paused

    def pause(self, on: bool) -> None:
        """Drop the camera (cut the streams, answer 503) or bring it back."""
        with self._frames.cond:
            self._frames.paused = on
        if on:
            self._frames.cut()

    def stop(self) -> None:
        """Cut every client and stop serving; returns within about 0.2 s."""
        with self._frames.cond:
            self._frames.closed = True
        self._frames.cut()
        if self._thread is not None:
            self._httpd.shutdown()
            self._thread.join(1.0)
            self._thread = None
        self._httpd.server_close()
