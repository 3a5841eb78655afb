"""The C++ back end's part for a ``ros2`` interface's actions and services (SPEC 5.3,
docs/ros2-cpp.md "Actions and services").

Each service or action type a model uses gets the header rclcpp code includes
(``include/std_srvs/srv/trigger.hpp``, ``include/nav2_msgs/action/navigate_to_pose.hpp``)
with the struct rclcpp names (``std_srvs::srv::Trigger`` with ``Request`` and ``Response``;
``nav2_msgs::action::NavigateToPose`` with ``Goal``, ``Result``, ``Feedback`` and ``Impl``),
over the generated messages of its parts (``hfsmc.ros2.cpp_messages``). The interface class
gets, per action or service, its declaration and typed ``send_goal``/``call`` overloads,
and ``feedback``/``result``/``response`` (typed when every action, or every service, of the
interface has one type; ``feedback<A>(name)`` always). Everything a template prints is
computed here.
"""

from __future__ import annotations

from dataclasses import dataclass

import jinja2

from hfsmc.ir import SERVICE_TIMEOUT_US, Ros2Rpc, Ros2Settings
from hfsmc.ros2.cpp_messages import cpp_type_name, header_path, snake_case
from hfsmc.ros2.services import kind_of


@dataclass(frozen=True, slots=True)
class RpcView:
    key: str
    ros_name: str  # as written: NAME.yaml may change it
    type: str  # pkg/action/Name or pkg/srv/Name
    cpp_type: str  # pkg::action::Name
    timeout: str  # seconds, a C++ literal; -1: none
    action: bool


@dataclass(frozen=True, slots=True)
class RpcTypeView:
    """What ``ros2_rpc_type.hpp.j2`` prints for one service or action type."""

    package: str
    kind: str  # srv or action
    name: str
    type: str
    parts: tuple[tuple[str, str], ...]  # (rclcpp's member name, the generated message)
    headers: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class RpcsView:
    """The actions and services of one interface, for ``ros2_interface.hpp.j2``."""

    rpcs: tuple[RpcView, ...]
    headers: tuple[str, ...]
    goal_types: tuple[tuple[str, str], ...]  # (pkg::action::Name, its actions)
    request_types: tuple[tuple[str, str], ...]  # (pkg::srv::Name, its services)
    one_action: str  # the type of every action, "" when none or several
    one_service: str


def rpc_header(type_: str) -> str:
    """``nav2_msgs/action/NavigateToPose`` -> ``nav2_msgs/action/navigate_to_pose.hpp``."""
    package, kind, name = type_.split("/")
    return f"{package}/{kind}/{snake_case(name)}.hpp"


def _timeout(r: Ros2Rpc, action: bool) -> str:
    us = r.timeout_us if r.timeout_us is not None else None if action else SERVICE_TIMEOUT_US
    return "-1.0" if us is None else repr(us / 1e6)


def rpcs_view(r: Ros2Settings) -> RpcsView:
    rpcs = (*(RpcView(x.name, x.ros_name, x.type, cpp_type_name(x.type), _timeout(x, True), True)
              for x in r.actions),
            *(RpcView(x.name, x.ros_name, x.type, cpp_type_name(x.type), _timeout(x, False), False)
              for x in r.services))

    def grouped(action: bool) -> tuple[tuple[str, str], ...]:
        by: dict[str, list[str]] = {}
        for v in rpcs:
            if v.action == action:
                by.setdefault(v.cpp_type, []).append(v.key)
        return tuple((k, ", ".join(v)) for k, v in by.items())

    goals, requests = grouped(True), grouped(False)
    return RpcsView(rpcs, tuple(dict.fromkeys(rpc_header(v.type) for v in rpcs)), goals, requests,
                    goals[0][0] if len(goals) == 1 else "",
                    requests[0][0] if len(requests) == 1 else "")


def _type_view(type_: str) -> RpcTypeView:
    package, kind, name = type_.split("/")
    parts: tuple[str, ...] = ("Request", "Response") if kind_of(type_) == "srv" \
        else ("Goal", "Result", "Feedback")
    impl = ("SendGoal_Request", "SendGoal_Response", "GetResult_Request", "GetResult_Response",
            "FeedbackMessage") if kind == "action" else ()
    messages = [f"{type_}_{p}" for p in (*parts, *impl)]
    if kind == "action":
        messages += ["action_msgs/srv/CancelGoal_Request", "action_msgs/srv/CancelGoal_Response",
                     "action_msgs/msg/GoalStatusArray"]
    return RpcTypeView(package, kind, name, type_,
                       tuple((p, f"{name}_{p}") for p in parts),
                       tuple(header_path(m) for m in messages))


def rpc_type_files(settings: list[Ros2Settings], env: jinja2.Environment) -> dict[str, str]:
    """The header of each service and action type the interfaces use, by path."""
    types = dict.fromkeys(x.type for r in settings for x in (*r.actions, *r.services)
                          if kind_of(x.type) is not None)
    template = env.get_template("ros2_rpc_type.hpp.j2")
    return {f"include/{rpc_header(t)}": template.render(t=_type_view(t)) for t in types}
