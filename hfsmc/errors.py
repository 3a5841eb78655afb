"""Source positions, diagnostics and the one error tree of hfsmc.

Every problem hfsmc finds in a model is a :class:`Diagnostic` with a
:class:`Span` (file, 1-based line and column).  Stages collect diagnostics in a
:class:`Diagnostics` bag so that all problems of a model are reported in one
run; a stage that cannot go on raises the matching :class:`HfsmcError`
subclass carrying everything collected so far.
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Literal, NoReturn

Severity = Literal["error", "warning"]

# Every diagnostic code hfsmc emits, with a one-line summary (docs and tests use it).
CODES: dict[str, str] = {
    # reading the file
    "E001": "the file cannot be read (missing, empty, binary, not UTF-8, too large)",
    "E002": "syntax error in the YAML or XML document",
    "E003": "duplicate key in a YAML mapping, or a repeated XML element",
    "E004": "forbidden XML construct (DOCTYPE, entity, XInclude, processing instruction)",
    "E005": "not an hfsm document (unknown root element or top-level shape)",
    "E006": "the model nests deeper than hfsmc accepts",
    # schema
    "E100": "unknown key",
    "E101": "wrong type",
    "E102": "missing required key",
    "E103": "invalid value",
    "E104": "unsupported format version",
    "E105": "YAML tag, anchor or alias at the start of a code snippet (quote the snippet)",
    "E106": "YAML tag that hfsmc does not define",
    "E107": "a state named like a state key (`transitions`, `entry`...): the key is indented wrongly",
    # durations and periods
    "E110": "malformed duration",
    "E111": "period not a whole number of milliseconds, or below 1 ms",
    # names and structure
    "E120": "not an identifier",
    "E121": "duplicate name",
    "E122": "name used for two kinds of things",
    "E123": "name reserved for generated code (starts with `_hfsm`)",
    "E124": "variable, parameter or interface named with a reserved word of the snippet language",
    "E130": "sub-automaton without initial state",
    "E131": "initial state is not a child of this sub-automaton",
    "E132": "transition to an unknown state",
    "E133": "transition to a state that is not a sibling",
    "E134": "transition out of a final state",
    "E135": "final state with a sub-automaton",
    "E136": "on_interrupt is not a state of the root sub-automaton",
    "E137": "transition without `when` or `after`",
    "E138": "initial, period or history without states",
    "E139": "interrupt_timeout without on_interrupt",
    # parallel regions (docs/semantics.md: regions)
    "E160": "a state with both `states` and `regions`",
    "E161": "a state with a single region",
    "E162": "transition from one region to another",
    # sub-automata from other files (docs/model.md: use)
    "E170": "used file does not exist",
    "E171": "used file cannot be read",
    "E172": "used file is not an hfsm model (a legacy file, another kind of document)",
    "E173": "used file is a model of another language",
    "E174": "used model has on_interrupt, interrupt_timeout, time_limit or on_shutdown",
    "E175": "`use` cycle",
    "E176": "`use` together with states, regions, initial, period or history",
    "E177": "`with` names neither a parameter nor an interface of the used model",
    "E178": "`with` gives a parameter a literal of the wrong type",
    "E179": "`with` binds a parameter to `$NAME`, and the using model has no parameter NAME",
    "E180": "`with` binds a parameter to a parameter of another type",
    "E181": "`with` binds an interface to a name that is not an interface of the using model",
    "E182": "`with` binds an interface to an interface of another type",
    "E183": "interface of the used model left unbound, and the using model has none of that name and type",
    "E184": "`with` without `use`",
    # scenario files (hfsmc test, docs/testing.md)
    "E190": "unknown key in a scenario file",
    "E191": "wrong type of a value in a scenario file",
    "E192": "missing key in a scenario file",
    "E193": "invalid value in a scenario file (a time without unit, a span that ends before it starts...)",
    "E194": "a scenario's model does not exist, or is not of the language given",
    "E195": "a scenario scripts an interface, or a value, the model does not have",
    "E196": "a scenario sets a parameter the model does not have, or with a value of another type",
    "E197": "a scenario expects a state the model does not have",
    "E198": "a file a scenario names (image, trace) does not exist or cannot be read",
    "E199": "a scenario expects a command the interface does not have",
    # ROS 2 messages (docs/ros2.md)
    "E310": "unknown ROS 2 message type (not in the distro nor in the model's .msg files)",
    "E311": "a .msg file that does not parse or names an unknown type",
    "E312": "a ros2 interface's keys misused (a key of another interface type, two distros)",
    "E313": "a ROS 2 name that ROS 2 forbids (topic, namespace, node)",
    "E314": "one ROS 2 topic used with two message types",
    "E315": "a ros2 interface's .msg file outside the model's folder, missing or unreadable",
    "E316": "unknown ROS 2 service or action type, or one of the wrong kind",
    # snippets
    "E140": "syntax error in a Python snippet",
    "E141": "undefined name in a Python snippet",
    "E142": "assignment to a parameter",
    "E143": "malformed import",
    "E144": "C++ compiler error in a snippet (hfsmc check, build --compile)",
    "E145": "`goto` called as a method in a C++ snippet: the method is `go_to`",
    "E146": "active() with a literal path that names no state",
    "E147": "bracket left open or closed without opening in a C++ snippet",
    "E148": "an interface has no such method or attribute (a Python snippet)",
    "E149": "an interface method called with arguments its parameters do not take (a Python snippet)",
    # output
    "E150": "output cannot be written (a value the output format cannot hold, a failing tool)",
    # warnings
    "W201": "unreachable state",
    "W202": "state with no way out that is not final",
    "W203": "transition shadowed by an earlier one that always fires first",
    "W204": "on_interrupt state can never reach a final state",
    # legacy VisualStates / VisualHFSM imports (docs/legacy.md)
    "W205": "legacy ROS topic or ICE interface kept as an interface components cannot drive",
    "W206": "legacy name changed to make it a unique identifier (references follow)",
    "W207": "legacy content not carried over",
    "W208": "legacy file inconsistent or ambiguous: how hfsmc reads it is stated",
    "W209": "C++ compiler warning in a snippet (hfsmc check, build --compile)",
    "W210": "yes/no/on/off/y/n read as a string (YAML 1.2), not as a boolean",
    "W211": "integer with a leading zero read as decimal (YAML 1.2), not octal",
    "W212": "duration written without a unit: a bare number means milliseconds",
    "W213": "a state named like a state key (`final`, `history`...): maybe a key indented wrongly",
    "W215": "done() in a state without a sub-automaton: always false",
    "W216": "time_limit without on_interrupt: the time limit stops the component where it is",
    "W220": "legacy code problem that `convert` carries into the new model (fix it there)",
    "W221": "legacy ROS 1 call with no ROS 2 equivalent: replaced by an hfsmc helper, or named",
}


@dataclass(frozen=True, slots=True, order=True)
class Span:
    """A position in a model file: 1-based line and column."""

    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


@dataclass(frozen=True, slots=True)
class Diagnostic:
    code: str
    message: str
    span: Span
    severity: Severity = "error"
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        return {
            "file": self.span.file,
            "line": self.span.line,
            "col": self.span.col,
            "severity": self.severity,
            "code": self.code,
            "message": self.message,
            "notes": list(self.notes),
        }


@dataclass
class Diagnostics:
    """An ordered bag of diagnostics, shared by the stages of one model."""

    items: list[Diagnostic] = field(default_factory=list)

    def error(self, code: str, message: str, span: Span, *notes: str) -> None:
        self.items.append(Diagnostic(code, message, span, "error", notes))

    def warning(self, code: str, message: str, span: Span, *notes: str) -> None:
        self.items.append(Diagnostic(code, message, span, "warning", notes))

    def extend(self, other: Iterable[Diagnostic]) -> None:
        self.items.extend(other)

    @property
    def has_errors(self) -> bool:
        return any(d.severity == "error" for d in self.items)

    def __iter__(self) -> Iterator[Diagnostic]:
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)

    def sorted(self) -> list[Diagnostic]:
        return sorted(self.items, key=lambda d: (d.span, d.code))


class HfsmcError(Exception):
    """Base of every error hfsmc reports to a user (never shown as a traceback)."""

    def __init__(self, diagnostics: Iterable[Diagnostic]) -> None:
        self.diagnostics = list(diagnostics)
        first = self.diagnostics[0] if self.diagnostics else None
        super().__init__(f"{first.span}: {first.message}" if first else "hfsmc error")


class ParseError(HfsmcError):
    """The file could not be read as YAML or XML."""


class SchemaError(HfsmcError):
    """The document does not follow the model schema."""


class CheckError(HfsmcError):
    """The model is well formed but wrong (names, targets, snippets)."""


class EmitError(HfsmcError):
    """Output could not be written."""


class UsageError(Exception):
    """Bad command-line use (exit status 2)."""


def fail(cls: type[HfsmcError], code: str, message: str, span: Span, *notes: str) -> NoReturn:
    """Raise ``cls`` with a single positioned diagnostic; never returns."""
    raise cls([Diagnostic(code, message, span, "error", notes)])


def did_you_mean(word: str, choices: Iterable[str]) -> str | None:
    """A "did you mean" note for a misspelt ``word``, or None."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f"did you mean `{close[0]}`?" if close else None


# ---------------------------------------------------------------------------
# rendering


def _source_line(lines: dict[str, list[str]], span: Span) -> str | None:
    text = lines.get(span.file)
    if text is None or not 1 <= span.line <= len(text):
        return None
    return text[span.line - 1]


def render_text(diags: Iterable[Diagnostic], sources: dict[str, list[str]], color: bool = False) -> str:
    """Compiler-style text: ``file:line:col: error[E101]: message``, source line, caret."""
    out: list[str] = []
    for d in diags:
        sev = d.severity
        if color:
            tint = "\x1b[1;31m" if sev == "error" else "\x1b[1;35m"
            head = f"\x1b[1m{d.span}:\x1b[0m {tint}{sev}[{d.code}]:\x1b[0m \x1b[1m{d.message}\x1b[0m"
        else:
            head = f"{d.span}: {sev}[{d.code}]: {d.message}"
        out.append(head)
        line = _source_line(sources, d.span)
        if line is not None:
            # one character per column, so the caret stays under it; no raw control bytes
            shown = "".join(ch if ch >= " " or ch == "\t" else "\ufffd" for ch in line)
            shown = shown.expandtabs(1)
            if len(shown) > 200:
                shown = shown[:200] + "..."
            out.append(f"  {shown}")
            out.append("  " + " " * max(0, min(d.span.col - 1, len(shown))) + "^")
        out.extend(f"  note: {n}" for n in d.notes)
    return "\n".join(out) + ("\n" if out else "")


def render_json(diags: Iterable[Diagnostic]) -> str:
    return json.dumps([d.as_dict() for d in diags], indent=2) + "\n"
