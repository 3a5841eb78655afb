"""What each interface type offers snippets: the one description of a driver (docs/drivers.md).

A driver is described once, in the file that implements it, and read here without
running it, so that ``hfsmc check`` knows each method's name and parameters (and which
argument names a key of the interface's options), the scenario files know which methods
are commands, and the recording knows the snapshot's fields:

- the built-in Python drivers (``templates/python/hfsmc_mavlink.py``, ``hfsmc_camera.py``):
  one class deriving from the driver base (``Driver``: mavlink's ``VehicleQueries``, below
  its live ``Vehicle``; the camera's ``Camera``), read as a user's driver is, below (its
  KIND is the built-in type; the declaration block of its C++ header, ``hfsmc/KIND.hpp``,
  too); each is its own fake (``Driver.fake``);
- a user's Python driver (``type: driver``, ``python: FILE``): one class deriving from
  ``Driver`` (templates/python/hfsmc_driver.py) whose methods are marked ``@query`` or
  ``@command`` and whose ``KIND``, ``SNAPSHOT`` and ``OPTIONS`` are literals; read with
  :mod:`ast` (never imported: a driver is code, and imports its device's library);
- a user's C++ driver (``cpp: FILE``): the declaration block at the top of its header,
  ``/* hfsmc driver`` ... ``*/``, a few lines of YAML (a header cannot be read reliably
  without a compiler; the block is read by hfsmc and by the reader of the header alike).

The C++ headers, the docs' tables and the scenario fakes of the built-in drivers are
compared with this in tests/test_drivers_api.py.
"""

from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass, field
from functools import cache
from importlib.resources import files
from typing import Any

# Interface type -> (driver file, its class on the driver base, the live class).
SOURCES: dict[str, tuple[str, str, str]] = {
    "mavlink": ("hfsmc_mavlink.py", "VehicleQueries", "Vehicle"),
    "camera": ("hfsmc_camera.py", "Camera", "Camera"),
}
# Types a user's driver may not take as its KIND: the built-in ones and the model keys.
RESERVED_KINDS = frozenset({"mavlink", "camera", "ros2", "ros_topic", "ice", "driver"})
# Methods of a user's driver that belong to the runtime (hfsmc_driver.Driver's protocol).
DRIVER_PROTOCOL = frozenset({"open", "read", "close", "snapshot", "apply", "send",
                             "warning_at_stop", "value", "say", "start_thread", "connect",
                             "fake", "snapshot_schema", "view_fields", "tell", "read_options",
                             "wait", "now", "tell_down", "tell_up", "keep_connected",
                             "hold_image", "image", "lockstep_sent", "lockstep_sync", "names",
                             "stopping", "attribute"})
# Of those, the ones a driver may also give snippets (``PUBLIC``; check knows them).
PUBLIC_PROTOCOL = frozenset({"close", "warning_at_stop"})
# Plain attributes every driver has (C++: the methods name() and url()).
ATTRIBUTES = ("name", "url")
# C++ names that differ from the Python ones (`goto` is a C++ keyword).
CPP_NAMES = {"goto": "go_to"}
_KIND = re.compile(r"^[a-z][a-z0-9_]*$")
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class DeclarationError(Exception):
    """A driver's declaration that cannot be read: its 1-based line and column in the file."""

    def __init__(self, message: str, line: int = 1, col: int = 1) -> None:
        super().__init__(message)
        self.message, self.line, self.col = message, line, col


@dataclass(frozen=True, slots=True)
class Method:
    """One method a snippet may call on an interface."""

    name: str
    params: tuple[str, ...]  # positional-or-keyword parameters, without self
    required: int  # how many of them have no default
    command: bool  # sends something (recorded); else a query of the instant's snapshot
    acknowledged: bool  # a command whose outcome ``last_ack`` gives (``@command(ack=True)``)
    doc: str  # the first line of its docstring
    # (parameter, option): a literal argument must be a key of that option's names
    names: tuple[tuple[str, str], ...] = ()

    def signature(self) -> str:
        return f"{self.name}({', '.join(self.params)})"


@dataclass(frozen=True, slots=True)
class Driver:
    """The methods and attributes of one interface type."""

    type: str
    methods: dict[str, Method]  # in the driver's order
    # A user's driver only: the snapshot's fields and their "nothing yet" values, the
    # options and their defaults, the class (Python) or the C++ class, its docstring.
    snapshot: tuple[tuple[str, Any], ...] = ()
    options: tuple[tuple[str, Any], ...] = ()
    cls: str = ""
    doc: str = ""
    attributes_from: tuple[str, ...] = field(default=())  # options whose names are attributes

    @property
    def commands(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.methods.values() if m.command)

    @property
    def acknowledged(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.methods.values() if m.acknowledged)

    @property
    def names(self) -> tuple[str, ...]:
        """Everything ``interface.X`` may name."""
        return (*self.methods, *ATTRIBUTES)


# The ros2 interface (templates/python/hfsmc_ros2.py, docs/ros2.md): its methods are read
# from the class snippets call, as for the other built-in drivers; what the runtime's
# declaration cannot say in Python is here: which argument names a subscription or a
# publication, and that each subscription is an attribute (`robot.scan`).
ROS2_SOURCE = ("hfsmc_ros2.py", "Ros2Queries")
ROS2_NAMES = {"age": (("name", "subscribe"),), "count": (("name", "subscribe"),),
              "publishers": (("name", "subscribe"),), "subscribers": (("name", "publish"),),
              "publish": (("name", "publish"),),
              **dict.fromkeys(("send_goal", "cancel", "goal_status", "feedback", "result"),
                              (("name", "actions"),)),
              **dict.fromkeys(("call", "call_status", "response"), (("name", "services"),))}
ROS2_COMMANDS = frozenset({"publish", "send_goal", "cancel", "call"})


@cache
def driver(kind: str) -> Driver | None:
    """The built-in driver of interface type ``kind``; None for a type without one (a
    legacy ROS topic or ICE interface, which components cannot drive; a user's driver,
    which the interface itself carries: ``Interface.declaration``)."""
    if kind == "ros2":
        return _ros2_driver()
    source = SOURCES.get(kind)
    if source is None:
        return None
    text = files("hfsmc.templates").joinpath("python").joinpath(source[0]).read_text("utf-8")
    return read_python_driver(text, kind)  # declared as a user's driver is


def _ros2_driver() -> Driver:
    file, queries = ROS2_SOURCE
    text = files("hfsmc.templates").joinpath("python").joinpath(file).read_text("utf-8")
    cls = next(n for n in ast.parse(text).body if isinstance(n, ast.ClassDef)
               and n.name == queries)
    methods: dict[str, Method] = {}
    for node in cls.body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            m = _method(node)
            methods[node.name] = Method(m.name, m.params, m.required,
                                        node.name in ROS2_COMMANDS, False, m.doc,
                                        ROS2_NAMES.get(node.name, ()))
    return Driver("ros2", methods, attributes_from=("subscribe",))


def _method(node: ast.FunctionDef) -> Method:
    params = tuple(a.arg for a in (*node.args.posonlyargs, *node.args.args))[1:]  # no self
    calls = [n for n in ast.walk(node) if isinstance(n, ast.Call)
             and isinstance(n.func, ast.Attribute) and n.func.attr == "_issue"]
    acked = any(k.arg == "ack" and isinstance(k.value, ast.Constant) and k.value.value is True
                for c in calls for k in c.keywords)
    doc = (ast.get_docstring(node) or "").split("\n")[0]
    return Method(node.name, params, len(params) - len(node.args.defaults), bool(calls), acked,
                  doc)


# --- a user's Python driver -------------------------------------------------------------

@cache
def read_python_driver(text: str, builtin: str | None = None) -> Driver:
    """The declaration of a user's Python driver (docs/drivers.md); DeclarationError with
    its position when it is not one. ``builtin``: the interface type of a built-in driver
    declared the same way (``hfsmc_mavlink.VehicleQueries``), whose KIND it is."""
    try:
        tree = ast.parse(text)
    except SyntaxError as e:
        raise DeclarationError(f"not Python: {e.msg}", e.lineno or 1, e.offset or 1) from None
    found = [n for n in tree.body if isinstance(n, ast.ClassDef)
             and any(_base_name(b) == "Driver" for b in n.bases)]
    if len(found) != 1:
        raise DeclarationError("a Python driver defines exactly one class deriving from "
                               f"`Driver` (hfsmc_driver.Driver); found {len(found)}")
    cls = found[0]
    consts: dict[str, tuple[Any, ast.AST]] = {}
    for node in cls.body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name)):
            consts[node.targets[0].id] = (node.value, node)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value:
            consts[node.target.id] = (node.value, node)
    kind = _const(consts, "KIND", cls)
    if not isinstance(kind, str) or not _KIND.match(kind) or (kind in RESERVED_KINDS
                                                              and kind != builtin):
        raise DeclarationError(f"`KIND` must be a lower-case name (a-z, 0-9, _), not one of "
                               f"{', '.join(sorted(RESERVED_KINDS))}: `{kind}`",
                               *_at(consts["KIND"][1]))
    snapshot = _mapping(consts, "SNAPSHOT", cls)
    options = _mapping(consts, "OPTIONS", cls, required=False)
    attrs = _const(consts, "ATTRIBUTES_FROM", cls, ())
    if not (isinstance(attrs, tuple) and all(isinstance(a, str) and a in options for a in attrs)):
        raise DeclarationError("`ATTRIBUTES_FROM` must be a tuple of option names",
                               *_at(consts["ATTRIBUTES_FROM"][1]))
    public = _const(consts, "PUBLIC", cls, ())
    if not (isinstance(public, tuple) and all(p in PUBLIC_PROTOCOL for p in public)):
        raise DeclarationError("`PUBLIC` must be a tuple of the runtime's methods a snippet "
                               f"may call: {', '.join(sorted(PUBLIC_PROTOCOL))}",
                               *_at(consts["PUBLIC"][1]))
    frames = _const(consts, "FRAMES", cls, "")
    if not isinstance(frames, str) or (frames and frames not in snapshot):
        raise DeclarationError("`FRAMES` must name the snapshot field that numbers the "
                               "images", *_at(consts["FRAMES"][1]))
    readable = frozenset(snapshot) | ({"frame"} if frames else frozenset())
    methods: dict[str, Method] = {}
    for node in cls.body:
        if not isinstance(node, ast.FunctionDef):
            continue
        marks = [d for d in node.decorator_list if _base_name(d) in ("query", "command")]
        if not marks and node.name in public:  # a runtime method snippets may call too
            methods[node.name] = _public(node)
        if not marks:
            continue
        if node.name.startswith("_") or node.name in DRIVER_PROTOCOL or node.name in ATTRIBUTES:
            raise DeclarationError(f"`{node.name}` cannot be a query or a command: the name "
                                   "is the runtime's", *_at(node))
        mark = marks[0]
        names = _names(mark, node, options, readable)
        params = tuple(a.arg for a in (*node.args.posonlyargs, *node.args.args))[1:]
        if node.args.vararg or node.args.kwarg or node.args.kwonlyargs:
            raise DeclarationError(f"`{node.name}`: a query or a command takes plain "
                                   "parameters (no *args, **kwargs or keyword-only ones)",
                                   *_at(node))
        doc = (ast.get_docstring(node) or "").split("\n")[0]
        methods[node.name] = Method(node.name, params, len(params) - len(node.args.defaults),
                                    _base_name(mark) == "command", _flag(mark, "ack"), doc,
                                    names)
    for name in public:  # the base class's (hfsmc_driver.Driver): no parameters
        methods.setdefault(name, Method(name, (), 0, False, False, ""))
    if not methods:
        raise DeclarationError(f"`{cls.name}` marks no method `@query` or `@command`",
                               *_at(cls))
    return Driver(kind, methods, tuple(snapshot.items()), tuple(options.items()), cls.name,
                  (ast.get_docstring(cls) or "").split("\n")[0], attrs)


def _base_name(node: ast.AST) -> str:
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def _at(node: ast.AST) -> tuple[int, int]:
    return getattr(node, "lineno", 1), getattr(node, "col_offset", 0) + 1


_MISSING = object()


def _const(consts: dict[str, tuple[Any, ast.AST]], key: str, cls: ast.ClassDef,
           default: Any = _MISSING) -> Any:
    if key not in consts:
        if default is _MISSING:
            raise DeclarationError(f"`{cls.name}` has no `{key}`", *_at(cls))
        return default
    node, where = consts[key]
    try:
        return literal(node)
    except ValueError as e:
        raise DeclarationError(f"`{key}`: {e}", *_at(where)) from None


def _mapping(consts: dict[str, tuple[Any, ast.AST]], key: str, cls: ast.ClassDef,
             required: bool = True) -> dict[str, Any]:
    value = _const(consts, key, cls, _MISSING if required else {})
    if not isinstance(value, dict) or not all(isinstance(k, str) and _IDENT.match(k)
                                              for k in value):
        raise DeclarationError(f"`{key}` must map names to their default values",
                               *_at(consts[key][1]))
    return value


def literal(node: ast.AST) -> Any:
    """A literal as Python reads it, with ``float("inf")``, ``math.inf`` and ``math.nan``
    too (a snapshot's "nothing yet" is often infinity); ValueError for anything else."""
    if isinstance(node, ast.Call) and _base_name(node.func) == "float" and len(node.args) == 1 \
            and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
        return float(node.args[0].value)
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
            and node.value.id == "math" and node.attr in ("inf", "nan"):
        return getattr(math, node.attr)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        value = literal(node.operand)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return -value
    if isinstance(node, ast.Dict):
        return {literal(k) if k is not None else None: literal(v)
                for k, v in zip(node.keys, node.values, strict=True)}
    if isinstance(node, (ast.Tuple, ast.List)):
        return tuple(literal(e) for e in node.elts)
    if isinstance(node, ast.Constant) and isinstance(node.value, (str, int, float, bool,
                                                                  type(None))):
        return node.value
    raise ValueError("write a literal (numbers, strings, true/false, None, tuples, dicts, "
                     "float(\"inf\"))")


def _public(node: ast.FunctionDef) -> Method:
    params = tuple(a.arg for a in (*node.args.posonlyargs, *node.args.args))[1:]
    return Method(node.name, params, len(params) - len(node.args.defaults), False, False,
                  (ast.get_docstring(node) or "").split("\n")[0])


def _flag(mark: ast.AST, key: str) -> bool:
    """``@command(ack=True)``: a literal true keyword of the mark."""
    return isinstance(mark, ast.Call) and any(
        k.arg == key and isinstance(k.value, ast.Constant) and k.value.value is True
        for k in mark.keywords)


# The keywords of the marks besides ``names`` (hfsmc_driver.query and command).
_MARK_KEYWORDS = {"query": ("reads",), "command": ("ack", "checked")}


def _names(mark: ast.AST, node: ast.FunctionDef, options: dict[str, Any],
           fields: frozenset[str]) -> tuple[tuple[str, str], ...]:
    """A mark's ``names=`` (its other keywords checked); ``fields``: what ``reads=`` may name."""
    if not isinstance(mark, ast.Call):
        return ()
    params = {a.arg for a in node.args.args}
    kind = _base_name(mark)
    found: tuple[tuple[str, str], ...] = ()
    for k in mark.keywords:
        if k.arg in _MARK_KEYWORDS[kind]:
            value = k.value.value if isinstance(k.value, ast.Constant) else None
            good = value in fields if k.arg == "reads" else isinstance(value, bool)
            if not good:
                raise DeclarationError(f"`{k.arg}` must be " + (
                    "a field of `SNAPSHOT` (or `frame`: the image of a driver with `FRAMES`)"
                    if k.arg == "reads" else "True or False"), *_at(mark))
            continue
        if k.arg != "names":
            raise DeclarationError(f"`@{kind}` takes only `names=`"
                                   + "".join(f", `{w}=`" for w in _MARK_KEYWORDS[kind]),
                                   *_at(mark))
        try:
            names = literal(k.value)
        except ValueError as e:
            raise DeclarationError(f"`names`: {e}", *_at(mark)) from None
        if not isinstance(names, dict) or not all(
                p in params and o in options for p, o in names.items()):
            raise DeclarationError("`names` maps a parameter to the option that lists its "
                                   f"names (options: {', '.join(options) or 'none'})", *_at(mark))
        found = tuple(names.items())
    return found


# --- a user's C++ driver ----------------------------------------------------------------

_BLOCK = re.compile(r"/\*\s*hfsmc driver[ \t]*\n(.*?)\*/", re.S)
_SIGNATURE = re.compile(r"^\s*([A-Za-z_]\w*)\s*\(([^()]*)\)\s*(?::\s*(.*))?$")


def read_cpp_driver(text: str, builtin: str | None = None) -> Driver:
    """The declaration block of a user's C++ driver header (docs/drivers.md); ``builtin``:
    the interface type of a built-in driver's header (``hfsmc/mavlink.hpp``)."""
    import yaml  # a C++ declaration block is a few lines of YAML

    m = _BLOCK.search(text)
    if m is None:
        raise DeclarationError("no declaration block: the header starts with "
                               "`/* hfsmc driver` ... `*/` (docs/drivers.md)")
    first = text.count("\n", 0, m.start(1)) + 1
    try:
        data = yaml.safe_load(m.group(1))
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = first + (mark.line if mark is not None else 0)
        raise DeclarationError(f"the declaration block is not YAML: {getattr(e, 'problem', e)}",
                               line) from None
    if not isinstance(data, dict):
        raise DeclarationError("the declaration block is a mapping (kind, class, snapshot, "
                               "options, queries, commands)", first)
    unknown = set(data) - {"kind", "class", "doc", "snapshot", "options", "queries",
                           "commands", "attributes_from"}
    if unknown:
        raise DeclarationError(f"unknown key `{sorted(unknown)[0]}` in the declaration block "
                               "(kind, class, doc, snapshot, options, queries, commands, "
                               "attributes_from)", first)
    kind, cls = data.get("kind"), data.get("class")
    if not isinstance(kind, str) or not _KIND.match(kind) or (kind in RESERVED_KINDS
                                                              and kind != builtin):
        raise DeclarationError(f"`kind` must be a lower-case name, not a built-in type: "
                               f"`{kind}`", first)
    if not isinstance(cls, str) or not re.match(r"^[A-Za-z_][\w:]*$", cls):
        raise DeclarationError("`class` names the driver's C++ class", first)
    snapshot, options = data.get("snapshot") or {}, data.get("options") or {}
    for key, value in (("snapshot", snapshot), ("options", options)):
        if not isinstance(value, dict) or not all(isinstance(k, str) and _IDENT.match(k)
                                                  for k in value):
            raise DeclarationError(f"`{key}` must map names to their default values", first)
    attrs = tuple(data.get("attributes_from") or ())
    methods: dict[str, Method] = {}
    for group, command in (("queries", False), ("commands", True)):
        for entry in data.get(group) or ():
            sig = _SIGNATURE.match(str(entry))
            if sig is None:
                raise DeclarationError(f"`{group}`: `{entry}` is not NAME(PARAM, ...)", first)
            name, raw, doc = sig.group(1), sig.group(2), (sig.group(3) or "").strip()
            params, names = [], []
            for p in (x.strip() for x in raw.split(",") if x.strip()):
                pname, _, option = (s.strip() for s in p.partition(" in "))
                if option and option not in options:
                    raise DeclarationError(f"`{entry}`: no option `{option}`", first)
                params.append(pname)
                if option:
                    names.append((pname, option))
            methods[name] = Method(name, tuple(params), len(params), command, False, doc,
                                   tuple(names))
    if not methods:
        raise DeclarationError("the declaration block lists no queries or commands", first)
    return Driver(kind, methods, tuple(snapshot.items()), tuple(options.items()), cls,
                  str(data.get("doc") or ""), attrs)


def disagreement(py: Driver, cpp: Driver) -> str | None:
    """What a model's Python and C++ drivers of one interface do not agree on (one
    description: the same kind, methods, parameters and snapshot fields), or None."""
    if py.type != cpp.type:
        return f"the Python driver's KIND is `{py.type}`, the C++ one's `{cpp.type}`"
    for name in (*py.methods, *cpp.methods):
        a, b = py.methods.get(name), cpp.methods.get(name)
        if a is None or b is None:
            return f"`{name}` is declared in the {'C++' if a is None else 'Python'} driver only"
        if a.params != b.params or a.command != b.command or a.names != b.names:
            return f"`{name}` differs: Python {a.signature()}, C++ {b.signature()}"
    if [k for k, _ in py.snapshot] != [k for k, _ in cpp.snapshot]:
        return "the snapshot's fields differ"
    if [k for k, _ in py.options] != [k for k, _ in cpp.options]:
        return "the options differ"
    return None


def option_names(value: str) -> tuple[str, ...]:
    """The names an option lists (``"red, green"``, ``"[red, green]"``, ``"red green"``)."""
    return tuple(n for n in re.split(r"[\s,\[\]'\"]+", value) if n)
