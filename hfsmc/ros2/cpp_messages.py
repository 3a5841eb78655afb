"""C++ message types of the ``ros2`` interface, generated from the neutral definitions.

Each ROS 2 message a model uses becomes ``PKG::msg::Name`` in
``include/PKG/msg/snake_name.hpp`` (the path rclcpp code includes), with rclcpp's field
names and C++ types (``std::string``, ``std::vector``, ``std::array``, bounded sequences,
nested types, ``static constexpr`` constants, ROS 2 defaults as member initialisers), and
two free functions found by argument-dependent lookup, ``cdr_write`` and ``cdr_read``,
that put it on the wire as plain CDR exactly as rosbags (and ROS 2) does: docs/ros2-cpp.md
says why the component writes its CDR itself rather than through IDL compiled by ``idlc``.

The input is a :class:`~hfsmc.ros2.definitions.MessageSet` (the closure of the types a
model uses, dependencies first); the runtime also needs
``rmw_dds_common/msg/ParticipantEntitiesInfo`` (:data:`RUNTIME_TYPES`: a model's message
set is asked with it). The view computed here is all a template sees; it only loops and
prints.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.resources import files as resource_files

import jinja2

from hfsmc.errors import Diagnostic, EmitError, Span
from hfsmc.ros2.definitions import Field, FieldType, Message, MessageSet, Scalar

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


@dataclass(frozen=True, slots=True)
class FieldView:
    """One member: its declaration and the statements that write and read it."""
    name: str
    decl: str           # `double x = 0.0;`
    write: tuple[str, ...]
    read: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class MessageView:
    package: str
    kind: str           # msg, srv (a service's request or response), action
    name: str
    ros_type: str       # sensor_msgs/msg/LaserScan
    dds_type: str       # sensor_msgs::msg::dds_::LaserScan_
    type_hash: str      # RIHS01_... (jazzy), "" (humble)
    definition: str     # the ros2msg text (with its dependencies), a C++ literal
    includes: tuple[str, ...]
    fields: tuple[FieldView, ...]
    constants: tuple[str, ...]  # `static constexpr int32_t ARROW = 0;`


def snake_case(name: str) -> str:
    """rosidl's header name for a message: ``LaserScan`` -> ``laser_scan``,
    ``PointCloud2`` -> ``point_cloud2``, ``TFMessage`` -> ``tf_message``."""
    value = re.sub(r"(.)([A-Z][a-z]+)", r"\1_\2", name)
    return re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", value).lower()


def header_path(ros_type: str) -> str:
    """``geometry_msgs/msg/Twist`` -> ``geometry_msgs/msg/twist.hpp``; a service's or an
    action's message keeps its folder (``std_srvs/srv/trigger__request.hpp``)."""
    package, kind, name = ros_type.split("/")
    return f"{package}/{kind}/{snake_case(name)}.hpp"


def cpp_type_name(ros_type: str) -> str:
    """``geometry_msgs::msg::Twist``, ``std_srvs::srv::Trigger_Request``."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::{name}"


def _literal(text: str) -> str:
    """A C++ string literal of ``text`` (ASCII escapes only: json's are valid C++)."""
    return json.dumps(text, ensure_ascii=True)


def _element(t: FieldType) -> tuple[str, str, int]:
    """(C++ type, kind: prim|bool|string|msg, wire size or the least an element takes)."""
    if t.kind == "nested":
        return cpp_type_name(t.name), "msg", 1
    if t.kind == "string":
        return "std::string", "string", 5
    if t.name == "bool":
        return "bool", "bool", 1
    ctype, size = PRIMITIVES[t.name]
    return ctype, "prim", size


def _value(base: str, value: Scalar) -> str:
    """A C++ literal of a constant's or a default's value."""
    if base in ("string", "wstring"):
        return _literal(str(value))
    if base == "bool":
        return "true" if value else "false"
    if base in ("float32", "float64"):
        v = float(value)
        if math.isnan(v):
            return "std::numeric_limits<double>::quiet_NaN()"
        if math.isinf(v):
            return ("-" if v < 0 else "") + "std::numeric_limits<double>::infinity()"
        text = repr(v)
        return text + ("f" if base == "float32" else "")
    if base.startswith("u") or base in ("byte", "char"):
        return f"{int(value)}u" if base != "uint64" else f"UINT64_C({int(value)})"
    if base == "int64":
        return f"INT64_C({int(value)})"
    return str(int(value))


def _initialiser(f: Field) -> str:
    t = f.type
    if f.default is None:
        return "" if t.kind in ("nested", "string") or t.array in ("bounded", "unbounded") \
            else "{}"
    values = f.default if isinstance(f.default, tuple) else (f.default,)
    items = ", ".join(_value(t.name if t.kind == "primitive" else t.kind, v) for v in values)
    return f"{{{items}}}"


def _field(f: Field) -> FieldView:
    t, name, m = f.type, f.name, f"m.{f.name}"
    ctype, ek, wire = _element(t)
    init = _initialiser(f)
    if t.array == "none":
        return FieldView(name, f"{ctype} {name}{init};", *_scalar(ek, ctype, m, t.string_bound))
    if t.array == "fixed":
        decl = f"std::array<{ctype}, {t.size}> {name}{init or '{}'};"
        if ek == "prim":
            return FieldView(name, decl, (f"w.prims({m}.data(), {t.size});",),
                             (f"r.prims({m}.data(), {t.size});",))
        w, r = _scalar(ek, ctype, "e", t.string_bound)
        return FieldView(name, decl, (f"for (const auto& e : {m}) {{ {' '.join(w)} }}",),
                         (f"for (auto& e : {m}) {{ {' '.join(r)} }}",))
    size = t.size if t.array == "bounded" else 0
    if size:
        decl = f"::hfsmc::cdr::BoundedVector<{ctype}, {size}> {name}{init};"
    else:
        decl = f"std::vector<{ctype}> {name}{init};"
    write = [f"w.bound({m}.size(), {size});", f"w.count({m}.size());"]
    read = [f"{{ std::size_t n = r.count({wire}); r.bound(n, {size}); {m}.resize(n);"]
    if ek == "prim":
        write.append(f"w.prims({m}.data(), {m}.size());")
        read.append(f"r.prims({m}.data(), n); }}")
    elif ek == "bool":
        write.append(f"for (bool e : {m}) w.boolean(e);")
        read.append(f"for (std::size_t i = 0; i < n; ++i) {m}[i] = r.boolean(); }}")
    else:
        w, r = _scalar(ek, ctype, "e", t.string_bound)
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


def _constant(name: str, base: str, value: Scalar) -> str:
    if base in ("string", "wstring"):
        return f"static constexpr const char* {name} = {_literal(str(value))};"
    return f"static constexpr {PRIMITIVES[base][0]} {name} = {_value(base, value)};"


def message_view(m: Message, distro: str) -> MessageView:
    """The view of one message type."""
    wide = [f.name for f in m.fields if f.type.kind == "wstring"]
    if wide:
        raise EmitError([Diagnostic(
            "E318", f"{m.name}: wstring fields ({', '.join(wide)}) are not supported by the "
            "C++ component yet", Span(m.origin, 1, 1), "error",
            ("use string (UTF-8) in the model's own .msg files",))])
    nested = {f.type.name for f in m.fields if f.type.kind == "nested"}
    return MessageView(
        package=m.package, kind=m.name.split("/")[1], name=m.short, ros_type=m.name, dds_type=m.dds_type_name,
        type_hash=m.type_hash if distro == "jazzy" else "",
        definition=_literal(m.ros2msg),
        includes=tuple(sorted(header_path(n) for n in nested)),
        fields=tuple(_field(f) for f in m.fields),
        constants=tuple(_constant(c.name, c.type, c.value) for c in m.constants))


def cpp_message_files(ms: MessageSet, model: str = "") -> dict[str, str]:
    """The headers of the messages of ``ms``, by their path in the component folder
    (``include/geometry_msgs/msg/twist.hpp``). On jazzy each carries its type's RIHS01 hash
    (the endpoints' USER_DATA); on humble none."""
    template = _environment().get_template("ros2_message.hpp.j2")
    return {"include/" + header_path(m.name):
            template.render(m=message_view(m, ms.distro), distro=ms.distro, model=model)
            for m in ms}


def _environment() -> jinja2.Environment:
    """templates/cpp, as hfsmc.emit.templating makes it (this package sits below emit)."""
    folder = resource_files("hfsmc.templates").joinpath("cpp")
    return jinja2.Environment(
        loader=jinja2.FunctionLoader(lambda name: folder.joinpath(name).read_text("utf-8")),
        undefined=jinja2.StrictUndefined, keep_trailing_newline=True, trim_blocks=True,
        lstrip_blocks=True, autoescape=False)
