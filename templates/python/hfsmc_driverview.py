"""A user driver as the live views show it (schemas/monitor.md, minor version 4).

Copied beside every generated Python component and imported by ``hfsmc view``: standard
library only. The monitor and ``--display`` call ``driver_message`` about 4 times a
second with the snapshot the driver gave the automaton's latest instant
(``Driver.view_fields()``, docs/drivers.md): its declared fields and their values, in the
declaration's order, whatever the driver is. ``driver_rows`` is the terminal view's
small table of one such message; the web view draws the same table.
"""

from __future__ import annotations

import math
from typing import Any

MAX_FIELDS = 64  # a snapshot with more fields is cut (a view needs no more)
MAX_TEXT = 80  # a value longer than that, as text, ends with an ellipsis


def is_driver(obj: Any) -> bool:
    """A driver shown by its snapshot's fields (hfsmc_driver.Driver), live or a playback's
    fake. Not one whose ``VIEW`` is another feed (the built-in mavlink's: the vehicle panel)
    nor one with images (``FRAMES``: the camera), shown by the latest image a snippet obtained."""
    return isinstance(getattr(type(obj), "KIND", None), str) and \
        isinstance(getattr(type(obj), "SNAPSHOT", None), dict) and \
        callable(getattr(obj, "view_fields", None)) and \
        getattr(type(obj), "VIEW", "driver") == "driver" and not getattr(type(obj), "FRAMES", "")


def shown(value: Any) -> Any:
    """A field's value in a message: a number (rounded to 6 significant digits), a
    boolean, null, or text of at most MAX_TEXT characters (infinities and NaN as
    `inf`, `-inf`, `nan`, as recordings write them; a list as it prints)."""
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, int):
        return value if abs(value) < 1 << 53 else str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
        return float(f"{value:.6g}")
    if isinstance(value, (tuple, list)):
        text = "[" + ", ".join(str(shown(x)) for x in list(value)[:MAX_FIELDS]) + "]"
    else:
        text = str(value)
    return text if len(text) <= MAX_TEXT else text[:MAX_TEXT - 1] + "…"


def driver_message(name: str, t_ms: int, driver: Any) -> dict[str, Any]:
    """The ``driver`` message of the interface ``name``: its fields at the latest instant."""
    snap = driver.view_fields()
    fields = [{"name": str(k), "value": shown(snap.get(k))}
              for k in list(type(driver).SNAPSHOT)[:MAX_FIELDS]]
    return {"type": "driver", "t": int(t_ms), "name": name, "kind": str(type(driver).KIND),
            "live": bool(getattr(driver, "live", True)), "fields": fields}


def valid(msg: dict[str, Any]) -> bool:
    """A ``driver`` message a viewer shows (what it cannot read, it ignores)."""
    fields = msg.get("fields")
    return isinstance(msg.get("name"), str) and isinstance(msg.get("kind"), str) \
        and isinstance(fields, list) and len(fields) <= MAX_FIELDS \
        and all(isinstance(f, dict) and isinstance(f.get("name"), str) for f in fields)


def cleaned(msg: dict[str, Any]) -> dict[str, Any] | None:
    """A ``driver`` message rebuilt from what is expected of it, each text cut to
    MAX_TEXT characters (what the web view passes on to its pages); None if invalid."""
    if not valid(msg):
        return None

    def cut(x: object) -> str:
        text = str(x)
        return text if len(text) <= MAX_TEXT else text[:MAX_TEXT - 1] + "…"

    def value(v: object) -> Any:
        if v is None or isinstance(v, bool):
            return v
        if isinstance(v, (int, float)):
            return v if math.isfinite(v) else None
        return cut(v)

    t = msg.get("t")
    return {"type": "driver", "t": t if isinstance(t, int) and not isinstance(t, bool) else 0,
            "name": cut(msg["name"]), "kind": cut(msg["kind"]), "live": msg.get("live") is not False,
            "fields": [{"name": cut(f["name"]), "value": value(f.get("value"))}
                       for f in msg["fields"]]}


def text_of(value: Any) -> str:
    """A field's value as the views print it."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def driver_rows(msg: dict[str, Any]) -> list[tuple[str, str]]:
    """A ``driver`` message as the terminal view's rows: a title, then field and value
    (the caller cleans what it prints)."""
    title = f"{msg.get('kind')} {msg.get('name')}" + ("" if msg.get("live", True) else " (playback)")
    return [(title, ""), *((str(f.get("name")), text_of(f.get("value")))
                           for f in msg.get("fields", ()))]
