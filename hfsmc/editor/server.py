"""The editor's server: the page, its files and one WebSocket per page, all behind the web
view's trust rules (a token per run turned into a cookie, Host and Origin checked:
hfsmc/web/trust.py). The server holds the edit session; a page sends operations by name
(a whitelist of the engine's, with their arguments checked), undo, redo, save, a state's
position, and is answered with the whole model as it now is (docs/editor.md)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import sys
from importlib import resources
from pathlib import Path
from typing import Any, TextIO

from aiohttp import WSMsgType, web

from hfsmc.edit.session import Conflict, EditSession
from hfsmc.edit.text import EditError
from hfsmc.editor import clipboard, forms, tabs
from hfsmc.editor.build import check_cxx
from hfsmc.editor.gutter import place
from hfsmc.editor.live import OPS as LIVE_OPS
from hfsmc.editor.live import PAUSED, Live
from hfsmc.editor.model import SNIPPETS, Layout, diagnostics, structure
from hfsmc.frontend import is_xml
from hfsmc.web.server import release_signals, stop_on_signals, url_of
from hfsmc.web.trust import Trust, guard, headers, loopback_only

WS_MESSAGE_LIMIT = 1 << 20  # a snippet is text a person typed: 1 MiB is plenty
MAX_PAGES = 16
FILES = {"": ("editor.html", "text/html"), "editor.js": ("editor.js", "text/javascript"),
         **{f"{n}.js": (f"{n}.js", "text/javascript") for n in forms.PAGE_SCRIPTS},
         "editor.css": ("editor.css", "text/css"),
         "editor_live.js": ("editor_live.js", "text/javascript"),
         "editor_live.css": ("editor_live.css", "text/css"),
         "vendor/codemirror.js": ("vendor/codemirror.js", "text/javascript")}
# The page's own files and its WebSocket only; no eval (CodeMirror needs none); CodeMirror
# adds its styles as <style> elements, hence style-src 'unsafe-inline'.
CSP = ("default-src 'none'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
       "img-src 'self' data:; connect-src 'self'; base-uri 'none'; form-action 'none'; "
       "frame-ancestors 'none'")
TRANSITION_KEYS = ("name", "to", "when", "after", "do")
READ_ONLY_XML = ("XML models open read-only in the page for now: edit the file, or convert it "
                 "to YAML (docs/editor.md)")


class BadRequest(Exception):
    """A message from the page that is not an operation the editor makes."""


def _arg(args: dict[str, Any], name: str, kind: type, optional: bool = False) -> Any:
    value = args.get(name)
    if value is None and optional:
        return None
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise BadRequest(f"`{name}` must be a {kind.__name__}")
    if isinstance(value, str) and len(value) > WS_MESSAGE_LIMIT:
        raise BadRequest(f"`{name}` is too long")
    return value


def _number(args: dict[str, Any], name: str) -> float:
    value = args.get(name)
    if isinstance(value, bool) or not isinstance(value, int | float) or \
            not -1e6 < value < 1e6:
        raise BadRequest(f"`{name}` must be a number between -1e6 and 1e6")
    return float(value)


class Editor:
    """The edit session of one model, its layout, and the pages that show it."""

    def __init__(self, path: Path, monitor: tuple[str, int] | None = None) -> None:
        self.path = path
        self.session = EditSession.open(str(path))
        self.read_only = is_xml(self.session.text)
        self.layout = Layout.beside(path)
        self.conflict = False
        self.pages: set[web.WebSocketResponse] = set()
        self.live = Live(path, self.send_all, monitor)  # --monitor, Build and run
        self._told_for: tuple[str, int] | None = None  # the text shape and found are of
        self._shape: dict[str, Any] = {}
        self._found: list[dict[str, Any]] = []

    # ----- what a page is told

    def state(self, message: str | None = None) -> dict[str, Any]:
        s = self.session
        key = (s.text, id(s.diagnostics))
        if self._told_for != key:  # a save, a move or a page's arrival: the text is the same
            self._told_for, self._shape = key, structure(s)
            self._found = diagnostics(s)
            place(s.text, self._found)  # where in its snippet each is, for the gutters
        shape, found = self._shape, self._found
        return {"type": "model", "file": self.path.name, "read_only": self.read_only,
                "dirty": s.text != s.disk, "conflict": self.conflict,
                "can_undo": bool(s.undo_stack), "can_redo": bool(s.redo_stack),
                **shape, "positions": self.layout.positions(shape),
                "diagnostics": found, "message": message,
                "layout_problem": self.layout.problem, **tabs.links(self)}

    async def tell_all(self, message: str | None = None) -> None:
        await self.send_all(self.state(message))

    async def send_all(self, msg: dict[str, Any]) -> None:
        text = json.dumps(msg)
        for ws in list(self.pages):
            with contextlib.suppress(ConnectionError, RuntimeError):
                await ws.send_str(text)

    # ----- what a page asks

    def handle(self, msg: dict[str, Any]) -> str | dict[str, Any] | None:
        """Make what the page asks; a message for the pages, or None, or (a dict) a reply
        for the page that asked only."""
        op = msg.get("op")
        args: dict[str, Any] = msg["args"] if isinstance(msg.get("args"), dict) else {}
        if op == "move":
            if self.live.paused:
                raise EditError(PAUSED)
            self.layout.move(_arg(args, "state", str), _number(args, "x"), _number(args, "y"))
            return None
        if op in ("undo", "redo") and self.live.paused:
            raise EditError(PAUSED)
        if op == "undo":
            return None if self.session.undo() else "nothing to undo"
        if op == "redo":
            return None if self.session.redo() else "nothing to redo"
        if op == "save":
            return self.save()
        if op == "reload":
            return self.reload()
        if op == "copy":
            return clipboard.copy(self.session, _arg(args, "path", str))
        if self.live.paused:
            raise EditError(PAUSED)
        if self.read_only:
            raise EditError(READ_ONLY_XML)
        if op == "paste":
            return clipboard.paste(self.session, _arg(args, "parent", str), _arg(args, "text", str))
        make = self._operation(str(op), args)
        self.session.apply(make)
        if op == "rename":
            old = args["path"]
            parent = old.rsplit("/", 1)[0] + "/" if "/" in old else ""
            self.layout.renamed(old, parent + args["new"])
        return None

    def _operation(self, op: str, a: dict[str, Any]) -> Any:
        """The engine's operation ``op`` with the page's arguments, checked (a whitelist)."""
        if op == "add_state":
            parent, name = _arg(a, "parent", str), _arg(a, "name", str)
            return lambda o: o.add_state(parent, name)
        if op == "delete_state":
            path = _arg(a, "path", str)
            return lambda o: o.delete_state(path)
        if op == "rename":
            path, new = _arg(a, "path", str), _arg(a, "new", str)
            return lambda o: o.rename(path, new)
        if op == "add_transition":
            state, to = _arg(a, "state", str), _arg(a, "to", str)
            return lambda o: o.add_transition(state, {"to": to})
        if op == "delete_transition":
            state, i = _arg(a, "state", str), _arg(a, "index", int)
            return lambda o: o.delete_transition(state, i)
        if op == "move_transition":
            state, i, to = _arg(a, "state", str), _arg(a, "index", int), _arg(a, "to", int)
            return lambda o: o.move_transition(state, i, to)
        if op == "set_state_field":
            state, key = _arg(a, "state", str), _arg(a, "key", str)
            value = _arg(a, "value", str, optional=True)
            if key not in (*SNIPPETS, "initial"):
                raise BadRequest(f"`{key}` is not a field the page edits")
            return lambda o: o.set_state_field(state, key, value or None)
        if op == "set_transition_field":
            state, i, key = _arg(a, "state", str), _arg(a, "index", int), _arg(a, "key", str)
            value = _arg(a, "value", str, optional=True)
            if key not in TRANSITION_KEYS:
                raise BadRequest(f"`{key}` is not a field of a transition")
            return lambda o: o.set_field((*o.element(state).doc_path, "transitions", i, key),
                                         value or None)
        made = forms.operation(op, a, _arg)
        if made is not None:
            return made
        raise BadRequest(f"no operation `{op}`")

    def save(self) -> str:
        if self.read_only:
            return READ_ONLY_XML
        try:
            self.session.save()
        except Conflict:
            self.conflict = True
            return (f"not saved: {self.path.name} changed on disk since it was read. Reload "
                    "takes the disk's text (then Ctrl+Z gives your edits back)")
        self.conflict = False
        if "cpp" in self.session.text and structure(self.session)["language"] == "cpp":
            # g++ over the snippets, as `hfsmc check` does: kept until the next change
            self.session.diagnostics, note = check_cxx(self.session)
            if note:
                return f"saved {self.path.name}; {note}"
        return f"saved {self.path.name}"

    def reload(self) -> str:
        now = self.path.read_text("utf-8")
        self.session.replace(now)
        self.session.disk = now
        self.conflict = False
        return f"reloaded {self.path.name} from the disk"

    async def watch(self) -> None:
        """The file on disk, watched for other writers: taken when nothing is unsaved, a
        conflict otherwise (never overwritten)."""
        while True:
            await asyncio.sleep(0.3)
            try:
                now = self.path.read_text("utf-8")
            except (OSError, UnicodeDecodeError):
                continue
            s = self.session
            if now == s.disk or self.conflict:
                continue
            if s.text == s.disk:
                s.replace(now)
                s.disk = now
                await self.tell_all(f"{self.path.name} changed on disk: reloaded")
            else:
                self.conflict = True
                await self.tell_all(f"{self.path.name} changed on disk while you have unsaved "
                                    "edits: Save is refused; Reload takes the disk's text")


_EDITOR = web.AppKey("editor", Editor)
_FILES = web.AppKey("files", dict)


def make_app(editor: Editor, trust: Trust, log: TextIO | None = None) -> web.Application:
    app = web.Application(middlewares=[guard(trust, log)], client_max_size=WS_MESSAGE_LIMIT)
    app.on_response_prepare.append(headers)
    app[_EDITOR] = editor
    folder = resources.files("hfsmc.web") / "static"
    app[_FILES] = {route: ((folder / name).read_bytes(), kind)
                   for route, (name, kind) in FILES.items()}
    for route in FILES:
        app.router.add_get("/" + route, _file)
    app.router.add_get("/ws", _socket)
    app.router.add_get("/favicon.ico", _no_icon)
    app.on_cleanup.append(lambda _app: tabs.close(editor))
    return app


async def _file(request: web.Request) -> web.Response:
    body, kind = request.app[_FILES][request.path.lstrip("/")]
    return web.Response(body=body, content_type=kind, charset="utf-8",
                        headers={"Cache-Control": "no-cache", "Content-Security-Policy": CSP})


async def _no_icon(request: web.Request) -> web.Response:
    return web.Response(status=204)


async def _socket(request: web.Request) -> web.WebSocketResponse:
    ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=WS_MESSAGE_LIMIT)
    await ws.prepare(request)
    try:  # a `use`d file's own tab (docs/editor.md), else the model
        editor = tabs.pick(request.app[_EDITOR], request.query.get("file"), Editor)
    except (ValueError, OSError, UnicodeDecodeError, EditError) as e:
        await ws.send_str(json.dumps({"type": "error", "message": str(e)}))
        await ws.close(code=1008, message=b"not a file of this model")
        return ws
    if len(editor.pages) >= MAX_PAGES:
        await ws.close(code=1013, message=b"too many pages")
        return ws
    editor.pages.add(ws)
    try:
        await ws.send_str(json.dumps(editor.state()))
        await ws.send_str(json.dumps(editor.live.message()))
        await ws.send_str(json.dumps(editor.live.log_message()))
        async for msg in ws:
            if msg.type != WSMsgType.TEXT:
                continue
            try:
                asked = json.loads(msg.data)
                if not isinstance(asked, dict):
                    raise BadRequest("a message is a JSON object")
                if asked.get("op") in LIVE_OPS:  # the overlay, Build and run: live.py
                    s = editor.session
                    said = await editor.live.handle(str(asked["op"]), s.text == s.disk,
                                                    editor.conflict)
                    if said is not None:
                        await ws.send_str(json.dumps({"type": "note", "message": said}))
                    continue
                said = await asyncio.to_thread(editor.handle, asked)
            except (BadRequest, EditError, ValueError, OSError) as e:
                await ws.send_str(json.dumps({"type": "error", "message": str(e)}))
                said = "error"
            except Exception as e:  # a bug: said in one line, the server goes on
                await ws.send_str(json.dumps({"type": "error", "message":
                                              f"internal error: {type(e).__name__}: {e} "
                                              "(please report it)"}))
                said = "error"
            if isinstance(said, dict):
                await ws.send_str(json.dumps(said))
            elif said != "error":
                await editor.tell_all(said)
    finally:
        editor.pages.discard(ws)
    return ws


async def serve(sock: socket.socket, editor: Editor, trust: Trust, out: TextIO | None = None,
                log: TextIO | None = None, stop: asyncio.Event | None = None) -> None:
    """Serve the editor on ``sock`` until SIGINT/SIGTERM (or ``stop``)."""
    out = out if out is not None else sys.stdout
    log = log if log is not None else sys.stderr
    stop = stop if stop is not None else asyncio.Event()
    stop_on_signals(stop)
    runner = web.AppRunner(make_app(editor, trust, log), access_log=None, handle_signals=False)
    await runner.setup()
    watching = asyncio.create_task(editor.watch())
    try:
        if editor.live.target is not None:
            await editor.live.watch(*editor.live.target)
        await web.SockSite(runner, sock, shutdown_timeout=1.0).start()
        if not loopback_only(sock):
            print(f"hfsmc edit: warning: the editor on {sock.getsockname()[:2]} can be reached "
                  "from other machines: whoever has its URL with the token can change "
                  f"{editor.path.name}, which is code that is built and run", file=log, flush=True)
        print(f"hfsmc edit: editing {editor.path.name} on {url_of(sock, trust.token)} "
              "(Ctrl+C to stop)", file=out, flush=True)
        await stop.wait()
    finally:
        watching.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await watching
        await editor.live.close()  # the run ends with the editor
        for ws in list(editor.pages):
            with contextlib.suppress(Exception):
                await ws.close()
        await runner.cleanup()
        release_signals()
