"""C++ message types of the ``ros2`` interface, generated from the distro's definitions.

Each ROS 2 message a model uses becomes ``PKG::msg::Name`` in
``include/PKG/msg/snake_name.hpp`` (the path rclcpp code includes), with rclcpp's field
names and C++ types (``std::string``, ``std::vector``, ``std::array``, nested types,
``static constexpr`` constants, zero or ROS 2 defaults), and two free functions found by
argument-dependent lookup, ``cdr_write`` and ``cdr_read``, that put it on the wire as
plain CDR exactly as rosbags (and ROS 2) does: docs/ros2-cpp.md says why the component
writes its CDR itself rather than through IDL compiled by ``idlc``.

Only the types a model names are generated, with the types they contain, and
``rmw_dds_common/msg/ParticipantEntitiesInfo`` that the runtime announces its node with.
The definitions come from a rosbags type store (the distro's standard packages plus the
model's own ``.msg`` files registered into it); the view computed here is all a template
sees, and it only loops and prints.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib.resources import files as resource_files
from typing import Any

import jinja2

from hfsmc.errors import HfsmcError

# rclcpp's C++ type of each ROS 2 primitive (rosidl_generator_cpp), with its size on the wire.
PRIMITIVES: Mapping[str, tuple[str, int]] = {
    "bool": ("bool", 1), "byte": ("uint8_t", 1), "char": ("uint8_t", 1),
    "int8": ("int8_t", 1), "uint8": ("uint8_t", 1), "int16": ("int16_t", 2),
    "uint16": ("uint16_t", 2), "int32": ("int32_t", 4), "uint32": ("uint32_t", 4),
    "int64": ("int64_t", 8), "uint64": ("uint64_t", 8), "float32": ("float", 4),
    "float64": ("double", 8),
}
# What the runtime itself sends on every participant (ros_discovery_info).
RUNTIME_TYPES = ("rmw_dds_common/msg/ParticipantEntitiesInfo",)

_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4  # rosbags' Nodetype values


@dataclass(frozen=True, slots=True)
class FieldView:
    """One member: its declaration and the statements that write and read it."""
    name: str
    decl: str           # `double x = 0.0;`
    write: tuple[str, ...]
    read: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class ConstantView:
    decl: str           # `static constexpr int32_t ARROW = 0;`


@dataclass(frozen=True, slots=True)
class MessageView:
    package: str
    name: str
    ros_type: str       # sensor_msgs/msg/LaserScan
    dds_type: str       # sensor_msgs::msg::dds_::LaserScan_
    type_hash: str      # RIHS01_... (jazzy), "" (humble)
    definition: str     # the ros2msg text (with its dependencies), a C++ literal
    guard_comment: str
    includes: tuple[str, ...]
    fields: tuple[FieldView, ...]
    constants: tuple[ConstantView, ...]


def snake_case(name: str) -> str:
    """rosidl's header name for a message: ``LaserScan`` -> ``laser_scan``,
    ``PointCloud2`` -> ``point_cloud2``, ``TFMessage`` -> ``tf_message``."""
    value = re.sub(r"(.)([A-Z][a-z]+)", r"\1_\2", name)
    return re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", value).lower()


def header_path(ros_type: str) -> str:
    """``geometry_msgs/msg/Twist`` -> ``geometry_msgs/msg/twist.hpp``."""
    package, _, name = ros_type.split("/")
    return f"{package}/msg/{snake_case(name)}.hpp"


def cpp_type_name(ros_type: str) -> str:
    package, _, name = ros_type.split("/")
    return f"{package}::msg::{name}"


def closure(store: Any, names: Iterable[str]) -> list[str]:
    """The types named and every type they contain, dependencies first, each once."""
    out: list[str] = []

    def visit(name: str, path: tuple[str, ...]) -> None:
        if name in out:
            return
        if name not in store.fielddefs:
            raise HfsmcError(f"unknown ROS 2 message type {name!r}")
        for ref in _references(store.fielddefs[name][1]):
            if ref not in path:
                visit(ref, path + (name,))
        out.append(name)

    for name in [*names, *RUNTIME_TYPES]:
        visit(name, ())
    return out


def _references(fields: Iterable[tuple[str, Any]]) -> list[str]:
    refs = []
    for _, (kind, desc) in fields:
        if kind == _NAME:
            refs.append(desc)
        elif kind in (_ARRAY, _SEQUENCE) and desc[0][0] == _NAME:
            refs.append(desc[0][1])
    return refs


def _literal(text: str) -> str:
    """A C++ string literal of ``text`` (ASCII escapes only: json's are valid C++)."""
    return json.dumps(text, ensure_ascii=True)


def _element(kind: int, desc: Any) -> tuple[str, str, int, int]:
    """(C++ type, kind: prim|bool|string|msg, wire size or minimal size, string bound)."""
    if kind == _NAME:
        return cpp_type_name(desc), "msg", 1, 0
    base, bound = desc
    if base == "string":
        return "std::string", "string", 5, bound
    if base == "wstring":
        raise HfsmcError("wstring fields are not supported by the C++ component yet")
    if base == "bool":
        return "bool", "bool", 1, 0
    ctype, size = PRIMITIVES[base]
    return ctype, "prim", size, 0


def _field(name: str, kind: int, desc: Any) -> FieldView:
    m = f"m.{name}"
    if kind in (_BASE, _NAME):
        ctype, ek, _, sbound = _element(kind, desc)
        init = "" if ek in ("msg", "string") else "{}"
        return FieldView(name, f"{ctype} {name}{init};", *_scalar(ek, ctype, m, sbound))
    (ekind, edesc), size = desc
    ctype, ek, wire, sbound = _element(ekind, edesc)
    if kind == _ARRAY:
        decl = f"std::array<{ctype}, {size}> {name}{{}};"
        if ek == "prim":
            return FieldView(name, decl, (f"w.prims({m}.data(), {size});",),
                             (f"r.prims({m}.data(), {size});",))
        w, r = _scalar(ek, ctype, "e", sbound)
        return FieldView(name, decl, (f"for (const auto& e : {m}) {{ {' '.join(w)} }}",),
                         (f"for (auto& e : {m}) {{ {' '.join(r)} }}",))
    if size:
        decl = f"::hfsmc::cdr::BoundedVector<{ctype}, {size}> {name};"
    else:
        decl = f"std::vector<{ctype}> {name};"
    write = [f"w.bound({m}.size(), {size});", f"w.count({m}.size());"]
    read = [f"{{ std::size_t n = r.count({wire}); r.bound(n, {size}); {m}.resize(n);"]
    if ek == "prim":
        write.append(f"w.prims({m}.data(), {m}.size());")
        read.append(f"r.prims({m}.data(), n); }}")
    elif ek == "bool":
        write.append(f"for (bool e : {m}) w.boolean(e);")
        read.append(f"for (std::size_t i = 0; i < n; ++i) {m}[i] = r.boolean(); }}")
    else:
        w, r = _scalar(ek, ctype, "e", sbound)
        write.append(f"for (const auto& e : {m}) {{ {' '.join(w)} }}")
        read.append(f"for (auto& e : {m}) {{ {' '.join(r)} }} }}")
    return FieldView(name, decl, tuple(write), (" ".join(read),))


def _scalar(ek: str, ctype: str, ref: str, sbound: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    if ek == "msg":
        return (f"cdr_write(w, {ref});",), (f"cdr_read(r, {ref});",)
    if ek == "string":
        return (f"w.string({ref}, {sbound});",), (f"r.string({ref}, {sbound});",)
    if ek == "bool":
        return (f"w.boolean({ref});",), (f"{ref} = r.boolean();",)
    return (f"w.prim<{ctype}>({ref});",), (f"{ref} = r.prim<{ctype}>();",)


def _constant(name: str, base: str, value: Any) -> ConstantView:
    if base in ("string", "wstring"):
        return ConstantView(f"static constexpr const char* {name} = {_literal(str(value))};")
    ctype = PRIMITIVES[base][0]
    if base == "bool":
        text = "true" if value else "false"
    elif base in ("float32", "float64"):
        text = repr(float(value))
        text = text if any(c in text for c in ".en") else text + ".0"
        text = {"inf": "std::numeric_limits<double>::infinity()",
                "-inf": "-std::numeric_limits<double>::infinity()",
                "nan": "std::numeric_limits<double>::quiet_NaN()"}.get(text, text)
    elif base.startswith("u") or base in ("byte", "char"):
        text = f"{int(value)}u"
    elif base == "int64":
        text = f"INT64_C({int(value)})"
    else:
        text = str(int(value))
    return ConstantView(f"static constexpr {ctype} {name} = {text};")


def message_view(store: Any, ros_type: str, type_hash: str) -> MessageView:
    """The view of one message type (its definition in ``store``)."""
    package, _, name = ros_type.split("/")
    consts, fields = store.fielddefs[ros_type]
    includes = sorted({header_path(ref) for ref in _references(fields)})
    try:
        definition = store.generate_msgdef(ros_type, ros_version=2)[0]
    except Exception:  # a definition rosbags cannot print back: the recording names the type
        definition = ""
    return MessageView(
        package=package, name=name, ros_type=ros_type,
        dds_type=f"{package}::msg::dds_::{name}_", type_hash=type_hash,
        definition=_literal(definition), guard_comment=ros_type,
        includes=tuple(includes),
        fields=tuple(_field(fname, kind, desc) for fname, (kind, desc) in fields),
        constants=tuple(_constant(c[0], c[1], c[2]) for c in consts))


def cpp_message_files(store: Any, names: Iterable[str], distro: str,
                      model: str = "") -> dict[str, str]:
    """The headers of the types ``names`` (and those they contain), by their path in the
    component folder (``include/geometry_msgs/msg/twist.hpp``). ``distro`` is ``jazzy``
    (the headers carry each type's RIHS01 hash) or ``humble`` (no hash)."""
    template = _environment().get_template("ros2_message.hpp.j2")
    files: dict[str, str] = {}
    for ros_type in closure(store, names):
        type_hash = store.hash_rihs01(ros_type) if distro == "jazzy" else ""
        view = message_view(store, ros_type, type_hash)
        files["include/" + header_path(ros_type)] = template.render(
            m=view, distro=distro, model=model)
    return files


def _environment() -> jinja2.Environment:
    """templates/cpp, as hfsmc.emit.templating makes it (this package sits below emit)."""
    folder = resource_files("hfsmc.templates").joinpath("cpp")
    return jinja2.Environment(
        loader=jinja2.FunctionLoader(lambda name: folder.joinpath(name).read_text("utf-8")),
        undefined=jinja2.StrictUndefined, keep_trailing_newline=True, trim_blocks=True,
        lstrip_blocks=True, autoescape=False)
