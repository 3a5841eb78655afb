"""``hfsmc view``: watch a running component's monitor, or replay a trace, in the terminal.

The view itself (``ViewState``, the rich tree, plain lines) and the monitor
protocol live in the component's own runtime modules, shipped in
``hfsmc.templates.python``, so that a component and ``hfsmc view`` show the
same screen.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from collections.abc import Iterator
from typing import Any

from hfsmc.emit.structure import structure_of
from hfsmc.ir import Model

# The component's own modules, shipped as the data package hfsmc.templates (mapped
# from templates/ by setuptools, a mapping mypy does not follow: they are typed Any here).
from hfsmc.templates.python import hfsmc_monitor, hfsmc_view  # type: ignore[import-not-found]

Item = tuple[str, Any]


class _ViewError(Exception):
    """A problem reported in one line, with an exit status."""

    def __init__(self, message: str, status: int = 1) -> None:
        super().__init__(message)
        self.status = status


def view(target: str | None, replay: str | None, focus: str | None = None,
         autofocus: bool = True, speed: float = 1.0, model: str | None = None,
         web: str | None = None, allow_hosts: tuple[str, ...] = (),
         world: str | None = None) -> int:
    """Run ``hfsmc view`` and return its exit status.

    ``target`` is ``[HOST:]PORT`` of a component started with ``--monitor``;
    ``replay`` a trace file (``--trace``) played at ``speed`` times real time
    (0: at once, then the final screen), its tree taken from ``model`` when
    given, else inferred from the paths in the trace. With ``web``
    (``[HOST:]PORT``) the component is shown in a browser instead
    (docs/web.md), drawn from ``model`` when given, or the trace ``replay``
    is played there, from the pages' controls; the pages are served under loopback
    names, the host of ``web`` and the names ``allow_hosts`` (``--allow-host``); ``world``
    (a ground world file) is drawn under a ros2 interface's map. Errors
    are one line on stderr: exit 2 for usage errors, 1 for anything else.
    """
    try:
        if (target is None) == (replay is None):
            raise _ViewError("give either [HOST:]PORT or --replay TRACE", 2)
        if allow_hosts and web is None:
            raise _ViewError("--allow-host is for the web view (--web [HOST:]PORT)", 2)
        if world is not None and (web is None or replay is not None):
            raise _ViewError("--world is for the web view of a running component "
                             "(--web [HOST:]PORT and the component's [HOST:]PORT)", 2)
        if web is not None:
            if focus is not None:
                raise _ViewError("--focus is for the terminal view; the web view draws every state",
                                 2)
            allowed = _allowed_names(allow_hosts)
            if replay is not None:
                return _web_replay(web, replay, model, autofocus, speed, allowed)
            assert target is not None
            return _web(web, target, model, autofocus, allowed, world)
        if replay is not None:
            return _replay(replay, focus, autofocus, speed, model)
        assert target is not None
        return _attach(target, focus, autofocus)
    except _ViewError as e:
        print(f"hfsmc: error: {e}", file=sys.stderr)
        return e.status


def _attach(target: str, focus: str | None, autofocus: bool) -> int:
    try:
        host, port = hfsmc_monitor.parse_address(target)
    except ValueError as e:
        raise _ViewError(str(e), 2) from None
    if port == 0:
        raise _ViewError(f"bad address {target!r}: port 0 is not a component's port", 2)
    label = hfsmc_monitor.format_address(host, port)
    try:
        sock = hfsmc_monitor.connect(host, port)
    except OSError as e:
        raise _ViewError(f"cannot connect to {label}: {e.strerror or e}") from None

    def hang_up() -> None:
        with contextlib.suppress(OSError):
            sock.close()

    print(f"hfsmc view: connected to {label}", file=sys.stderr, flush=True)
    items = hfsmc_monitor.client_items(sock, label)
    return int(hfsmc_view.run_viewer(items, focus, autofocus, stop=hang_up))


def _allowed_names(given: tuple[str, ...]) -> tuple[str, ...]:
    from hfsmc.hosts import allowed_name

    try:
        return tuple(allowed_name(text) for text in given)
    except ValueError as e:
        raise _ViewError(str(e), 2) from None


def _web_listen(web: str) -> Any:
    """The web view's listening socket at ``web`` ([HOST:]PORT)."""
    try:
        from hfsmc.web.server import listen
    except ImportError as e:  # an installation made before the web view needed aiohttp
        raise _ViewError(f"the web view needs {e.name or 'aiohttp'}: reinstall hfsmc "
                         "(pip install aiohttp)") from None
    try:
        web_host, web_port = hfsmc_monitor.parse_address(web)
    except ValueError as e:
        raise _ViewError(str(e), 2) from None
    try:
        return listen(web_host, web_port)
    except OSError as e:
        where = hfsmc_monitor.format_address(web_host, web_port)
        why = os.strerror(e.errno) if e.errno else str(e)
        raise _ViewError(f"cannot serve the web view on {where}: {why}") from None


def _web_replay(web: str, path: str, model_path: str | None, autofocus: bool,
                speed: float, allow: tuple[str, ...]) -> int:
    from hfsmc.errors import UsageError

    if not (speed > 0 and speed <= 1000):  # also refuses NaN
        raise _ViewError(f"bad --speed {speed}: the web view plays from more than 0 to 1000 "
                         "times real time", 2)
    try:
        named = hfsmc_monitor.parse_address(web)[0]
    except ValueError as e:
        raise _ViewError(str(e), 2) from None
    records = load_trace(path)
    model = _load_model(model_path, "the trace") if model_path is not None else None
    sock = _web_listen(web)
    try:
        from hfsmc.web import replay

        return int(replay(sock, path, records, model, speed=speed, autofocus=autofocus,
                          named=named, allow=allow))
    except UsageError as e:
        raise _ViewError(str(e)) from None
    finally:
        sock.close()


def _world_map(path: str) -> Any:
    """A ground world file as the web view's plain data; _ViewError at its problem."""
    from hfsmc.sim.ground.world import load_ground_world
    from hfsmc.sim.world import WorldError
    from hfsmc.web.ros2 import WorldMap

    try:
        w = load_ground_world(path)
    except WorldError as e:
        raise _ViewError(f"--world: {e}") from None
    return WorldMap(file=path, walls=w.walls,
                    boxes=tuple((b.x, b.y, b.length, b.width, b.yaw_deg) for b in w.boxes),
                    robots=tuple((r.name, r.namespace, r.x, r.y, r.yaw_deg) for r in w.robots))


def _web(web: str, target: str, model_path: str | None, autofocus: bool,
         allow: tuple[str, ...], world_path: str | None = None) -> int:
    from hfsmc.errors import UsageError
    from hfsmc.web import watch

    try:
        host, port = hfsmc_monitor.parse_address(target)
        named = hfsmc_monitor.parse_address(web)[0]
    except ValueError as e:
        raise _ViewError(str(e), 2) from None
    if port == 0:
        raise _ViewError(f"bad address {target!r}: port 0 is not a component's port", 2)
    model = _load_model(model_path) if model_path is not None else None
    world = _world_map(world_path) if world_path is not None else None
    sock = _web_listen(web)
    try:
        return int(watch(sock, host, port, model, autofocus=autofocus, named=named,
                         allow=allow, world=world))
    except UsageError as e:
        raise _ViewError(str(e)) from None
    finally:
        sock.close()


def _replay(path: str, focus: str | None, autofocus: bool, speed: float, model: str | None) -> int:
    if not speed >= 0:  # also refuses NaN
        raise _ViewError(f"bad --speed {speed}: expected 0 (as fast as possible) or more", 2)
    records = load_trace(path)
    structure = hfsmc_view.infer_structure(records) if model is None else _model_structure(model)
    state = hfsmc_view.ViewState(structure)
    wanted = (focus or "").strip("/")
    if wanted and wanted not in state.children:
        where = model if model is not None else path
        raise _ViewError(f"--focus {focus}: no state of that path in {where}", 2)
    items = _replay_items(records, structure, speed, path)
    return int(hfsmc_view.run_viewer(items, focus, autofocus))


def load_trace(path: str) -> list[dict[str, Any]]:
    """The records of a trace file (docs/semantics.md §13); _ViewError at the first bad line."""
    records: list[dict[str, Any]] = []
    try:
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    rec = json.loads(line)
                except ValueError as e:
                    raise _ViewError(f"{path}:{n}: bad trace record: {getattr(e, 'msg', e)}") from None
                except RecursionError:
                    raise _ViewError(f"{path}:{n}: bad trace record: nested too deeply") from None
                why: str | None = hfsmc_view.check_record(rec)
                if why is not None:
                    raise _ViewError(f"{path}:{n}: bad trace record: {why}")
                records.append(rec)
    except UnicodeDecodeError:
        raise _ViewError(f"{path}: not a trace (not UTF-8 text)") from None
    except OSError as e:
        raise _ViewError(f"cannot read {path}: {e.strerror or e}") from None
    if not records:
        raise _ViewError(f"{path}: no trace records")
    return records


def _replay_items(records: list[dict[str, Any]], structure: dict[str, Any], speed: float,
                  path: str) -> Iterator[Item]:
    """The records at their times (scaled by ``speed``), the clock moving in between."""
    yield "structure", structure
    start = time.monotonic()
    for rec in records:
        if speed > 0:
            due = start + rec["t"] / 1000 / speed
            while (now := time.monotonic()) < due:
                time.sleep(min(0.1, due - now))
                yield "advance", min(int((time.monotonic() - start) * 1000 * speed), rec["t"])
        yield "record", rec
    yield "end", f"replayed {len(records)} records of {path}"


def _model_structure(path: str) -> dict[str, Any]:
    return structure_of(_load_model(path, "the trace"))


def _load_model(path: str, what: str = "the component") -> Model:
    from hfsmc.errors import render_text
    from hfsmc.pipeline import compile_file

    result = compile_file(path)
    if result.model is None or not result.ok:
        sys.stderr.write(render_text(result.diagnostics, result.sources,
                                     color=sys.stderr.isatty()))
        raise _ViewError(f"{path} has errors; {what} cannot be shown with it")
    return result.model
