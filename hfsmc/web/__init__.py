"""The web view of a running component (``hfsmc view --web``): docs/web.md.

``server.py`` serves the page and its WebSocket, ``bridge.py`` is the monitor
client that keeps what the pages show, ``picture.py`` draws the diagram,
``trust.py`` decides whom the server answers (a token per run, Host and Origin), and
``static/`` holds the page's own HTML, JavaScript and CSS.
"""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Iterable
from typing import Any, TextIO

from hfsmc.emit.structure import structure_of
from hfsmc.ir import Model


def watch(sock: socket.socket, host: str, port: int, model: Model | None, *,
          autofocus: bool = True, out: TextIO | None = None, named: str | None = None,
          allow: Iterable[str] = (), world: Any = None) -> int:
    """Serve the web view on ``sock`` of the component at ``host:port`` until SIGINT/SIGTERM.

    The pages are served under loopback names, ``named`` (the host of ``--web``) and the
    names ``allow`` (``--allow-host``), to whoever has the URL printed on ``out``.

    ``model`` (``--model``) gives the picture while the component is that
    model's; without it the picture is drawn from the component's structure. ``world``
    (a ``hfsmc.web.ros2.WorldMap``) is drawn under a ros2 interface's map.
    Raises UsageError when ``dot`` cannot draw the model. Returns the exit status.
    """
    from hfsmc.web.bridge import Bridge, Picture
    from hfsmc.web.picture import svg_of
    from hfsmc.web.server import painter, serve
    from hfsmc.web.trust import Trust

    drawn = Picture(svg_of(model), "model", source=model) if model is not None else None
    paint = painter(drawn, structure_of(model) if model is not None else None)
    bridge = Bridge(host, port, paint, autofocus=autofocus, world=world)
    asyncio.run(serve(sock, bridge, Trust.new(sock, named, allow), out))
    return 0


def replay(sock: socket.socket, path: str, records: list[dict[str, Any]], model: Model | None, *,
           speed: float = 1.0, autofocus: bool = True, out: TextIO | None = None,
           named: str | None = None, allow: Iterable[str] = ()) -> int:
    """Serve the web view on ``sock`` of the trace ``path`` (its ``records``) until SIGINT/SIGTERM,
    to those ``watch`` serves.

    The tree and picture come from ``model`` when given, else from the paths in
    the trace. Raises UsageError when ``dot`` cannot draw the model.
    """
    from hfsmc.templates.python import hfsmc_viewstate  # type: ignore[import-not-found]
    from hfsmc.web.bridge import Picture
    from hfsmc.web.picture import svg_of
    from hfsmc.web.replay import Replay
    from hfsmc.web.server import painter, serve
    from hfsmc.web.trust import Trust

    structure = structure_of(model) if model is not None else hfsmc_viewstate.infer_structure(records)
    drawn = Picture(svg_of(model), "model", source=model) if model is not None else None
    bridge = Replay(records, structure, path, painter(drawn, structure if model else None),
                    speed=speed, autofocus=autofocus)
    asyncio.run(serve(sock, bridge, Trust.new(sock, named, allow), out))
    return 0
