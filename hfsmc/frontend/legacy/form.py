"""The neutral legacy form the format readers produce and the assembler maps (docs/legacy.md).

Levels of states (a VisualStates state's children, a VisualHFSM sub-automaton),
the namespaces their code runs in, and the interfaces the file declares, each
with the span it was read at.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hfsmc.errors import Span
from hfsmc.frontend.legacy.code import Mapped, Ref, identifier


@dataclass(eq=False)
class Member:
    """A variable, function or interface of a legacy namespace."""

    name: str  # as the legacy code names it
    kind: str  # variable | function | interface | init (defined by a statement) | implicit
    span: Span
    value: Any = None  # a variable's value (data for the model's `variables`)
    value_span: Span | None = None
    final: str = ""  # its name in the model


@dataclass(eq=False)
class Space:
    """A namespace: the global one (``self.globalNamespace``, VisualHFSM's automaton)
    or the local one of a VisualStates level (``self.namespace``)."""

    owner: str  # the owning state's name ("" for the global namespace): prefix of renamed members
    where: str  # for messages
    span: Span
    functions: list[Mapped] = field(default_factory=list)
    variables: list[Mapped] = field(default_factory=list)
    members: dict[str, Member] = field(default_factory=dict)
    inits: list[Mapped] = field(default_factory=list)  # statements that run at load
    ctx: Context | None = None  # how its own functions name things


@dataclass(eq=False)
class Context:
    """Where each kind of reference looks a name up, in order (see code.Ref)."""

    scopes: dict[str, tuple[Space, ...]]
    state: bool = False  # the code of a state or transition (not a namespace's functions)

    def find(self, ref: Ref) -> Member | None:
        for space in self.scopes.get(ref.scope, ()):
            member = space.members.get(ref.name)
            if member is not None:
                return member
        return None


@dataclass(eq=False)
class Interface:
    candidates: tuple[str, ...]  # the names code may use for it, preferred first
    type: str  # ros_topic | ice
    url: str | None
    options: dict[str, str]
    span: Span
    what: str  # "ROS topic `/odom`" (for messages)
    msg_import: tuple[str, Span] | None = None  # the ROS message type's import
    member: Member | None = None


@dataclass(eq=False)
class Transition:
    span: Span
    name: str | None
    target: LState
    target_span: Span
    after_ms: int | None = None
    after_span: Span | None = None
    cond: Mapped | None = None
    cond_is_body: bool = False  # VisualStates: the body of a function returning a bool
    code: Mapped | None = None


@dataclass(eq=False)
class LState:
    uid: str  # the legacy id
    written: str  # the name as written
    span: Span  # of the name
    code: Mapped | None
    ctx: Context
    transitions: list[Transition] = field(default_factory=list)
    child: Level | None = None
    name: str = ""  # its name in the model


@dataclass(eq=False)
class Level:
    """A sub-automaton: a VisualStates state's children, or a VisualHFSM SubAutomata."""

    span: Span
    states: list[LState] = field(default_factory=list)
    initial: LState | None = None
    initial_span: Span | None = None
    period_ms: int | None = None  # None: the parent's
    period_span: Span | None = None


@dataclass(eq=False)
class Legacy:
    root: Level
    spaces: list[Space]  # the global namespace first
    interfaces: list[Interface]
    libraries: list[tuple[str, Span]]
    history: bool  # what re-entering a composite state does in the legacy tool
    implicit_imports: tuple[str, ...]  # modules the legacy tool's generated code imported
    dropped: list[tuple[Span, str]] = field(default_factory=list)  # for the report
    language: str | None = None  # the code's language when the format fixes it
    language_why: str = ""
    ros_dependencies: list[tuple[str, Span]] = field(default_factory=list)  # ROS packages


def ice_interface(name: str, server: str, proxy: str, ip: str, port: str, kind: str, topic: str,
                  span: Span) -> Interface:
    """A JdeRobot interface: served over ICE (server 1) or ROS (server 2)."""
    ros = server.strip().lower() in ("2", "ros")
    options = {k: v for k, v in (("interface", kind), ("server", server)) if v}
    if ros:
        return Interface((identifier(name, "interface"),), "ros_topic", topic or None, options,
                         span, f"JdeRobot interface `{name}` over ROS")
    endpoint = " ".join(p for p in ("default" if ip or port else "", f"-h {ip}" if ip else "",
                                    f"-p {port}" if port else "") if p)
    url = f"{proxy}:{endpoint}" if proxy and endpoint else (proxy or None)
    if topic:
        options["topic"] = topic
    return Interface((identifier(name, "interface"),), "ice", url, options, span,
                     f"ICE interface `{name}`" + (f" ({kind})" if kind else ""))
