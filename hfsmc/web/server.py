"""``hfsmc view --web``: serve a page that draws a running component live.

One aiohttp server, on loopback unless a host is named: ``/`` is the page,
``/app.css`` and its scripts (SCRIPTS: ``/app.js`` and the parts it uses) its
own code (package data: nothing is fetched from elsewhere), ``/sub?state=PATH``
a composite state's sub-automaton drawn alone, ``/ws`` the WebSocket each page reads its messages from
(docs/web.md). What a page sends is thrown away, but for a replay's controls. The monitor
client and what the pages are told live in hfsmc/web/bridge.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import socket
import sys
from collections.abc import Callable, Coroutine
from importlib import resources
from typing import Any, TextIO

from aiohttp import WSMsgType, web

from hfsmc.errors import UsageError
from hfsmc.web.bridge import Bridge, Page, Picture
from hfsmc.web.trust import Trust, guard, headers, loopback_only

MAX_PAGES = 64  # pages served at once; more WebSockets are closed at once
WS_MESSAGE_LIMIT = 1 << 16  # a page sends nothing legitimate: a bigger frame closes its socket
# The page's scripts, in index.html's order: page.js first (the parts' shared data), app.js
# last (the connection and the messages, handed to the others).
SCRIPTS = ("ros2.js", "page.js", "diagram.js", "states.js", "lists.js", "status.js", "feeds.js",
           "replay.js", "app.js")
STATIC = {"": ("index.html", "text/html"), "app.css": ("app.css", "text/css"),
          **{name: (name, "text/javascript") for name in SCRIPTS}}
# Only the page's own files and its WebSocket; the SVG is inline.
CSP = ("default-src 'none'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
       "img-src 'self' data:; connect-src 'self'; base-uri 'none'; form-action 'none'; "
       "frame-ancestors 'none'")
_BRIDGE = web.AppKey("bridge", Bridge)
_FILES = web.AppKey("files", dict)


def static_files() -> dict[str, tuple[bytes, str]]:
    """The page's files, read from the package (they ship in the wheel)."""
    folder = resources.files("hfsmc.web") / "static"
    return {route: ((folder / name).read_bytes(), kind) for route, (name, kind) in STATIC.items()}


def make_app(bridge: Bridge, trust: Trust, log: TextIO | None = None) -> web.Application:
    """The web application that serves ``bridge``'s view to those ``trust`` lets in
    (refusals said once each on ``log``, stderr by default)."""
    app = web.Application(middlewares=[guard(trust, log)])
    app.on_response_prepare.append(headers)
    app[_BRIDGE] = bridge
    app[_FILES] = static_files()
    for route in STATIC:  # the fixed list: nothing else of the package is served
        app.router.add_get("/" + route, _file)
    app.router.add_get("/ws", _socket)
    app.router.add_get("/sub", _sub)
    app.router.add_get("/favicon.ico", _no_icon)
    return app


async def _file(request: web.Request) -> web.Response:
    body, kind = request.app[_FILES][request.path.lstrip("/")]
    return web.Response(body=body, content_type=kind, charset="utf-8",
                        headers={"Cache-Control": "no-cache", "Content-Security-Policy": CSP,
                                 "X-Content-Type-Options": "nosniff"})


async def _sub(request: web.Request) -> web.Response:
    """``/sub?state=PATH``: the sub-automaton of the composite state PATH alone, as SVG."""
    svg = await request.app[_BRIDGE].sub_svg(request.query.get("state", ""))
    headers = {"Cache-Control": "no-cache", "X-Content-Type-Options": "nosniff"}
    if svg is None:
        return web.Response(status=404, text="no such sub-automaton", headers=headers)
    return web.Response(text=svg, content_type="image/svg+xml", headers=headers)


async def _no_icon(request: web.Request) -> web.Response:
    return web.Response(status=204)


async def _socket(request: web.Request) -> web.WebSocketResponse:
    bridge = request.app[_BRIDGE]
    ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=WS_MESSAGE_LIMIT)
    await ws.prepare(request)
    if len(bridge.pages) >= MAX_PAGES:
        await ws.close(code=1013, message=b"too many pages")
        return ws
    page = bridge.attach()
    sender = asyncio.create_task(_send(ws, page))
    try:
        async for msg in ws:  # only a replay takes commands; anything else is thrown away
            if msg.type == WSMsgType.ERROR:
                break
            if msg.type == WSMsgType.TEXT:
                bridge.command(msg.data)
    finally:
        bridge.detach(page)
        page.end()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(sender, 2.0)
        if not sender.done():
            sender.cancel()
    return ws


async def _send(ws: web.WebSocketResponse, page: Page) -> None:
    """Send a page its queue until the queue ends; a page that fell behind is closed."""
    try:
        while (text := await page.queue.get()) is not None:
            await ws.send_str(text)
    except (ConnectionError, RuntimeError):  # the page went away meanwhile
        pass
    with contextlib.suppress(Exception):
        await ws.close(code=1008 if page.dropped else 1000,
                       message=b"too slow: reload" if page.dropped else b"")


def listen(host: str, port: int) -> socket.socket:
    """The web view's listening socket (OSError when the address is taken)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.create_server((host, port), family=family, backlog=128)
    sock.setblocking(False)
    return sock


def url_of(sock: socket.socket, token: str) -> str:
    """The URL to open: on loopback when the server listens on every address."""
    host, port = sock.getsockname()[:2]
    host = {"0.0.0.0": "127.0.0.1", "::": "::1"}.get(host, host)
    where = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
    return f"http://{where}/?token={token}"


def stop_on_signals(stop: asyncio.Event) -> None:
    """SIGINT and SIGTERM set ``stop`` (where the loop can take signal handlers)."""
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)


def release_signals() -> None:
    """Undo stop_on_signals."""
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.remove_signal_handler(sig)


async def serve(sock: socket.socket, bridge: Bridge, trust: Trust, out: TextIO | None = None,
                stop: asyncio.Event | None = None, log: TextIO | None = None) -> None:
    """Serve the page on ``sock`` to those ``trust`` lets in, and run ``bridge``, until
    ``stop`` is set (or SIGINT/SIGTERM). The URL goes to ``out`` (stdout), a warning for a
    server other machines can reach and the refusals to ``log`` (stderr)."""
    out = out if out is not None else sys.stdout
    log = log if log is not None else sys.stderr
    stop = stop if stop is not None else asyncio.Event()
    stop_on_signals(stop)
    runner = web.AppRunner(make_app(bridge, trust, log), access_log=None, handle_signals=False)
    await runner.setup()
    watching = asyncio.create_task(bridge.run())
    try:
        await web.SockSite(runner, sock, shutdown_timeout=1.0).start()
        if not loopback_only(sock):
            print(network_warning(sock, trust), file=log, flush=True)
        print(f"hfsmc view: web view on {url_of(sock, trust.token)} ({bridge.watching})",
              file=out, flush=True)
        await stop.wait()
    finally:
        watching.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await watching
        for page in list(bridge.pages):
            page.end()
        await runner.cleanup()
        release_signals()


def network_warning(sock: socket.socket, trust: Trust) -> str:
    """What a server that other machines can reach says on stderr."""
    host, port = sock.getsockname()[:2]
    where = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
    names = ", ".join(sorted(trust.names)) or "none"
    return (f"hfsmc view: warning: the web view on {where} can be reached from other machines: "
            "whoever has its URL with the token sees the component's states, variables, log "
            "and camera, unencrypted; it answers to loopback names and to these others "
            f"(--allow-host): {names}")


def painter(drawn: Picture | None, model_structure: dict[str, Any] | None,
            ) -> Callable[[dict[str, Any]], Coroutine[Any, Any, Picture]]:
    """The bridge's ``paint``: the model's picture while the component is that model's,
    else a drawing from the component's own structure."""
    from hfsmc.web.picture import model_from_structure, svg_of

    def shape(structure: dict[str, Any] | None) -> tuple[Any, ...]:
        # What the drawing shows: parameter values (--param) do not change it.
        s = structure or {}
        return tuple(s.get(k) for k in ("name", "automata", "states", "transitions"))

    async def paint(structure: dict[str, Any]) -> Picture:
        if drawn is not None and shape(structure) == shape(model_structure):
            return drawn
        problem = None
        if drawn is not None:
            problem = ("the component is not the model given with --model (its states or "
                       "transitions differ): drawn from the component's own structure")
        try:
            model = model_from_structure(structure)
            svg = await asyncio.to_thread(lambda: svg_of(model))
        except (UsageError, ValueError, KeyError, TypeError) as e:
            return Picture(None, "", f"no picture: {e}")
        return Picture(svg, "structure", problem, model)

    return paint
