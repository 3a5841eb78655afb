"""Validation of the neutral document against ``schemas/hfsm.schema.json``.

The validator is the ``jsonschema`` library; this module only turns its
errors into positioned diagnostics (key position for unknown keys, with a
"did you mean"; value position for wrong types and values).

``jsonschema`` walks the document in Python, schema keyword by keyword: on a
large valid model that is most of the validation's time.  So a document is
first given to a validator that ``fastjsonschema`` compiled from the same
schema (once per process): when it says valid, so would ``jsonschema`` (its
checks are the same or stricter: the ``$`` of a pattern is ``\\Z`` there),
and there is nothing to report; only a document it refuses goes through
``jsonschema``, whose errors are reported.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Iterator
from fractions import Fraction
from functools import cache
from typing import Any

from jsonschema import Draft202012Validator, validators
from jsonschema.exceptions import ValidationError, best_match

from hfsmc.durations import MAX_US, format_us
from hfsmc.errors import Diagnostics, did_you_mean
from hfsmc.frontend.source import Document, PathKey
from hfsmc.frontend.yaml_traps import snippet_kind
from hfsmc.resources import json_schema

try:
    import fastjsonschema
except ImportError:  # pragma: no cover - an install without it: jsonschema alone, slower
    fastjsonschema = None  # type: ignore[assignment]

_TYPE_NAMES = {
    "object": "a mapping",
    "array": "a list",
    "string": "a string",
    "integer": "an integer",
    "number": "a number",
    "boolean": "a boolean (true or false)",
    "null": "nothing",
}


@cache
def _validator() -> Draft202012Validator:
    schema = json_schema()
    Draft202012Validator.check_schema(schema)
    validator: Draft202012Validator = _Validator(schema)
    return validator


# Every `$ref` of the schema is local (`#/$defs/...`): where one leads depends only on the
# resolver's base URI, so each is looked up once, not once per value (a third of the
# validation time of a large model went into `referencing` lookups).
_refs: dict[tuple[str, str], Any] = {}


def _ref(validator: Any, ref: str, instance: Any, schema: Any) -> Iterator[ValidationError]:
    resolver = validator._resolver
    key = (resolver._base_uri, ref)
    resolved = _refs.get(key)
    if resolved is None:
        resolved = _refs[key] = resolver.lookup(ref)
    yield from validator.descend(instance, resolved.contents, resolver=resolved.resolver)


def _pattern(validator: Any, pattern: str, instance: Any, schema: Any) -> Iterator[ValidationError]:
    """`pattern` as JSON Schema means it (ECMA-262 regular expressions): a final `$` is the
    end of the text, not also the place before a final newline as for Python's `re`, so
    that a quoted name such as "A\\n" is no name (fastjsonschema reads it so too)."""
    if validator.is_type(instance, "string") and not _pattern_re(pattern).search(instance):
        yield ValidationError(f"{instance!r} does not match {pattern!r}")


def _shown(value: Any) -> Any:
    """A value for a message: a string with a newline or another control character escaped
    (`A\\n`), so that the message stays one line."""
    if isinstance(value, str) and not value.isprintable():
        return value.encode("unicode_escape").decode("ascii")
    return value


@cache
def _pattern_re(pattern: str) -> re.Pattern[str]:
    if pattern.endswith("$") and not pattern.endswith("\\$"):
        pattern = pattern[:-1] + r"\Z"
    return re.compile(pattern)


_Validator: Any = validators.extend(  # type: ignore[no-untyped-call]
    Draft202012Validator, {"$ref": _ref, "pattern": _pattern})


@cache
def _fast_validator() -> Callable[[Any], Any] | None:
    """The schema compiled to Python by fastjsonschema (None without it).

    fastjsonschema takes a tuple for a JSON array, jsonschema does not: the
    generated code is compiled without that, and the result is tried on a
    tuple before it is trusted (a version that generates other code is not
    used).
    """
    if fastjsonschema is None:
        return None  # pragma: no cover
    code = fastjsonschema.compile_to_code(json_schema()).replace(", tuple)", ")")
    name = re.search(r"^def (\w+)\(", code, re.M)
    if name is None:
        return None  # pragma: no cover
    scope: dict[str, Any] = {}
    try:
        exec(compile(code, "<hfsm.schema.json>", "exec"), scope)
        compiled: Callable[[Any], Any] = scope[name.group(1)]
        compiled({"hfsm": 1, "name": "m", "initial": "A", "states": {"A": None}})
    except Exception:  # pragma: no cover - not the code this was written for
        return None
    try:
        compiled({"hfsm": 1, "name": "m", "initial": "A", "states": {"A": None}, "imports": ("m",)})
    except fastjsonschema.JsonSchemaException:
        return compiled
    return None  # pragma: no cover


def surely_valid(data: Any) -> bool:
    """True when the compiled validator accepts ``data``: jsonschema would too."""
    fast = _fast_validator()
    if fast is None:
        return False  # pragma: no cover
    try:
        fast(data)
    except (fastjsonschema.JsonSchemaException, RecursionError, TypeError, ValueError):
        return False
    return True


def validate(doc: Document, diags: Diagnostics) -> None:
    """Add a diagnostic for every schema violation of ``doc``."""
    found = Diagnostics()
    misplaced = _keys_named_as_states(doc, found)
    errors = () if surely_valid(doc.data) else _validator().iter_errors(doc.data)
    for err in errors:
        if misplaced and any(tuple(err.absolute_path)[:len(p)] == p for p in misplaced):
            continue  # E107 said why: a key indented as a state
        _report(doc, err, found)
    # jsonschema raises one `required` error per missing key; each report names all of them.
    seen: set[tuple[str, str, object]] = set()
    for d in found:
        if (d.code, d.message, d.span) not in seen:
            seen.add((d.code, d.message, d.span))
            diags.items.append(d)


def _describe(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "nothing"}[value]
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, str):
        return f"the string {value!r}" if len(value) < 40 else "a string"
    return f"the number {value!r}"


def _expected(types: str | Iterable[str]) -> str:
    names = [types] if isinstance(types, str) else list(types)
    words = [_TYPE_NAMES.get(t, t) for t in names if t != "null"] or ["nothing"]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _field(path: PathKey) -> str:
    named = [p for p in path if isinstance(p, str)]
    return f"`{named[-1]}`" if named else "the document"


def _report(doc: Document, err: ValidationError, diags: Diagnostics) -> None:
    path: PathKey = tuple(err.absolute_path)
    instance: Any = err.instance
    schema = err.schema if isinstance(err.schema, dict) else {}
    v = err.validator
    if v in ("anyOf", "oneOf") and err.context:
        _report(doc, best_match(err.context), diags)
        return
    if "x-error" in schema and v not in ("type", "required", "additionalProperties"):
        code = schema.get("x-code", "E103")
        span = doc.span(path)
        if "propertyNames" in err.schema_path:  # the offending value is a key of `path`
            span = doc.key_span((*path, str(instance)))
        message = schema["x-error"].format(value=_shown(instance))
        if path == ("hfsm",):
            code = "E104"
            if isinstance(instance, str):
                message = f"`hfsm` must be the number 1, not the string {instance!r}"
        diags.error(code, message, span)
        return
    if v == "additionalProperties":
        allowed = list((err.schema.get("properties") or {}).keys())  # type: ignore[union-attr]
        for key in instance:
            if key in allowed:
                continue
            note = did_you_mean(key, allowed)
            notes: tuple[str, ...] = (note,) if note else (f"allowed here: {', '.join(allowed)}",)
            if not str(key).isidentifier() and doc.format == "yaml":
                # `{to: B, when: max(a, b) > 1}`: the comma ended the value
                notes = (*notes, "code cut here? inside `{...}` a `,` ends a value: quote code "
                         "that holds a comma (docs/quoting.md)")
            diags.error("E100", f"unknown key `{key}`", doc.key_span((*path, key)), *notes)
        return
    if v == "propertyNames":
        # err.instance is the offending key itself; report the sub-error at the key.
        sub = err.context[0] if err.context else None
        sub_schema = sub.schema if sub is not None and isinstance(sub.schema, dict) else {}
        code = sub_schema.get("x-code", "E103")
        msg = sub_schema.get("x-error", "invalid name `{value}`").format(value=_shown(err.instance))
        diags.error(code, msg, doc.key_span((*path, str(instance))))
        return
    if v == "required":
        for key in err.validator_value:  # type: ignore[union-attr]
            if key not in instance:
                _missing(doc, path, key, instance, diags)
        return
    if v == "type":
        code = "E101"
        if path == ("hfsm",):
            code = "E104"
        expected = _expected(err.validator_value)  # type: ignore[arg-type]
        if instance is None and path and isinstance(path[-1], str):
            # `when:` with nothing after it: the value's position would be the next line
            diags.error(code, f"`{path[-1]}` is empty: it must be {expected}", doc.key_span(path))
            return
        if schema.get("x-code") == "E110" and isinstance(instance, float):
            diags.error("E110", f"`{instance}` is not a duration: a number with a fraction has no "
                        "unit", doc.span(path), *_seconds_hint(instance))
            return
        hint: tuple[str, ...] = ()
        if isinstance(instance, dict) and path and path[-1] == "transitions":
            hint = ("each transition is a list item: start it with `- ` (`- to: B`)",)
        if isinstance(instance, (dict, list)) and snippet_kind(path) is not None:
            opener = "{" if isinstance(instance, dict) else "["
            hint = (f"code starting with `{opener}` is read as a YAML {_describe(instance)[2:]}: "
                    "quote it or write it as a block (`|`), see docs/quoting.md",)
        diags.error(code, f"{_field(path)} must be {expected}, not {_describe(err.instance)}",
                    doc.span(path), *hint)
        return
    if v == "enum":
        allowed = [str(x) for x in err.validator_value]  # type: ignore[union-attr]
        note = did_you_mean(str(err.instance), allowed)
        diags.error("E103", f"{_field(path)} must be one of {', '.join(allowed)}; "
                    f"not {_describe(err.instance)}", doc.span(path), *((note,) if note else ()))
        return
    if v == "const":
        code = "E104" if path == ("hfsm",) else "E103"
        diags.error(code, f"{_field(path)} must be {err.validator_value!r}", doc.span(path))
        return
    if v in ("minProperties", "minItems", "minLength"):
        diags.error("E103", f"{_field(path)} must not be empty", doc.span(path))
        return
    diags.error("E103", f"{_field(path)}: {err.message}", doc.span(path))


def _missing(doc: Document, path: PathKey, key: str, instance: Any, diags: Diagnostics) -> None:
    """A missing required key, at the key that names the mapping; for the root, at its
    first key (line 1 may be a comment), with the states to choose from for `initial`."""
    span = doc.key_span(path) if path else doc.span(())
    notes: tuple[str, ...] = ()
    if not path and isinstance(instance, dict) and instance:
        span = doc.key_span(("states",)) if doc.format == "xml" else doc.key_span((next(iter(instance)),))
        states = instance.get("states")
        if key == "initial" and isinstance(states, dict) and states:
            notes = (f"its states: {', '.join(str(s) for s in states)}",)
    diags.error("E102", f"missing required key `{key}` in {_field(path)}", span, *notes)


def _seconds_hint(value: float) -> tuple[str, ...]:
    """`period: 0.1` probably means 0.1 seconds: suggest `100ms`."""
    try:
        us = Fraction(str(value)) * 1_000_000
    except (ValueError, OverflowError):
        return ("write 250ms, 2s, 1.5s or 2m",)
    if us.denominator != 1 or not 0 < us <= MAX_US:
        return ("write 250ms, 2s, 1.5s or 2m",)
    return (f"if it means seconds, write `{format_us(int(us))}`",)


# The keys of a state (schemas/hfsm.schema.json); a state named like one is a key indented wrongly.
STATE_KEYS = ("transitions", "entry", "during", "exit", "initial", "period", "states", "history",
              "final")


def _keys_named_as_states(doc: Document, diags: Diagnostics) -> list[PathKey]:
    """E107 for a state named like a state key whose value is no state (W213 when it
    is one); the paths of the E107 ones, whose schema errors would only confuse."""
    out: list[PathKey] = []
    data = doc.data
    if doc.format != "yaml":  # XML and legacy files name their states in attributes
        return out
    todo: list[tuple[PathKey, Any]] = [(("states",), data.get("states") if isinstance(data, dict) else None)]
    while todo:
        path, states = todo.pop()
        if not isinstance(states, dict):
            continue
        names = list(states)
        for i, name in enumerate(names):
            value = states[name]
            sp = (*path, name)
            if isinstance(value, dict):
                todo.append(((*sp, "states"), value.get("states")))
            if name not in STATE_KEYS:
                continue
            owner = "/".join(str(p) for p in path[1::2]) or "the root"
            where = f"`{owner}`" if path[1:] else owner
            note = _indent_note(doc, path, states, names[i - 1] if i else None, name)
            if value is None or (isinstance(value, dict) and set(value) <= set(STATE_KEYS) | {"description"}):
                diags.warning("W213", f"a state named `{name}`, like the state key: is it a key "
                              "indented too little?", doc.key_span(sp), note)
                continue
            out.append(sp)
            diags.error("E107", f"`{name}` is read as the name of a state of {where}, so the key "
                        f"`{name}` is probably indented too little", doc.key_span(sp), note)
    return out


def _indent_note(doc: Document, path: PathKey, states: dict[str, Any], previous: str | None,
                 name: str) -> str:
    """Where the key would belong: under the keys of the state written before it."""
    if previous is None:
        return "a state's keys are indented under the state's name"
    value = states[previous]
    first = next(iter(value), None) if isinstance(value, dict) else None
    if first is not None:
        col = doc.key_span((*path, previous, first)).col
        return f"to make it a key of `{previous}`, start `{name}` at column {col}, under `{first}`"
    return f"to make it a key of `{previous}`, indent it under `{previous}`"
