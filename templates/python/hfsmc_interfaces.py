# hfsmc_interfaces.py: how a Python component makes its interfaces (docs/drivers.md).
# Copied unchanged into every component folder; standard library only.
"""The one seam between the runtime and the drivers.

Every interface type is a driver module: the built-in ones (``hfsmc_mavlink``,
``hfsmc_camera``) and a model's own (``type: driver``: a module holding one class
deriving from ``hfsmc_driver.Driver``, named in the component's ``drivers`` table). The
runtime asks this module for each interface: the live driver (``connect``), or with
``--playback`` its fake fed from the script, hooked to the recording and the playback
(its commands, a camera's frames). A driver's snapshot is taken by the engine when an
instant begins (``snapshot()``), and recorded with the driver's schema.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NoReturn

# The built-in drivers: interface type -> module (beside the component).
BUILTIN = {"mavlink": "hfsmc_mavlink", "camera": "hfsmc_camera", "ros2": "hfsmc_ros2"}
# The built-in drivers made as a user's driver is (hfsmc_driver.Driver): module, class.
BUILTIN_CLASSES = {"camera": ("hfsmc_camera", "Camera"), "mavlink": ("hfsmc_mavlink", "Vehicle")}
# What to install for a module a driver imports (pip names; Debian: python3-opencv etc.).
_INSTALL = {"pymavlink": "pymavlink", "cv2": "opencv-python-headless", "numpy": "numpy",
            "serial": "pyserial", "cyclonedds": "cyclonedds"}
# A ros2 interface's settings that the configuration file may change without a rebuild,
# and those it may only repeat (the generated messages depend on them: docs/ros2.md).
ROS2_CHANGEABLE = ("node", "namespace", "domain")
ROS2_FIXED = ("type", "distro")
ROS2_TOPIC_CHANGEABLE = ("topic", "qos")
ROS2_RPC_CHANGEABLE = ("name", "timeout")  # an action's or a service's


class UsageError(Exception):
    """A bad flag or configuration: exit status 2."""


class StartError(Exception):
    """The component cannot start (a library an interface needs is missing): exit status 1."""


class Unavailable:
    """An interface this component cannot drive: fails when used, not at start."""

    def __init__(self, name: str, why: str) -> None:
        object.__setattr__(self, "_why", f"interface `{name}`: {why}")

    def __getattr__(self, attr: str) -> NoReturn:
        raise RuntimeError(object.__getattribute__(self, "_why"))

    def __setattr__(self, attr: str, value: object) -> NoReturn:
        raise RuntimeError(object.__getattribute__(self, "_why"))

    def __call__(self, *args: object, **kwargs: object) -> NoReturn:
        raise RuntimeError(object.__getattribute__(self, "_why"))

    def __bool__(self) -> NoReturn:
        raise RuntimeError(object.__getattribute__(self, "_why"))

    def __iter__(self) -> NoReturn:
        raise RuntimeError(object.__getattribute__(self, "_why"))

    def __repr__(self) -> str:
        return f"<unavailable: {object.__getattribute__(self, '_why')}>"


def _import(name: str, kind: str, module: str) -> Any:
    try:
        return __import__(module)
    except ImportError as e:  # the driver's library, or one its URL needs (pyserial)
        missing = getattr(e, "name", None) or "?"
        top = missing.partition(".")[0]
        how = f"pip install {_INSTALL[top]}" if top in _INSTALL else f"install `{top}`"
        raise StartError(f"interface `{name}` ({kind}) needs the Python module `{missing}`, "
                         f"which is not installed: {how}") from None


def make_interface(name: str, kind: str, url: str | None, options: dict[str, str],
                   sim: Any = None, drivers: dict[str, tuple[str, str]] | None = None) -> object:
    """The driver object of an interface, by type.

    A driver whose library is missing (pymavlink, OpenCV) stops the component at
    start with what to install, rather than at the first call of a snippet.
    """
    own = (drivers or {}).get(kind) or BUILTIN_CLASSES.get(kind)
    if kind not in BUILTIN and own is None:
        return Unavailable(name, f"interfaces of type `{kind}` are kept from a legacy model "
                                 "but hfsmc components cannot drive them")
    module = _import(name, kind, BUILTIN[kind] if own is None else own[0])
    if kind == "ros2":  # its settings are a table, not a URL (docs/ros2.md); exits 2 itself
        made: object = module.connect(name, options)
        if sim is not None:  # it follows the simulator's time (hfsmc_ros2_lockstep)
            sim.drivers.append(made)
        return made
    try:
        factory: Callable[..., object] = (module.connect if own is None
                                          else getattr(module, own[1]).connect)
        if sim is None:
            return factory(name, url, options)
        if own is not None and not getattr(module, own[1]).LOCKSTEP:  # on the wall clock
            return factory(name, url, options)
        driver = factory(name, url, options, sim)
        sim.drivers.append(driver)
        return driver
    except ImportError as e:  # a library the driver imports late (a URL's: pyserial)
        missing = getattr(e, "name", None) or "?"
        top = missing.partition(".")[0]
        how = f"pip install {_INSTALL[top]}" if top in _INSTALL else f"install `{top}`"
        raise StartError(f"interface `{name}` ({kind}) needs the Python module `{missing}`, "
                         f"which is not installed: {how}") from None
    except Exception as e:  # a URL the driver's library refuses (a port out of range)
        raise StartError(f"interface `{name}` ({kind}): cannot open `{url}`: "
                         f"{type(e).__name__}: {e}") from None


def make_fake(engine: Any, name: str, kind: str, url: str | None,
              options: dict[str, str]) -> object | None:
    """With --playback: the interface's fake fed from the script (None: a type that has
    none, which stays Unavailable)."""
    import hfsmc_playback  # type: ignore[import-not-found]  # beside the component

    own = engine.m.get("drivers", {}).get(kind)
    try:
        if own is None:
            made: object | None = engine.playback.fake(name, kind, options)
            return made
        cls = getattr(_import(name, kind, own[0]), own[1])
        try:
            fake = cls.fake(name, url, options, engine.playback)
        except Exception as e:  # an option the driver refuses
            raise StartError(f"interface `{name}` ({kind}): {type(e).__name__}: {e}") from None
        adopted: object = engine.playback.adopt(name, fake)
        return adopted
    except hfsmc_playback.PlaybackError as e:
        raise UsageError(f"--playback: {e}") from None


def wire(engine: Any, wired: dict[str, Any]) -> None:
    """Make every interface of the model, as the configuration file wires it."""
    m = engine.m
    ns = m["namespace"]
    for name, kind, url, options in m["interfaces"]:
        given = wired.get(name) or {}
        if kind == "ros2":
            merged = ros2_settings(name, options, given)
        else:
            merged = {**options, **(given.get("options") or {})}
        where = given.get("url", url)
        kind = str(given.get("type", kind))
        where = None if where is None else str(where)
        engine.wiring[name] = {"type": kind, "url": where, "options": merged}
        fake = (make_fake(engine, name, kind, where, merged) if engine.playback is not None
                else None)
        ns[name] = fake if fake is not None else make_interface(
            name, kind, where, merged, engine.sim, m.get("drivers"))
        if callable(getattr(type(ns[name]), "snapshot", None)):  # not Unavailable's __getattr__
            engine.inputs.append((name, kind, ns[name]))


def ros2_settings(name: str, built: dict[str, Any], given: dict[str, Any]) -> dict[str, Any]:
    """A ros2 interface's settings: the model's (``built``), with what the configuration
    file changes (``given``: node, namespace, domain, each topic's name and QoS). A type or
    a distro other than the model's, or a topic the model does not declare, needs a
    rebuild (the messages are generated for them): UsageError."""
    where = f"the configuration of interface `{name}`"
    out = {**built, **{key: {k: dict(v) for k, v in built.get(key, {}).items()}
                       for key in ("subscribe", "publish", "actions", "services")}}
    for key, value in given.items():
        if key in ROS2_CHANGEABLE:
            out[key] = value
        elif key in ROS2_FIXED:
            if value != (built.get(key) if key != "type" else "ros2"):
                raise UsageError(f"{where}: `{key}: {value}` differs from the model's "
                                 f"({built.get(key, 'ros2')}): change the model and rebuild")
        elif key in ("subscribe", "publish"):
            if not isinstance(value, dict):
                raise UsageError(f"{where}: `{key}` maps names to {{topic, qos}}")
            for entry, spec in value.items():
                _ros2_topic(where, key, entry, spec, out[key])
        elif key == "introspection":  # may be turned off; on needs its messages generated
            if value not in (True, False):
                raise UsageError(f"{where}: `introspection: {value}`: true or false")
            if value and not built.get("introspection"):
                raise UsageError(f"{where}: `introspection: true`: the model does not ask for "
                                 "it (its messages are not generated): change the model and "
                                 "rebuild")
            out[key] = value
        elif key in ("actions", "services"):
            if not isinstance(value, dict):
                raise UsageError(f"{where}: `{key}` maps names to {{name, timeout}}")
            for entry, spec in value.items():
                _ros2_rpc(where, key, entry, spec, out[key])
        elif key not in ("url", "options") or given[key]:
            raise UsageError(f"{where}: `{key}` is not a setting of a ros2 interface "
                             f"(the file may change {', '.join(ROS2_CHANGEABLE)}, turn "
                             "introspection off, and each topic's topic and qos)")
    return out


def _ros2_rpc(where: str, key: str, entry: str, spec: Any, table: dict[str, Any]) -> None:
    """An action's or a service's ROS name and time limit (s) may change; its type not."""
    if entry not in table or not isinstance(spec, dict):
        raise UsageError(f"{where}: `{key}.{entry}`: the model has {', '.join(table) or 'none'}"
                         " ({name, type, timeout} each): change the model and rebuild")
    for k, v in spec.items():
        if k in ROS2_RPC_CHANGEABLE:
            table[entry][k] = v
        elif k != "type" or v != table[entry]["type"]:
            raise UsageError(f"{where}: `{key}.{entry}.{k}: {v}`: only name and timeout may "
                             "change without a rebuild")


def _ros2_topic(where: str, key: str, entry: str, spec: Any, table: dict[str, Any]) -> None:
    if entry not in table:
        raise UsageError(f"{where}: `{key}` has no `{entry}` in the model "
                         f"({', '.join(table) or 'none'}): add it to the model and rebuild")
    if not isinstance(spec, dict):
        raise UsageError(f"{where}: `{key}.{entry}` is {{topic, type, qos}}")
    for k, v in spec.items():
        if k in ROS2_TOPIC_CHANGEABLE:
            table[entry][k] = v
        elif k == "type":
            if v != table[entry]["type"]:
                raise UsageError(f"{where}: `{key}.{entry}.type: {v}` differs from the "
                                 f"model's ({table[entry]['type']}): change the model and "
                                 "rebuild")
        else:
            raise UsageError(f"{where}: `{key}.{entry}.{k}`: a topic has topic, type and qos")


def hook(engine: Any, name: str, iface: Any) -> None:
    """Tell the recording and the playback what the snippets do with an interface."""
    rec, pb = engine.recorder, engine.playback
    if rec is not None and hasattr(iface, "on_frame"):
        iface.on_frame = lambda count, image, jpeg: rec.frame(engine.t, name, count, image, jpeg)
    if rec is not None and callable(getattr(type(iface), "snapshot_schema", None)):
        rec.declare(getattr(type(iface), "KIND", ""), iface.snapshot_schema())
    if hasattr(iface, "on_command"):
        def told(call: str, args: list[Any]) -> None:
            if rec is not None:
                rec.command(engine.t, name, call, args)
            if pb is not None:
                pb.command(engine.t, name, call, args)
        iface.on_command = told
