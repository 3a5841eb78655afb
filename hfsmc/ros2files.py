"""A ``ros2`` interface's keys, read while the model is built (docs/ros2.md, SPEC 5.2).

The builder hands each ``type: ros2`` interface here: its keys become a
:class:`~hfsmc.ir.Ros2Settings`, and what can be told from the model alone is reported at
the model's positions: a ROS 2 name ROS 2 forbids (E313), one topic with two types
(E314), a ``.msg`` file that leaves the model's folder or is missing (E315, confined as
drivers are: hfsmc/driverfiles.py), keys of another interface type (E312). Then, for the
whole model, :func:`check_messages` finds every message type the model names (the topics'
``type:`` and the snippets' ``from sensor_msgs.msg import LaserScan``) among the distro's
and the model's own (E310 with a did-you-mean, E311 at a ``.msg`` file's line).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from hfsmc.driverfiles import confined, leads_out
from hfsmc.durations import parse_us
from hfsmc.errors import CheckError, Diagnostics, Span
from hfsmc.frontend.source import Document, PathKey
from hfsmc.ir import Import, Interface, MsgRef, Ros2Rpc, Ros2Settings, Ros2Topic
from hfsmc.ros2.definitions import (
    DEFAULT_DISTRO,
    MessageSet,
    MsgFile,
    message_set,
    ros2_type_name,
    standard_types,
)
from hfsmc.ros2.names import NameError_, resolve_name, validate_namespace, validate_node_name
from hfsmc.ros2.services import SHIPPED

ROS2_KEYS = ("node", "namespace", "domain", "distro", "subscribe", "publish", "messages",
             "actions", "services", "introspection")
OTHER_KEYS = ("url", "options", "python", "cpp")
# What the runtime needs besides the model's types: the node's announcement.
RUNTIME_TYPES = ("rmw_dds_common/msg/ParticipantEntitiesInfo",)
# What `introspection: true` publishes (SPEC 5.4), and the shipped files of yasmin_msgs.
INTROSPECTION_TYPES = ("yasmin_msgs/msg/StateMachine", "std_msgs/msg/String")
INTROSPECTION_TOPICS = ("/fsm_viewer", "~/hfsm/status")  # templates/python/hfsmc_ros2intro.py
YASMIN_MSGS = tuple(SHIPPED / "yasmin_msgs" / "msg" / f"{n}.msg"
                    for n in ("Transition", "State", "StateMachine"))
_QOS_KEYS = ("reliability", "durability", "depth")
_FROM_MSG = re.compile(r"^\s*from\s+([A-Za-z_][A-Za-z0-9_]*)\.msg\s+import\s+\(?(.*?)\)?\s*$")


def misplaced_keys(doc: Document, name: str, spec: Mapping[str, Any], diags: Diagnostics) -> None:
    """E312 for a ros2 key on another type of interface."""
    for key in ROS2_KEYS:
        if key in spec:
            diags.error("E312", f"`{key}` is a key of `type: ros2` interfaces, not of "
                        f"`type: {spec['type']}`", doc.key_span(("interfaces", name, key)))


def ros2_settings(doc: Document, name: str, spec: Mapping[str, Any], model_name: str,
                  language: str, diags: Diagnostics) -> Ros2Settings:
    """The keys of the ros2 interface ``name`` (a schema-valid ``spec``), checked."""
    path: PathKey = ("interfaces", name)
    for key in OTHER_KEYS:
        if key in spec:
            diags.error("E312", f"`{key}` is not a key of `type: ros2` interfaces (they have "
                        f"{', '.join(ROS2_KEYS)})", doc.key_span((*path, key)))
    node = spec.get("node")
    namespace = spec.get("namespace")
    try:
        validate_node_name(node if node is not None else model_name)
    except NameError_ as e:
        diags.error("E313", str(e), doc.span((*path, "node")) if node is not None
                    else doc.key_span(path), "a node name is one part: `bump_and_go`")
    ns_ok = True
    if namespace is not None:
        try:
            validate_namespace(namespace)
        except NameError_ as e:
            ns_ok = False
            diags.error("E313", str(e), doc.span((*path, "namespace")))
    subscribe = _topics(doc, path, spec, "subscribe")
    publish = _topics(doc, path, spec, "publish")
    settings = Ros2Settings(node, namespace, spec.get("domain"), spec.get("distro"), subscribe,
                            publish, _messages(doc, path, spec, diags),
                            _rpcs(doc, path, spec, "actions"), _rpcs(doc, path, spec, "services"),
                            spec.get("introspection"))
    _check_topics(settings, model_name if node is None else node, ns_ok, diags)
    _check_rpcs(settings, model_name if node is None else node, ns_ok, diags)
    return settings


def _rpcs(doc: Document, path: PathKey, spec: Mapping[str, Any], key: str
          ) -> tuple[Ros2Rpc, ...]:
    out = []
    for entry, t in (spec.get(key) or {}).items():
        epath = (*path, key, entry)
        ros_name = t.get("name")
        timeout = t.get("timeout")
        out.append(Ros2Rpc(
            str(entry), str(ros_name) if ros_name is not None else str(entry), str(t["type"]),
            parse_us(timeout) if timeout is not None else None, doc.key_span(epath),
            doc.span((*epath, "type")),
            doc.span((*epath, "name")) if ros_name is not None else doc.key_span(epath)))
    return tuple(out)


def _check_rpcs(s: Ros2Settings, node: str, ns_ok: bool, diags: Diagnostics) -> None:
    """E313 for a ROS name ROS 2 forbids, E316 for a type of the wrong kind (a service
    among the actions), E312 for a name used twice."""
    names = {t.name for t in (*s.subscribe, *s.publish)}
    for kind, rpcs in (("action", s.actions), ("srv", s.services)):
        for r in rpcs:
            if r.name in names:
                diags.error("E312", f"`{r.name}` names two things of the interface: snippets "
                            "name each by its own name", r.span)
            names.add(r.name)
            parts = r.type.split("/")
            if len(parts) != 3 or parts[1] != kind:
                diags.error("E316", f"`{r.type}` is not {'an action' if kind == 'action' else 'a service'} "
                            f"type: `pkg/{kind}/Name`", r.type_span)
            try:
                resolve_name(r.ros_name, s.namespace or "/" if ns_ok else "/", node)
            except NameError_ as e:
                diags.error("E313", str(e), r.name_span, "ROS 2 names: parts of letters, "
                            "digits and `_`, not starting with a digit, no `__`")


def _topics(doc: Document, path: PathKey, spec: Mapping[str, Any], key: str
            ) -> tuple[Ros2Topic, ...]:
    out = []
    for entry, t in (spec.get(key) or {}).items():
        epath = (*path, key, entry)
        qos = t.get("qos")
        written: str | tuple[tuple[str, str | int], ...] = (
            "default" if qos is None else qos if isinstance(qos, str)
            else tuple((k, qos[k]) for k in _QOS_KEYS if k in qos))
        topic = t.get("topic")
        out.append(Ros2Topic(
            str(entry), str(topic) if topic is not None else str(entry), str(t["type"]),
            written, doc.key_span(epath), doc.span((*epath, "type")),
            doc.span((*epath, "topic")) if topic is not None else doc.key_span(epath)))
    return tuple(out)


def _check_topics(s: Ros2Settings, node: str, ns_ok: bool, diags: Diagnostics) -> None:
    """E313 for a topic name ROS 2 forbids, E314 for one topic with two types."""
    seen: dict[str, Ros2Topic] = {}
    names: dict[str, Ros2Topic] = {}
    for t in (*s.subscribe, *s.publish):
        if t.name in names:
            diags.error("E312", f"`{t.name}` is both a subscription and a publication: "
                        "snippets name each by its own name", t.span,
                        f"the other is on line {names[t.name].span.line}")
        names.setdefault(t.name, t)
        try:
            full = resolve_name(t.topic, s.namespace or "/" if ns_ok else "/", node)
        except NameError_ as e:
            diags.error("E313", str(e), t.topic_span, "ROS 2 names: parts of letters, digits "
                        "and `_`, not starting with a digit, no `__`; `~/x` is below the node")
            continue
        if s.introspection and full in (INTROSPECTION_TOPICS[0],
                                        resolve_name(INTROSPECTION_TOPICS[1], s.namespace or "/"
                                                     if ns_ok else "/", node)):
            diags.error("E314", f"topic {full} is the introspection's (`introspection: "
                        "true`): the model may not subscribe or publish it", t.topic_span)
        other = seen.setdefault(full, t)
        if ros2_type_name(other.type) != ros2_type_name(t.type):
            diags.error("E314", f"topic {full} is used with two types: {other.type} "
                        f"(`{other.name}`, line {other.type_span.line}) and {t.type}",
                        t.type_span, "a ROS 2 topic has one type")


def _messages(doc: Document, path: PathKey, spec: Mapping[str, Any], diags: Diagnostics
              ) -> tuple[MsgRef, ...]:
    out = []
    for k, written in enumerate(spec.get("messages") or ()):
        span = doc.span((*path, "messages", k))
        try:
            file = confined(doc.file, str(written))
        except ValueError:
            diags.error("E315", f"message file `{written}` is outside the model's folder: "
                        "it is read only from the model's folder and below", span)
            continue
        if not os.path.isfile(file):
            diags.error("E315", f"message file `{written}` does not exist (looked for {file})",
                        span)
            continue
        real = leads_out(doc.file, file)
        if real is not None:
            diags.error("E315", f"message file `{written}` leads outside the model's folder "
                        f"(to {real})", span)
            continue
        out.append(MsgRef(str(written), file, span))
    return tuple(out)


# ---------------------------------------------------------------------------
# the whole model: which message types it uses


def ros2_interfaces(interfaces: Iterable[Interface]) -> list[Interface]:
    return [i for i in interfaces if i.ros2 is not None]


def model_distro(interfaces: Iterable[Interface]) -> str:
    found = [i.ros2.distro_or_default for i in ros2_interfaces(interfaces) if i.ros2]
    return found[0] if found else DEFAULT_DISTRO


def msg_files(interfaces: Iterable[Interface]) -> tuple[MsgFile, ...]:
    seen: dict[str, MsgFile] = {}
    for i in ros2_interfaces(interfaces):
        assert i.ros2 is not None
        for m in i.ros2.messages:
            seen.setdefault(os.path.realpath(m.path), MsgFile(Path(m.path), m.path))
    return tuple(seen.values())


def imported_types(imports: Iterable[Import], packages: set[str]
                   ) -> list[tuple[str, Span]]:
    """``from PKG.msg import A, B as C`` items whose PKG is a ROS 2 package of the model:
    each ``PKG/msg/A`` with the position of its name."""
    out = []
    for imp in imports:
        m = _FROM_MSG.match(imp.text)
        if m is None or m[1] not in packages:
            continue
        for part in m[2].split(","):
            short = part.strip().split(" as ")[0].strip()
            if not short:
                continue
            col = imp.text.find(short, m.start(2))
            out.append((f"{m[1]}/msg/{short}",
                        Span(imp.span.file, imp.span.line, imp.span.col + max(col, 0))))
    return out


def _packages(distro: str, files: Iterable[MsgFile]) -> set[str]:
    own = {f.path.parent.parent.name for f in files}
    return {n.split("/")[0] for n in standard_types(distro)} | own


def check_messages(interfaces: tuple[Interface, ...], imports: tuple[Import, ...],
                   diags: Diagnostics) -> None:
    """E310 for every message type the model names that the distro and its ``.msg`` files
    do not have (at the `type:` value or the import); E311 for a bad ``.msg`` file; E312
    for two ros2 interfaces of different distros (the component's messages are one set)."""
    ros = ros2_interfaces(interfaces)
    if not ros:
        return
    distros = {i.ros2.distro_or_default for i in ros if i.ros2 is not None}
    if len(distros) > 1:
        diags.error("E312", f"ros2 interfaces of two distros ({', '.join(sorted(distros))}): "
                    "a component's messages are those of one distro", ros[-1].span)
        return
    try:
        used_messages(interfaces, imports)
    except CheckError as e:
        diags.extend(e.diagnostics)


def used_messages(interfaces: tuple[Interface, ...], imports: tuple[Import, ...],
                  runtime: bool = False) -> MessageSet:
    """The message set of the model's ros2 interfaces and imports (``runtime``: with what
    the component's runtime needs too); CheckError as message_set raises it."""
    distro = model_distro(interfaces)
    files = msg_files(interfaces)
    if runtime and any(i.ros2 is not None and i.ros2.introspection
                       for i in ros2_interfaces(interfaces)):
        files += tuple(MsgFile(p, f"hfsmc/ros2/msg/yasmin_msgs/msg/{p.name}") for p in YASMIN_MSGS)
    uses: list[tuple[str, Span]] = [
        (t.type, t.type_span) for i in ros2_interfaces(interfaces) if i.ros2 is not None
        for t in (*i.ros2.subscribe, *i.ros2.publish)]
    uses += imported_types(imports, _packages(distro, files))
    if runtime:
        uses += [(t, Span("<runtime>", 1, 1)) for t in RUNTIME_TYPES]
        if any(i.ros2 is not None and i.ros2.introspection for i in ros2_interfaces(interfaces)):
            uses += [(t, Span("<runtime>", 1, 1)) for t in INTROSPECTION_TYPES]
    rpcs = [(r.type, r.type_span) for i in ros2_interfaces(interfaces) if i.ros2 is not None
            for r in (*i.ros2.actions, *i.ros2.services) if r.type.count("/") == 2]
    return message_set(distro, uses, files, rpcs)
