"""The C++ back end's part for ``ros2`` interfaces (docs/ros2-cpp.md, SPEC 5.2).

For a model with ``ros2`` interfaces the component folder gets: the headers of every
message type the model uses, and of those they contain, at rclcpp's paths
(``include/geometry_msgs/msg/twist.hpp``, by ``hfsmc.ros2.cpp_messages``), with
``rmw_dds_common/msg/ParticipantEntitiesInfo`` that the node announces itself with; and
one class per interface (``include/hfsmc_ros2/NAME.hpp``, ``hfsmc_ros2::Ros2_NAME``) over
``hfsmc::ros2::Interface`` (templates/cpp/hfsmc/ros2_interface.hpp): a typed query per
subscription and a ``publish`` overload per type published. Everything a template prints
is computed here.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.resources import files as resource_files

import jinja2

from hfsmc.emit.cpp_ros2_rpc import RpcsView, rpc_type_files, rpcs_view
from hfsmc.errors import CheckError, EmitError, fail
from hfsmc.ir import Interface, Model, Ros2Topic
from hfsmc.ros2.cpp_messages import cpp_message_files, cpp_type_name, header_path
from hfsmc.ros2.definitions import ros2_type_name
from hfsmc.ros2files import used_messages

# The introspection's observer (SPEC 5.4), copied only for a model that asks for it.
INTROSPECTION_HEADER = "hfsmc/ros2_intro.hpp"
# What the class of an interface has already: a subscription cannot take these names.
BASE_MEMBERS = frozenset({
    "age", "count", "publishers", "subscribers", "malformed", "topic", "name", "publish",
    "subscribe", "advertise", "start", "latest", "send", "source_name", "source_type",
    "source_config", "take_snapshot", "snapshot_fields", "snapshot_schema", "sent",
    # actions and services (SPEC 5.3)
    "send_goal", "cancel", "goal_status", "feedback", "result", "call", "call_status",
    "response", "action", "service", "stop_goals",
})


@dataclass(frozen=True, slots=True)
class TopicView:
    key: str
    topic: str  # as written: NAME.yaml may change it
    type: str  # pkg/msg/Name
    cpp_type: str  # pkg::msg::Name
    qos: str  # a profile, or `reliability=..,durability=..,depth=..`
    publication: bool


@dataclass(frozen=True, slots=True)
class Ros2InterfaceView:
    """What ``ros2_interface.hpp.j2`` prints for one interface."""

    name: str
    base: str  # the model's file name
    cls: str
    distro: str
    node: str
    ns: str
    domain: int  # -1: $ROS_DOMAIN_ID, else 0
    headers: tuple[str, ...]  # the message headers it includes
    topics: tuple[TopicView, ...]
    publish_types: tuple[tuple[str, str], ...]  # (pkg::msg::Name, the publications of it)
    rpc: RpcsView  # its actions and services
    introspection: bool = False  # `introspection: true`: hfsmc/ros2_intro.hpp publishes the automaton


def interface_class(name: str) -> str:
    return f"hfsmc_ros2::Ros2_{name}"


def interface_header(name: str) -> str:
    return f"hfsmc_ros2/{name}.hpp"


def _qos(t: Ros2Topic) -> str:
    if isinstance(t.qos, str):
        return t.qos
    return ",".join(f"{k}={v}" for k, v in t.qos)


def _topic(t: Ros2Topic, publication: bool) -> TopicView:
    full = ros2_type_name(t.type)
    return TopicView(t.name, t.topic, full, cpp_type_name(full), _qos(t), publication)


def interface_view(model: Model, i: Interface, base: str) -> Ros2InterfaceView:
    r = i.ros2
    assert r is not None
    for t in r.subscribe:
        if t.name in BASE_MEMBERS:
            fail(EmitError, "E150", f"a C++ ros2 interface cannot name a subscription `{t.name}`: "
                 f"`{i.name}.{t.name}()` is the interface's own method; rename it", t.span)
    topics = (*(_topic(t, False) for t in r.subscribe), *(_topic(t, True) for t in r.publish))
    by_type: dict[str, list[str]] = {}
    for view in topics:
        if view.publication:
            by_type.setdefault(view.cpp_type, []).append(view.key)
    return Ros2InterfaceView(
        name=i.name, base=base, cls=f"Ros2_{i.name}", distro=r.distro_or_default,
        node=r.node or model.name, ns=r.namespace or "/",
        domain=r.domain if r.domain is not None else -1,
        headers=tuple(dict.fromkeys(header_path(view.type) for view in topics)),
        topics=topics,
        publish_types=tuple((k, ", ".join(v)) for k, v in by_type.items()),
        rpc=rpcs_view(r),
        introspection=bool(r.introspection))


def ros2_files(model: Model, env: jinja2.Environment, base: str) -> dict[str, str]:
    """The message headers and the interface classes, by path in the component folder."""
    ros = [i for i in model.interfaces if i.ros2 is not None]
    if not ros:
        return {}
    try:
        messages = used_messages(model.interfaces, model.imports, runtime=True)
    except CheckError as e:  # `check` has said it already; a build says it again
        raise EmitError(e.diagnostics) from None
    out = cpp_message_files(messages, model=base)
    out |= rpc_type_files([i.ros2 for i in ros if i.ros2 is not None], env)
    template = env.get_template("ros2_interface.hpp.j2")
    for i in ros:
        out[f"include/{interface_header(i.name)}"] = template.render(v=interface_view(model, i, base))
    if any(i.ros2 is not None and i.ros2.introspection for i in ros):  # its yasmin_msgs too
        out[f"include/{INTROSPECTION_HEADER}"] = resource_files("hfsmc.templates").joinpath(
            "cpp", INTROSPECTION_HEADER).read_text("utf-8")
    return out
