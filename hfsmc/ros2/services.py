"""ROS 2 services and actions (SPEC 5.3, docs/ros2.md "Services and actions"): the
standard ``.srv`` and ``.action`` definitions hfsmc ships (``hfsmc/ros2/msg/``, as
rosbags' stores carry none), and the messages ROS 2 makes of each, as rosidl makes them.

A service ``pkg/srv/Name`` is two messages, ``pkg/srv/Name_Request`` and
``pkg/srv/Name_Response``. An action ``pkg/action/Name`` is its ``_Goal``, ``_Result`` and
``_Feedback``, and what its services and topics carry: ``_SendGoal_Request`` (goal id and
goal), ``_SendGoal_Response`` (accepted, stamp), ``_GetResult_Request`` (goal id),
``_GetResult_Response`` (status, result) and ``_FeedbackMessage`` (goal id, feedback);
its cancel service is ``action_msgs/srv/CancelGoal`` and its status topic carries
``action_msgs/msg/GoalStatusArray``. Each message is registered in rosbags' type store
under that name, so both generators, the type hashes and the tests' reference
serialization treat it as any other message.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

SHIPPED = Path(__file__).resolve().parent / "msg"
CANCEL_SERVICE = "action_msgs/srv/CancelGoal"
STATUS_MESSAGE = "action_msgs/msg/GoalStatusArray"


def shipped(distro: str) -> dict[str, Path]:
    """The services and actions hfsmc ships for ``distro``: full name -> its file.
    Services are the same in every distro; an action's definition is the distro's
    release of its package (``nav2_msgs/<distro>/action/``)."""
    out = {f"{f.parent.parent.name}/srv/{f.stem}": f for f in SHIPPED.glob("*/srv/*.srv")}
    for f in SHIPPED.glob(f"*/{distro}/action/*.action"):
        out[f"{f.parent.parent.parent.name}/action/{f.stem}"] = f
    return dict(sorted(out.items()))


def kind_of(name: str) -> str | None:
    """``srv`` or ``action`` for ``pkg/srv/Name`` or ``pkg/action/Name``, else None."""
    parts = name.split("/")
    return parts[1] if len(parts) == 3 and parts[1] in ("srv", "action") else None


def parts(name: str) -> tuple[str, ...]:
    """The messages of a service (request, response) or an action (goal, result,
    feedback, send_goal request and response, get_result request and response, feedback
    message), by their full names."""
    if kind_of(name) == "srv":
        return (f"{name}_Request", f"{name}_Response")
    return tuple(f"{name}_{p}" for p in (
        "Goal", "Result", "Feedback", "SendGoal_Request", "SendGoal_Response",
        "GetResult_Request", "GetResult_Response", "FeedbackMessage"))


def sections(text: str, n: int, what: str) -> list[str]:
    """The ``---``-separated sections of a ``.srv`` (2) or ``.action`` (3) file."""
    out: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip() == "---":
            out.append([])
        else:
            out[-1].append(line)
    if len(out) != n:
        raise ValueError(f"{what}: {n} sections separated by `---`, not {len(out)}")
    return ["\n".join(s) + "\n" for s in out]


def derived(name: str, text: str) -> dict[str, str]:
    """The ``.msg`` text of each message ROS 2 makes of the service or action ``name``."""
    if kind_of(name) == "srv":
        req, resp = sections(text, 2, name)
        return {f"{name}_Request": req, f"{name}_Response": resp}
    goal, result, feedback = sections(text, 3, name)
    return {
        f"{name}_Goal": goal, f"{name}_Result": result, f"{name}_Feedback": feedback,
        f"{name}_SendGoal_Request": f"unique_identifier_msgs/UUID goal_id\n{name}_Goal goal\n",
        f"{name}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp\n",
        f"{name}_GetResult_Request": "unique_identifier_msgs/UUID goal_id\n",
        f"{name}_GetResult_Response": f"int8 status\n{name}_Result result\n",
        f"{name}_FeedbackMessage":
            f"unique_identifier_msgs/UUID goal_id\n{name}_Feedback feedback\n",
    }


def types_of(name: str, text: str) -> dict[str, Any]:
    """rosbags' descriptions of the messages ROS 2 makes of the service or action ``name``
    whose ``.srv``/``.action`` text is ``text`` (to register in a rosbags store)."""
    from rosbags.typesys import get_types_from_msg

    types: dict[str, Any] = {}
    for msg, part in derived(name, text).items():
        if not any(line.split("#")[0].strip() for line in part.splitlines()):
            types[msg] = ([], [])  # an empty section: rosbags' parser wants a line
            continue
        # a short nested name (`GoalInfo`) is of the same package, as in a .msg
        pkg = msg.split("/")[0]
        got = get_types_from_msg(part, f"{pkg}/msg/{msg.split('/')[-1]}")
        for key, value in got.items():
            types[msg if key == f"{pkg}/msg/{msg.split('/')[-1]}" else key] = value
    return types


def register(store: Any, distro: str) -> None:
    """Register every shipped service's and action's messages in a rosbags store."""
    types: dict[str, Any] = {}
    for name, path in shipped(distro).items():
        types.update(types_of(name, path.read_text(encoding="utf-8")))
    store.register(types)
