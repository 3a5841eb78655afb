"""The files a model `use`s, each edited in a tab of its own (docs/editor.md, "Used
files"): the page opens ``/?file=KEY``, KEY the file's path relative to the model's
folder as its `use` names it. Only the model and the files it uses (and those they use,
read as the check reads them) can be opened: any other name is refused, whatever it
resolves to. Each file gets its own edit session, layout file and watcher."""

from __future__ import annotations

import asyncio
import contextlib
import os
import weakref
from pathlib import Path
from typing import Any, Protocol

from hfsmc.edit.session import EditSession
from hfsmc.errors import Diagnostics
from hfsmc.frontend import load

MAX_FILES = 64  # a model using more files than this is not one a person draws


class Tab(Protocol):
    path: Path
    session: EditSession

    async def watch(self) -> None: ...


class Opened:
    """The tabs opened besides the model's own: key -> editor, and their watchers."""

    def __init__(self) -> None:
        self.editors: dict[str, Any] = {}
        self.watchers: list[asyncio.Task[None]] = []


_OPENED: weakref.WeakKeyDictionary[Any, Opened] = weakref.WeakKeyDictionary()
_MAIN: weakref.WeakKeyDictionary[Any, Any] = weakref.WeakKeyDictionary()


def _uses(path: Path, text: str) -> list[tuple[str, Path]]:
    """Every state path of the model (``text`` at ``path``) that `use`s a file, and the file."""
    try:
        data = load(str(path), Diagnostics(), text).data
    except Exception:  # a text the front end cannot read: nothing to open from it
        return []
    out: list[tuple[str, Path]] = []

    def walk(body: Any, prefix: str) -> None:
        for group in ("states", "regions"):
            kids = body.get(group) if isinstance(body, dict) else None
            for name, sub in (kids.items() if isinstance(kids, dict) else []):
                if not isinstance(sub, dict):
                    continue
                here = prefix + str(name)
                if isinstance(sub.get("use"), str):
                    out.append((here, path.parent / sub["use"]))
                walk(sub, here + "/")
    walk(data, "")
    return out


def allowed(main: Tab) -> dict[str, Path]:
    """The files the page may open: key (relative to the model's folder) -> path."""
    folder = main.path.parent
    found: dict[str, Path] = {}
    todo = [(main.path, main.session.text)]
    seen = {main.path.resolve()}
    while todo and len(found) < MAX_FILES:
        path, text = todo.pop()
        for _state, used in _uses(path, text):
            real = used.resolve()
            if real in seen or not real.is_file():
                continue
            seen.add(real)
            found[Path(os.path.relpath(used, folder)).as_posix()] = real
            with contextlib.suppress(OSError, UnicodeDecodeError):
                todo.append((used, real.read_text("utf-8")))
    return found


def links(editor: Tab) -> dict[str, Any]:
    """For the page of ``editor``: each `use`ing state's tab key (relative to the model's
    folder), and this page's own key ("" the model's)."""
    main = _MAIN.get(editor, editor)
    folder = main.path.parent
    out = {state: Path(os.path.relpath(used, folder)).as_posix()
           for state, used in _uses(editor.path, editor.session.text)}
    own = "" if main is editor else Path(os.path.relpath(editor.path, folder)).as_posix()
    return {"tabs": out, "tab": own}


def pick(main: Any, key: str | None, make: Any) -> Any:
    """The editor of tab ``key`` (None or "": the model's), made with ``make(path)`` the
    first time; ValueError for a file the model does not use."""
    if not key:
        return main
    opened = _OPENED.setdefault(main, Opened())
    if key in opened.editors:
        return opened.editors[key]
    path = allowed(main).get(key)
    if path is None:
        raise ValueError(f"{key}: not a file {main.path.name} uses: only the model and the "
                         "files it uses open in the editor")
    editor = make(path)
    opened.editors[key] = editor
    _MAIN[editor] = main
    opened.watchers.append(asyncio.create_task(editor.watch()))
    return editor


async def close(main: Any) -> None:
    """Stop the watchers of the tabs opened besides the model's own."""
    opened = _OPENED.pop(main, None)
    if opened is None:
        return
    for task in opened.watchers:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
    for editor in opened.editors.values():
        for ws in list(editor.pages):
            with contextlib.suppress(Exception):
                await ws.close()
