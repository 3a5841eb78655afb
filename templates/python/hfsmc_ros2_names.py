# hfsmc_ros2_names.py: ROS 2's rules for names (docs/ros2.md, "On the wire").
# Copied beside a component with a ros2 interface; standard library only, so that
# `hfsmc check` applies the very rules the component applies at start.
"""ROS 2's name resolution and checks: topic names (relative, absolute, ``~``),
namespaces and node names."""

from __future__ import annotations

import re

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class Ros2Error(ValueError):
    """A setting ROS 2 would refuse: a name, a domain id, a QoS, a type."""


def resolve_name(name: str, namespace: str, node: str) -> str:
    """ROS 2's resolution of a topic name: absolute as it is, ``~`` against the node
    (``/ns/node/x``), relative against the namespace. Raises Ros2Error naming the rule a
    name breaks."""
    ns = validate_namespace(namespace)
    if not name:
        raise Ros2Error("a topic name is empty")
    if name.startswith("~"):
        if name != "~" and not name.startswith("~/"):
            raise Ros2Error(f"topic `{name}`: `~` is followed by `/` (`~/x`)")
        base = (ns.rstrip("/") + "/" + node)
        full = base + name[1:]
    elif name.startswith("/"):
        full = name
    else:
        full = ns.rstrip("/") + "/" + name
    _check_tokens(full, f"topic `{name}`")
    return full


def validate_namespace(namespace: str) -> str:
    ns = namespace or "/"
    if not ns.startswith("/"):
        ns = "/" + ns
    if ns != "/":
        _check_tokens(ns, f"namespace `{namespace}`")
    return ns


def validate_node_name(node: str) -> str:
    if not _TOKEN.match(node or ""):
        raise Ros2Error(f"node name `{node}`: letters, digits and `_`, not starting with a digit")
    return node


def _check_tokens(full: str, what: str) -> None:
    if full.endswith("/") and full != "/":
        raise Ros2Error(f"{what} ends with `/`")
    for token in full.split("/")[1:]:
        if not token:
            raise Ros2Error(f"{what} has an empty part (`//`)")
        if not _TOKEN.match(token):
            raise Ros2Error(f"{what}: `{token}` is not letters, digits and `_` "
                            "(not starting with a digit)")
        if "__" in token:
            raise Ros2Error(f"{what}: `{token}` has `__` (ROS 2 keeps it for itself)")
