"""ROS 2's rules for names (docs/ros2.md, "On the wire"), for ``hfsmc check``: the
component's own (``templates/python/hfsmc_ros2_names.py``, standard library only), so
that check and the component at start accept and refuse the same names."""

from __future__ import annotations

from hfsmc.templates.python import hfsmc_ros2_names as _names  # type: ignore[import-not-found]

NameError_: type[ValueError] = _names.Ros2Error


def resolve_name(name: str, namespace: str, node: str) -> str:
    """The resolved topic name (``/ns/x``, ``/ns/node/x``, ``/x``); NameError_ if refused."""
    return str(_names.resolve_name(name, namespace, node))


def validate_namespace(namespace: str) -> str:
    return str(_names.validate_namespace(namespace))


def validate_node_name(node: str) -> str:
    return str(_names.validate_node_name(node))
