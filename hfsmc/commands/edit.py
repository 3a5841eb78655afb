"""``hfsmc edit MODEL``: serve the model's editor page (docs/editor.md)."""

from __future__ import annotations

import asyncio
import os
from pathlib import Path

from hfsmc.errors import UsageError

# The component's own address parser, shipped in the data package hfsmc.templates.
from hfsmc.templates.python import hfsmc_monitor  # type: ignore[import-not-found]


def edit(model: str, web: str, monitor: str | None = None) -> int:
    """Serve the editor of ``model`` on ``web`` ([HOST:]PORT, loopback unless a host is
    named) until SIGINT/SIGTERM, showing the component at ``monitor`` ([HOST:]PORT) when
    given; raises UsageError for what cannot be served."""
    from hfsmc.edit.text import EditError
    from hfsmc.editor.server import Editor, serve
    from hfsmc.web.server import listen
    from hfsmc.web.trust import Trust

    path = Path(model)
    if not path.is_file():
        raise UsageError(f"{model}: no such model file")
    try:
        host, port = hfsmc_monitor.parse_address(web)
    except ValueError as e:
        raise UsageError(f"--web: {e}") from None
    target = None
    if monitor is not None:
        try:
            target = hfsmc_monitor.parse_address(monitor)
        except ValueError as e:
            raise UsageError(f"--monitor: {e}") from None
        if target[1] == 0:
            raise UsageError(f"--monitor: bad address {monitor!r}: port 0 is not a "
                             "component's port")
    try:
        editor = Editor(path.resolve(), target)
    except (OSError, UnicodeDecodeError, EditError) as e:
        raise UsageError(f"{model}: cannot be edited: {e}") from None
    try:
        sock = listen(host, port)
    except OSError as e:
        why = os.strerror(e.errno) if e.errno else str(e)
        raise UsageError(f"cannot serve the editor on "
                         f"{hfsmc_monitor.format_address(host, port)}: {why}") from None
    try:
        asyncio.run(serve(sock, editor, Trust.new(sock, host)))
    finally:
        sock.close()
    return 0
