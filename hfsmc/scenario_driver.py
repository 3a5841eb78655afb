"""A user driver's snapshot scripted by a scenario (docs/testing.md, "Interfaces of your own").

A driver declares its snapshot's fields with their "nothing yet" values
(docs/drivers.md); a scenario's entry under such an interface names those fields, and
each value must be of its default's type: ``true``/``false`` for a bool, an integer for
an int, a number for a float (``.inf``, ``.nan`` too), a string for a str, a list for a
tuple (its items of the first item's type). Numbers and lists of numbers may ramp, as
the built-in interfaces' numbers do. The scenario's reader keeps every value as written
(with its positions: :class:`~hfsmc.scenario_ros2.Written`), since which fields exist
is known only once the model is; :func:`check_settings` checks them against the
driver's declaration, and :func:`driver_value` gives the value the fake receives.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from hfsmc.drivers import Driver
from hfsmc.errors import Diagnostics, Span, did_you_mean
from hfsmc.scenario_ros2 import Written


@dataclass(frozen=True, slots=True)
class Ramp:
    """A value moving linearly from ``start`` to ``end`` over an entry's span."""

    start: Any  # a float, or a tuple of floats (a vector)
    end: Any


def _kind(v: Any) -> str:
    return {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number", type(None): "null"}.get(type(v), type(v).__name__)


def _type_words(default: Any) -> str:
    if isinstance(default, bool):
        return "true or false"
    if isinstance(default, int):
        return "an integer"
    if isinstance(default, float):
        return "a number (.nan and .inf are numbers too)"
    if isinstance(default, str):
        return "a string"
    if isinstance(default, (tuple, list)):
        items = {bool: "booleans", int: "integers", float: "numbers", str: "strings"}
        return "a list" + (f" of {items[type(default[0])]}" if default
                           and type(default[0]) in items else "")
    return "a value"


def _plain(w: Written) -> Any:
    if isinstance(w.value, dict):
        return {k: _plain(x) for k, x in w.value.items()}
    if isinstance(w.value, list):
        return [_plain(x) for x in w.value]
    return w.value


def _scalar(default: Any, w: Written, what: str, diags: Diagnostics) -> Any:
    """``w`` as a value of ``default``'s type; None (said in ``diags``) when it is not."""
    v = w.value
    ok: bool
    if isinstance(default, bool):
        ok = isinstance(v, bool)
    elif isinstance(default, int):
        ok = isinstance(v, int) and not isinstance(v, bool)
        if ok and not -(1 << 63) <= v < 1 << 63:  # what a C++ driver's long long holds
            diags.error("E191", f"{what}: {v} is out of the range of a 64-bit integer", w.span)
            return None
    elif isinstance(default, float):
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        if ok:
            try:
                return float(v)
            except OverflowError:
                diags.error("E191", f"{what}: {v} is beyond what a float holds", w.span)
                return None
    elif isinstance(default, str):
        ok = isinstance(v, str)
    elif isinstance(default, (tuple, list)):
        if not isinstance(v, list):
            ok = False
        else:
            item = default[0] if default else None
            out = []
            for x in v:
                if isinstance(x.value, (dict, list)) and not isinstance(item, (tuple, list)):
                    diags.error("E191", f"an item of {what} must be "
                                f"{_type_words(item) if item is not None else 'a scalar'}, "
                                f"not {_kind(x.value)}", x.span)
                    return None
                if item is None:
                    out.append(_plain(x))
                    continue
                got = _scalar(item, x, f"an item of {what}", diags)
                if got is None:
                    return None
                out.append(got)
            return out
    else:  # a default of no JSON type the scenario can check: any plain value
        return _plain(w)
    if not ok:
        shown = f" (`{v}`)" if isinstance(v, (int, float, str)) and not isinstance(v, bool) \
            else ""
        diags.error("E191", f"{what} must be {_type_words(default)}, not {_kind(v)}{shown}",
                    w.span)
        return None
    return v


def _numeric(default: Any) -> bool:
    if isinstance(default, float):
        return True
    return isinstance(default, (tuple, list)) and bool(default) and all(
        isinstance(x, float) for x in default)


def driver_value(default: Any, w: Written, spanned: bool, field: str,
                 diags: Diagnostics) -> Any:
    """The value a scenario gives field ``field`` (its declared "nothing yet" value:
    ``default``), a :class:`Ramp` for ``{ramp: [A, B]}`` (``spanned``: in a from/to
    entry); None, said in ``diags``, when it is not one."""
    if isinstance(w.value, dict):
        if set(w.value) != {"ramp"}:
            diags.error("E191", f"`{field}` must be {_type_words(default)}, not a mapping "
                        "(a value that moves is `{ramp: [START, END]}`)", w.span)
            return None
        if not _numeric(default) and not (isinstance(default, (tuple, list)) and not default):
            diags.error("E193", f"`{field}` cannot ramp: only numbers and lists of numbers "
                        "do (its declared value is " + _type_words(default) + ")", w.span)
            return None
        if not spanned:
            diags.error("E193", "a ramp needs a span: `from: TIME, to: TIME`", w.span)
            return None
        ends = w.value["ramp"]
        if not isinstance(ends.value, list) or len(ends.value) != 2:
            diags.error("E191", "`ramp` takes [START, END]", ends.span)
            return None
        ramp_of = default if isinstance(default, float) else (0.0,)
        a, b = (_scalar(ramp_of, x, f"`{field}`", diags) for x in ends.value)
        if a is None or b is None:
            return None
        if isinstance(a, list):
            if len(a) != len(b):
                diags.error("E193", f"`{field}`: a ramp between lists of {len(a)} and "
                            f"{len(b)} numbers", ends.span)
                return None
            return Ramp(tuple(a), tuple(b))
        return Ramp(a, b)
    return _scalar(default, w, f"`{field}`", diags)


def check_settings(iface: str, declaration: Driver | None, settings: Iterable[Any],
                   interface_span: Span, diags: Diagnostics) -> None:
    """Every field an entry of the user driver interface ``iface`` sets: one it declares,
    with a value of its type (E195 for a field it lacks, E191/E193 for a bad value)."""
    if declaration is None:
        diags.error("E195", f"`{iface}`: its driver's declaration could not be read",
                    interface_span)
        return
    fields = dict(declaration.snapshot)
    for s in settings:
        raw: Written | None = s.raw
        if raw is None:
            continue
        if s.field not in fields:
            note = did_you_mean(s.field, fields)
            diags.error("E195", f"`{s.field}` is not a snapshot field of the {declaration.type} "
                        f"driver (`{iface}`)", s.key_span, *([note] if note else []),
                        f"its fields: {', '.join(fields) or 'none'}")
            continue
        driver_value(fields[s.field], raw, s.spanned, s.field, diags)


def to_json(v: Any) -> Any:
    """A value as inputs.jsonl writes it (infinities and NaN as strings, as recordings do)."""
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, (list, tuple)):
        return [to_json(x) for x in v]
    if isinstance(v, dict):
        return {k: to_json(x) for k, x in v.items()}
    return v
