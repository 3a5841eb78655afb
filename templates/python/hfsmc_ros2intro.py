"""The automaton on ROS 2 (SPEC 5.4, docs/ros2.md "The automaton on ROS 2").

A ``ros2`` interface with ``introspection: true`` publishes, from the node it already is:

- ``/fsm_viewer``: the structure and active states as ``yasmin_msgs/msg/StateMachine``,
  the message YASMIN's viewer reads (``machine_message``);
- ``~/hfsm/status``: the monitor's snapshot (schemas/monitor.md) as JSON in a
  ``std_msgs/msg/String``, for ``ros2 topic echo``;

both at 4 Hz and at the end of every instant in which a state was entered or left. Copied
beside a component whose model asks for it; the runtime adds :class:`Introspection` to its
observers (the calls ``start``, ``record``, ``sample``, ``after_instant``, ``close``, all
on the engine's thread). Never under a playback: a replay has no node.
"""

from __future__ import annotations

import contextlib
import json
import time
from typing import Any

from cyclonedds.core import DDSException
from cyclonedds.pub import DataWriter

if __package__:
    from . import hfsmc_ros2_cdr as cdr
    from . import hfsmc_ros2_wire as wire
    from .hfsmc_viewstate import ViewState
else:  # copied beside the generated component, where the modules are top level
    import hfsmc_ros2_cdr as cdr  # type: ignore[import-not-found, no-redef]
    import hfsmc_ros2_wire as wire  # type: ignore[import-not-found, no-redef]
    from hfsmc_viewstate import ViewState  # type: ignore[import-not-found, no-redef]

FSM_VIEWER = "/fsm_viewer"  # YASMIN's topic: absolute, one for every machine
STATUS = "~/hfsm/status"  # the node's own
MACHINE_TYPE = "yasmin_msgs/msg/StateMachine"
STATUS_TYPE = "std_msgs/msg/String"
EVERY_S = 0.25  # 4 Hz: YASMIN's viewer forgets a machine it has not heard of for 3 s
# Records after which the active states may differ: published at the instant's end.
_CHANGES = frozenset({"start", "enter", "exit", "fire", "interrupt", "stop"})


def writers(node: Any, topic: Any) -> dict[str, tuple[Any, Any]]:
    """The node's two writers (``topic`` makes the DDS topic of a settings dict, as the
    node's own publications do): key -> (message class, DataWriter)."""
    out: dict[str, tuple[Any, Any]] = {}
    used = {s["topic"] for s in (*node._subs.values(), *node._pubs.values())}
    for key, name, type_name in (("machine", FSM_VIEWER, MACHINE_TYPE),
                                 ("status", STATUS, STATUS_TYPE)):
        cls = wire.message_class(type_name)
        s = {"topic": wire.resolve_name(name, node.namespace, node.node), "class": cls,
             "qos": wire.qos_of("default")}
        if s["topic"] in used:  # one topic, two writers of the node: the views' own
            raise wire.Ros2Error(f"topic {s['topic']} is the introspection's ({type_name}): "
                                 "the model may not subscribe or publish it")
        out[key] = (cls, DataWriter(node._dp, topic(s), qos=node._qos(s)))
    return out


def machine_name(node: str, namespace: str) -> str:
    """The name the viewer shows (and keys the machine by): the node's, after its
    namespace's parts joined with dots (``tb2.patrol``), as the viewer's URLs take no
    ``/``; two robots' components of one model are then two machines."""
    return ".".join([*[p for p in namespace.split("/") if p], node])


class Tree:
    """The YASMIN view of a component's structure (``Engine.structure()``), computed once:
    states depth first in model order, the component first. A state with a sub-automaton
    (its own or a used file's) is a machine; a state with regions is a machine whose states
    are its regions, each a machine of its own states."""

    def __init__(self, view: ViewState, root_name: str,
                 transitions: list[dict[str, Any]]) -> None:
        self.paths = ["", *view.paths()]
        self.ids = {p: i for i, p in enumerate(self.paths)}
        self.view = view
        self.root_name = root_name
        self.outgoing: dict[str, list[tuple[str, str]]] = {}
        for tr in sorted(transitions, key=lambda t: (str(t["from"]), int(t["index"]))):
            label = str(tr["name"]) if tr.get("name") else f"t{int(tr['index'])}"
            self.outgoing.setdefault(str(tr["from"]), []).append(
                (label, str(tr["to"]).rpartition("/")[2]))

    def parent(self, path: str) -> int:
        return -1 if path == "" else self.ids[path.rpartition("/")[0]]

    def current(self, path: str) -> int:
        """The id of the active state among ``path``'s states; -1 for a state with regions
        (all of them are active: each region says its own) and when none is active."""
        kids = self.view.children[path]
        if path not in self.view.regions and any(k in self.view.regions for k in kids):
            return -1
        for k in kids:
            if k in self.view.active:
                return self.ids[k]
        return -1

    def message(self, machine_cls: Any) -> Any:
        """The StateMachine message of the view's active states now."""
        state_cls = wire.message_class("yasmin_msgs/msg/State")
        transition_cls = wire.message_class("yasmin_msgs/msg/Transition")
        states = []
        for i, p in enumerate(self.paths):
            kids = self.view.children[p]
            out = self.outgoing.get(p, [])
            states.append(state_cls(
                id=i, parent=self.parent(p),
                name=self.root_name if p == "" else p.rpartition("/")[2],
                transitions=[transition_cls(outcome=o, state=s) for o, s in out],
                outcomes=[o for o, _ in out], is_fsm=bool(kids),
                current_state=self.current(p) if kids else -1))
        return machine_cls(states=states)


class Introspection:
    """An observer of the engine that publishes the automaton on the node's writers."""

    def __init__(self, node: Any, writers: dict[str, tuple[Any, Any]]) -> None:
        self.node = node
        self.writers = writers
        self.view = ViewState()
        self.tree: Tree | None = None
        self.name = machine_name(node.node, node.namespace)
        self.changed = False
        self.next = 0.0
        self.said = False

    def start(self, structure: dict[str, Any]) -> None:
        self.view.apply_structure(structure)
        self.tree = Tree(self.view, self.name, list(structure.get("transitions", ())))

    def record(self, rec: dict[str, Any]) -> None:
        self.view.apply_record(rec)
        if rec.get("ev") in _CHANGES:
            self.changed = True

    def sample(self, t_ms: int, values: dict[str, str], overruns: int,
               rate: float | None = None) -> None:
        self.view.apply_sample(t_ms, values, overruns, rate)
        if time.monotonic() >= self.next:
            self.publish()

    def after_instant(self) -> None:
        """At the end of an instant: publish if a state was entered or left in it."""
        if self.changed:
            self.publish()

    def close(self) -> None:
        """The last word: the states the component stopped in, and why."""
        self.publish()

    def publish(self) -> None:
        self.changed = False
        self.next = time.monotonic() + EVERY_S
        if self.tree is None:
            return
        status = {**self.view.snapshot(), "name": self.name}
        machine_cls, _ = self.writers["machine"]
        string_cls, _ = self.writers["status"]
        try:
            self._write("machine", cdr.serialize(self.tree.message(machine_cls)))
            self._write("status", cdr.serialize(string_cls(
                data=json.dumps(status, ensure_ascii=False, separators=(",", ":")))))
        except DDSException as exc:  # the node has left the graph (the component stops)
            if not self.said:
                self.said = True
                with contextlib.suppress(ValueError, OSError):
                    self.node._say(f"introspection: {exc}")

    def _write(self, key: str, data: bytes) -> None:
        _, writer = self.writers[key]
        writer.write(wire.raw_sample(writer.data_type, data))
