"""ROS 2's conventions on DDS, for the ``ros2`` interface of Python components
(docs/ros2.md, "On the wire"): name resolution, the domain id, QoS profiles, and the DDS
types under which raw CDR bytes are written and read with cyclonedds-python.

Copied beside a component with a ``ros2`` interface; needs only cyclonedds and the
generated message packages (``sensor_msgs/msg/__init__.py``...).

Raw CDR with cyclonedds-python: the binding serializes in Python (``sample.serialize()``)
and hands the bytes to the C layer, and a reader hands the C layer's bytes to
``data_type.deserialize``. :func:`dds_type` builds, from a generated message class, an
IDL struct with ROS 2's type name (``sensor_msgs::msg::dds_::LaserScan_``) and ROS 2's
fields (so the XTypes type information it announces is that of ROS 2's IDL, and a peer
that checks types finds the same), whose ``serialize`` returns the bytes the generated
class wrote and whose ``deserialize`` keeps the bytes received: the binding's own
serializer never runs.
"""

from __future__ import annotations

import importlib
import os
import re
from typing import Any

from cyclonedds.core import Policy, Qos
from cyclonedds.idl import make_idl_struct
from cyclonedds.idl import types as _types
from cyclonedds.util import duration

if __package__:
    from . import hfsmc_ros2_names as _names
else:  # copied beside the generated component, where the modules are top level
    import hfsmc_ros2_names as _names  # type: ignore[import-not-found, no-redef]

# ROS 2's name rules live in hfsmc_ros2_names (standard library only: hfsmc check uses them)
Ros2Error = _names.Ros2Error
resolve_name = _names.resolve_name
validate_namespace = _names.validate_namespace
validate_node_name = _names.validate_node_name

T: Any = _types  # sequence[...], array[...], bounded_str[...]: indexable at run time
DOMAIN_MAX = 232  # the largest id for which DDS's port mapping works (as ROS 2 documents)
PROFILES = {
    "default": ("reliable", "volatile", 10),
    "sensor_data": ("best_effort", "volatile", 5),
    "latched": ("reliable", "transient_local", 1),
}
_PRIMITIVES: dict[str, Any] = {
    "boolean": bool, "octet": T.byte, "uint8": T.uint8, "int8": T.int8, "int16": T.int16,
    "uint16": T.uint16, "int32": T.int32, "uint32": T.uint32, "int64": T.int64,
    "uint64": T.uint64, "float": T.float32, "double": T.float64, "string": str,
}


def domain_id(value: Any) -> int:
    """The domain: ``value`` when set, else $ROS_DOMAIN_ID, else 0; 0..232 or Ros2Error."""
    raw = value if value not in (None, "") else os.environ.get("ROS_DOMAIN_ID", "") or 0
    try:
        dom = int(str(raw).strip())
    except ValueError:
        raise Ros2Error(f"domain `{raw}` is not a number (ROS_DOMAIN_ID: 0..{DOMAIN_MAX})") \
            from None
    if not 0 <= dom <= DOMAIN_MAX:
        raise Ros2Error(f"domain {dom} is out of range (ROS_DOMAIN_ID: 0..{DOMAIN_MAX})")
    return dom


def qos_of(spec: Any) -> tuple[str, str, int]:
    """A QoS profile name or ``{reliability, durability, depth}`` -> the three."""
    if spec in (None, ""):
        spec = "default"
    if isinstance(spec, str):
        if spec not in PROFILES:
            raise Ros2Error(f"QoS `{spec}`: one of {', '.join(PROFILES)} or "
                            "{reliability, durability, depth}")
        return PROFILES[spec]
    if not isinstance(spec, dict):
        raise Ros2Error(f"QoS `{spec}`: a profile name or a mapping")
    rel = str(spec.get("reliability", "reliable"))
    dur = str(spec.get("durability", "volatile"))
    depth = spec.get("depth", 10)
    if rel not in ("reliable", "best_effort"):
        raise Ros2Error(f"reliability `{rel}`: reliable or best_effort")
    if dur not in ("volatile", "transient_local"):
        raise Ros2Error(f"durability `{dur}`: volatile or transient_local")
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
        raise Ros2Error(f"depth `{depth}`: a whole number from 1")
    return rel, dur, depth


def dds_qos(qos: tuple[str, str, int], user_data: bytes | None = None) -> Qos:
    """The DDS QoS of a ROS 2 endpoint: the profile, XCDR1, and its USER_DATA."""
    rel, dur, depth = qos
    policies: list[Any] = [
        Policy.Reliability.Reliable(duration(milliseconds=100)) if rel == "reliable"
        else Policy.Reliability.BestEffort,
        Policy.Durability.TransientLocal if dur == "transient_local"
        else Policy.Durability.Volatile,
        Policy.History.KeepLast(depth),
        Policy.DataRepresentation(use_cdrv0_representation=True),
    ]
    if user_data is not None:
        policies.append(Policy.Userdata(user_data))
    return Qos(*policies)


def message_class(type_name: str) -> Any:
    """The generated class of ``pkg/msg/Name`` (imported from ``pkg.msg``); also of a
    service's or an action's message (``std_srvs/srv/Trigger_Request``) and of a service
    or an action itself (``nav2_msgs/action/NavigateToPose``: rclpy's class)."""
    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] not in ("msg", "srv", "action"):
        raise Ros2Error(f"type `{type_name}`: pkg/msg/Name")
    try:
        cls = getattr(importlib.import_module(f"{parts[0]}.{parts[1]}"), parts[2])
    except (ImportError, AttributeError):
        raise Ros2Error(f"type `{type_name}` was not generated into this component "
                        "(rebuild it with hfsmc)") from None
    return cls


_TYPES: dict[str, Any] = {}


def dds_type(cls: Any, header: bool = False) -> Any:
    """The IDL struct under which raw CDR of ``cls`` goes through cyclonedds (see above).
    ``header``: a service's request or reply as rmw_cyclonedds_cpp writes it, the request
    header (the client's 8-byte id, the sequence number) before the message's fields."""
    key = cls._DDS + ("+header" if header else "")
    known = _TYPES.get(key)
    if known is not None:
        return known
    fields = {name: _idl(spec) for name, spec in cls._FIELDS.items()}
    if header:
        fields = {"rmw_client_id_": T.uint64, "rmw_sequence_": T.int64, **fields}
    made: Any = make_idl_struct(f"{cls.__name__}_", cls._DDS, fields)

    def serialize(self: Any, *_: Any, **__: Any) -> bytes:
        return bytes(self.__dict__["raw"])

    def deserialize(kind: Any, data: bytes, *_: Any, **__: Any) -> Any:
        sample = object.__new__(kind)
        sample.__dict__["raw"] = bytes(data)
        return sample

    made.serialize = serialize
    made.deserialize = classmethod(deserialize)
    _TYPES[key] = made
    return made


def raw_sample(kind: Any, data: bytes) -> Any:
    """A sample of ``kind`` (from :func:`dds_type`) that writes ``data`` as it is."""
    sample = object.__new__(kind)
    sample.__dict__["raw"] = data
    return sample


def _idl(spec: str) -> Any:
    """rclpy's type string of a field -> the cyclonedds IDL type."""
    m = re.fullmatch(r"sequence<(.+?)(?:, (\d+))?>", spec)
    if m:
        inner = _idl(m[1])
        return T.sequence[inner, int(m[2])] if m[2] else T.sequence[inner]
    m = re.fullmatch(r"(.+)\[(\d+)\]", spec)
    if m:
        return T.array[_idl(m[1]), int(m[2])]
    m = re.fullmatch(r"string<(\d+)>", spec)
    if m:
        return T.bounded_str[int(m[1])]
    if spec in _PRIMITIVES:
        return _PRIMITIVES[spec]
    if spec.count("/") == 2:  # a service's or an action's part, named whole
        return dds_type(message_class(spec))
    pkg, name = spec.split("/")
    return dds_type(message_class(f"{pkg}/msg/{name}"))
