"""ROS 2's rules for names (docs/ros2.md, "On the wire"), for ``hfsmc check``.

The component applies the same rules at start (``templates/python/hfsmc_ros2_wire.py``,
which cannot be imported here: it needs cyclonedds); tests/test_ros2_model.py checks
that both accept and refuse the same names.
"""

from __future__ import annotations

import re

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class NameError_(ValueError):
    """A name ROS 2 refuses; the message says which rule it breaks."""


def resolve_name(name: str, namespace: str, node: str) -> str:
    """ROS 2's resolution of a topic name: absolute as it is, ``~`` against the node,
    relative against the namespace."""
    ns = validate_namespace(namespace)
    if not name:
        raise NameError_("a topic name is empty")
    if name.startswith("~"):
        if name != "~" and not name.startswith("~/"):
            raise NameError_(f"topic `{name}`: `~` is followed by `/` (`~/x`)")
        full = ns.rstrip("/") + "/" + node + name[1:]
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
        raise NameError_(f"node name `{node}`: letters, digits and `_`, not starting with a "
                         "digit")
    return node


def _check_tokens(full: str, what: str) -> None:
    if full.endswith("/") and full != "/":
        raise NameError_(f"{what} ends with `/`")
    for token in full.split("/")[1:]:
        if not token:
            raise NameError_(f"{what} has an empty part (`//`)")
        if not _TOKEN.match(token):
            raise NameError_(f"{what}: `{token}` is not letters, digits and `_` "
                             "(not starting with a digit)")
        if "__" in token:
            raise NameError_(f"{what}: `{token}` has `__` (ROS 2 keeps it for itself)")
