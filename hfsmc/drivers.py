"""What each interface type offers snippets, read from its Python driver (docs/interfaces.md).

The Python drivers (``templates/python/hfsmc_mavlink.py``, ``hfsmc_camera.py``) are
the one description of an interface's methods: each has a class of what snippets
call (``VehicleQueries``, ``CameraQueries``, which the playback's test doubles
subclass too) and the live class below it, which adds ``close()``. This module
reads those classes' source with :mod:`ast` (without importing them: the mavlink
driver imports pymavlink, the camera's grabber OpenCV), so that ``hfsmc check``
knows each method's name and parameters and the scenario files know which methods
are commands (those that tell ``self._issue``). The C++ headers, the docs' tables
and the scenario fakes are compared with this in tests/test_drivers_api.py.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from functools import cache
from importlib.resources import files

# Interface type -> (driver file, the snippets' class, the live class).
SOURCES: dict[str, tuple[str, str, str]] = {
    "mavlink": ("hfsmc_mavlink.py", "VehicleQueries", "Vehicle"),
    "camera": ("hfsmc_camera.py", "CameraQueries", "Camera"),
}
# The live class's methods that belong to the runtime, not to snippets.
RUNTIME_ONLY = frozenset({"snapshot", "lockstep_sent", "lockstep_sync"})
# Plain attributes every driver has (C++: the methods name() and url()).
ATTRIBUTES = ("name", "url")
# C++ names that differ from the Python ones (`goto` is a C++ keyword).
CPP_NAMES = {"goto": "go_to"}


@dataclass(frozen=True, slots=True)
class Method:
    """One method a snippet may call on an interface."""

    name: str
    params: tuple[str, ...]  # positional-or-keyword parameters, without self
    required: int  # how many of them have no default
    command: bool  # sends something (tells ``_issue``); else a query or housekeeping
    acknowledged: bool  # a command whose outcome ``last_ack`` gives (``_issue(..., ack=True)``)
    doc: str  # the first line of its docstring

    def signature(self) -> str:
        return f"{self.name}({', '.join(self.params)})"


@dataclass(frozen=True, slots=True)
class Driver:
    """The methods and attributes of one interface type."""

    type: str
    methods: dict[str, Method]  # in the driver's order

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


@cache
def driver(kind: str) -> Driver | None:
    """The driver of interface type ``kind``; None for a type without one (a legacy
    ROS topic or ICE interface, which components cannot drive)."""
    source = SOURCES.get(kind)
    if source is None:
        return None
    file, queries, live = source
    text = files("hfsmc.templates").joinpath("python").joinpath(file).read_text("utf-8")
    classes = {n.name: n for n in ast.parse(text).body if isinstance(n, ast.ClassDef)}
    methods: dict[str, Method] = {}
    for cls, skip in ((classes[queries], frozenset[str]()), (classes[live], RUNTIME_ONLY)):
        for node in cls.body:
            if (isinstance(node, ast.FunctionDef) and not node.name.startswith("_")
                    and node.name not in skip and node.name not in methods):
                methods[node.name] = _method(node)
    return Driver(kind, methods)


def _method(node: ast.FunctionDef) -> Method:
    params = tuple(a.arg for a in (*node.args.posonlyargs, *node.args.args))[1:]  # no self
    calls = [n for n in ast.walk(node) if isinstance(n, ast.Call)
             and isinstance(n.func, ast.Attribute) and n.func.attr == "_issue"]
    acked = any(k.arg == "ack" and isinstance(k.value, ast.Constant) and k.value.value is True
                for c in calls for k in c.keywords)
    doc = (ast.get_docstring(node) or "").split("\n")[0]
    return Method(node.name, params, len(params) - len(node.args.defaults), bool(calls), acked,
                  doc)
