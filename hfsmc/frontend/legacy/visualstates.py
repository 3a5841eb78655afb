"""VisualStates files (JdeRobot VisualStates, every version) into the neutral legacy form.

The format, as VisualStates' own parser reads it: one root ``<state>`` (its
``<timestep>`` is the cycle of its children, its ``<namespace>`` the local
namespace of that level) holding child ``<state>`` elements and the
``<transition>`` elements that leave it; ``<global_namespace>`` (or, in older
files, ``<functions>`` and ``<variables>`` at the top), ``<libraries>`` and an
optional ``<config>`` (ROS topics, or JdeRobot ICE / ROS interfaces).

Unlike VisualStates' parser, only direct children are read (it looked
elements up anywhere below, and so read a child's ``<code>`` when a state had
none), and every missing or malformed element is reported where it is.
"""

from __future__ import annotations

from hfsmc.errors import Span
from hfsmc.frontend.legacy.code import identifier
from hfsmc.frontend.legacy.form import (
    Context,
    Interface,
    Legacy,
    Level,
    LState,
    Member,
    Space,
    Transition,
    ice_interface,
)
from hfsmc.frontend.legacy.levels import LevelStates, find_target, read_period
from hfsmc.frontend.legacy.reader import Reader, norm_id
from hfsmc.frontend.xmlsource import Element

_STATE_SINGLE = ("name", "code", "timestep", "namespace", "functions", "variables")
_TRANSITION_SINGLE = ("type", "time", "condition", "name", "originid", "destinationid", "code")
# Modules VisualStates' generated Python imported for the code (plain JdeRobot and ROS).
_IMPLICIT = ("sys", "threading", "time", "signal", "rospy")


def read(r: Reader, root: Element) -> Legacy | None:
    groups = r.children(root, ("config", "configs", "global_namespace", "functions",
                               "variables", "libraries"), ("state",))
    states = groups.get("state", [])
    if not states:
        r.error("E102", "a VisualStates file needs its root `<state>`", r.span(root))
        return None
    for extra in states[1:]:
        r.error("E003", "a second root `<state>`: a VisualStates file has one root state",
                r.span(extra), f"the root state is on line {r.span(states[0]).line}")
    glob = Space("", "the global namespace", r.span(root))
    ns = r.first(groups, "global_namespace")
    if ns is not None:
        _namespace(r, ns, glob)
    for tag in ("functions", "variables"):  # older files: at the top, no global_namespace
        el = r.first(groups, tag)
        if el is not None:
            (glob.functions if tag == "functions" else glob.variables).append(r.text(el))
    glob.ctx = Context({k: (glob,) for k in ("self", "global", "local", "bare")})
    dropped: list[tuple[Span, str]] = []
    packages: list[tuple[str, Span]] = []
    interfaces = _config(r, r.first(groups, "config"), dropped, packages)
    interfaces += _configs(r, r.first(groups, "configs"))
    libraries = _libraries(r, r.first(groups, "libraries"))
    reader = _States(r, glob, states[0])
    level = reader.root(states[0], dropped)
    dropped.append((r.span(root), "the layout of the diagram (posx, posy)"))
    return Legacy(level, [glob, *reader.spaces], interfaces, libraries, False, _IMPLICIT, dropped,
                  ros_dependencies=packages)


def _namespace(r: Reader, el: Element, space: Space) -> None:
    groups = r.children(el, ("functions", "variables", "parameters"))
    for tag in ("functions", "variables"):
        found = r.first(groups, tag)
        if found is not None:
            (space.functions if tag == "functions" else space.variables).append(r.text(found))
    params = r.first(groups, "parameters")
    if params is not None:
        for p in r.children(params, (), ("param",)).get("param", []):
            _parameter(r, p, space)


# VisualStates' parameter types (core/parameter.py) as model parameter types.
_PARAM_TYPES = {"boolean": "bool", "integer": "int", "float": "float", "string": "str",
                "character": "str"}


def _parameter(r: Reader, el: Element, space: Space) -> None:
    """``<param name type><value/><description/></param>``: a parameter of the model
    (VisualStates let a launch set it; so does `--param`)."""
    name, name_span = r.attr(el, "name")
    kind, kind_span = r.attr(el, "type")
    if not name or not name.strip():
        r.error("E102", "this `<param>` has no `name`", r.span(el))
        return
    g = r.children(el, ("value", "description"))
    value_el, desc_el = r.first(g, "value"), r.first(g, "description")
    text, value_span = r.value(value_el) if value_el is not None else ("", r.span(el))
    typ = _PARAM_TYPES.get((kind or "").strip().lower())
    value: object = text
    try:
        if typ == "bool" and text.lower() in ("true", "false"):
            value = text.lower() == "true"
        elif typ == "int":
            value = int(text)
        elif typ == "float":
            value = float(text)
        elif typ != "str":
            raise ValueError(text)
    except ValueError:
        r.warn("W208", f"parameter `{name}` of type {kind!r} has the value {text!r}: read as "
               "a string", value_span if value_el is not None else kind_span)
        typ, value = "str", text
    data: dict[str, object] = {"type": typ, "default": value}
    if desc_el is not None and r.value(desc_el)[0]:
        data["description"] = r.value(desc_el)[0]
    name = name.strip()
    if name not in space.members:
        space.members[name] = Member(name, "parameter", name_span, data, value_span)


def _libraries(r: Reader, el: Element | None) -> list[tuple[str, Span]]:
    if el is None:
        return []
    out: list[tuple[str, Span]] = []
    for lib in r.children(el, (), ("library",)).get("library", []):
        text, span = r.value(lib)
        if text:
            out.append((text, span))
    return out


# ---------------------------------------------------------------------------
# config: ROS topics, or JdeRobot interfaces


def _config(r: Reader, el: Element | None, dropped: list[tuple[Span, str]],
            packages: list[tuple[str, Span]]) -> list[Interface]:
    if el is None:
        return []
    groups = r.children(el, ("buildDependencies", "runDependencies", "topics", "interfaces"))
    for tag in ("buildDependencies", "runDependencies"):
        deps = r.first(groups, tag)
        if deps is not None:
            listed = [r.value(d) for d in r.children(deps, (), ("dependency",))
                      .get("dependency", [])]
            names = [n for n, _ in listed if n]
            packages += [(n, span) for n, span in listed if n]
            if names:
                dropped.append((r.span(deps), f"ROS {tag} {', '.join(names)}"))
    out: list[Interface] = []
    topics = r.first(groups, "topics")
    if topics is not None:
        for t in r.children(topics, (), ("topic",)).get("topic", []):
            found = _topic(r, t)
            if found is not None:
                out.append(found)
    interfaces = r.first(groups, "interfaces")
    if interfaces is not None:
        for i in r.children(interfaces, (), ("interface",)).get("interface", []):
            found = _jderobot_interface(r, i)
            if found is not None:
                out.append(found)
    return out


def _configs(r: Reader, el: Element | None) -> list[Interface]:
    """``<configs><config>`` (VisualStates' first Python editor, 2017): ICE interfaces."""
    if el is None:
        return []
    out: list[Interface] = []
    for c in r.children(el, (), ("config",)).get("config", []):
        t = _texts(r, c, ("name", "proxyname", "ip", "port", "interface"))
        name, span = t.get("name", ("", r.span(c)))
        if not name:
            r.error("E102", "this `<config>` has no `<name>`", span)
            continue
        proxy, ip, port, kind = (t[k][0] if k in t else ""
                                 for k in ("proxyname", "ip", "port", "interface"))
        out.append(ice_interface(name, "ice", proxy, ip, port, kind, "", r.span(c)))
    return out


def _texts(r: Reader, el: Element, tags: tuple[str, ...]) -> dict[str, tuple[str, Span]]:
    groups = r.children(el, tags)
    out: dict[str, tuple[str, Span]] = {}
    for tag in tags:
        found = r.first(groups, tag)
        if found is not None:
            out[tag] = r.value(found)
    return out


def _topic(r: Reader, el: Element) -> Interface | None:
    """A ROS topic. Code reaches it by its method or variable name; files written before
    those existed use the topic's name, as VisualStates derived it."""
    t = _texts(r, el, ("methodname", "variablename", "name", "type", "opType"))
    name, name_span = t.get("name", ("", r.span(el)))
    if not name:
        r.error("E102", "this ROS topic has no `<name>`", name_span)
        return None
    op, op_span = t.get("opType", ("", r.span(el)))
    if op.lower() not in ("publish", "subscribe"):
        r.error("E103", f"`<opType>` must be Publish or Subscribe, not {op!r}", op_span)
        return None
    publish = op.lower() == "publish"
    var = identifier(name.replace("/", "_").removeprefix("_"), "topic")
    given = t.get("methodname" if publish else "variablename", ("", name_span))[0]
    candidates = (identifier(given, var),) if given else \
        (var, f"publish{var}" if publish else f"get{var}")
    msg = t.get("type")
    options = {"direction": "publish" if publish else "subscribe"}
    if msg is not None and msg[0]:
        options["message"] = msg[0]
    return Interface(candidates, "ros_topic", name, options, r.span(el),
                     f"ROS topic `{name}` ({op.lower()})", msg if msg and msg[0] else None)


def _jderobot_interface(r: Reader, el: Element) -> Interface | None:
    t = _texts(r, el, ("serverType", "name", "topic", "proxyName", "ip", "port", "interfaceName"))
    name, span = t.get("name", ("", r.span(el)))
    if not name:
        r.error("E102", "this interface has no `<name>`", span)
        return None
    return ice_interface(name, t.get("serverType", ("", span))[0], t.get("proxyName", ("", span))[0],
                         t.get("ip", ("", span))[0], t.get("port", ("", span))[0],
                         t.get("interfaceName", ("", span))[0], t.get("topic", ("", span))[0],
                         r.span(el))


# ---------------------------------------------------------------------------
# states and transitions


class _States:
    """The states of the file, read level by level (a state's children are a level)."""

    def __init__(self, r: Reader, glob: Space, root: Element) -> None:
        self.r = r
        self.glob = glob
        self.spaces: list[Space] = []
        # every id in the file, to tell a transition to another level from one to nowhere
        self.everywhere: dict[str, str] = {}
        # Files written before VisualStates had timesteps (and before its editor marked
        # the first state of a level initial) have no <timestep> at all.
        self.timesteps = next(root.iter("timestep"), None) is not None
        for el in root.iter("state"):
            uid = norm_id(el.get("id", ""))
            name = el.find("name")
            self.everywhere.setdefault(uid, (name.text or "").strip() if name is not None else "")

    def root(self, el: Element, dropped: list[tuple[Span, str]]) -> Level:
        r = self.r
        groups = r.children(el, _STATE_SINGLE, ("state", "transition"))
        name_el = r.first(groups, "name")
        name = r.value(name_el)[0] if name_el is not None else ""
        code = r.first(groups, "code")
        if code is not None and r.text(code).text.strip():
            r.warn("W207", "the root state's code is not carried over: an hfsm model's root "
                   "has no code (put it in a state, or in `functions`)", r.value(code)[1])
        for t in groups.get("transition", []):
            r.warn("W207", "a transition of the root state is not carried over: nothing is "
                   "outside the root", r.span(t))
        if name and name != "root":
            dropped.append((r.value(name_el)[1] if name_el is not None else r.span(el),
                            f"the root state's name `{name}`"))
        self.state_namespace(groups)
        space = self.space(el, groups, identifier(name or "root", "root"), ())
        level = self.level(el, groups, (space,), name or "root")
        if not level.states:
            r.error("E102", "the root state has no child `<state>`: nothing to run",
                    r.span(el))
        return level

    def state_namespace(self, groups: dict[str, list[Element]]) -> None:
        """A state's own `<functions>` and `<variables>` (files of 2017, before namespaces):
        VisualStates read them as the file's, the global namespace."""
        for tag in ("functions", "variables"):
            found = self.r.first(groups, tag)
            if found is not None and self.r.text(found).text.strip():
                into = self.glob.functions if tag == "functions" else self.glob.variables
                into.append(self.r.text(found))
                self.r.note(self.r.span(found), f"`<{tag}>` of a state read as the file's "
                            f"{tag} (the global namespace), as VisualStates read them then")

    def space(self, el: Element, groups: dict[str, list[Element]], owner: str,
              chain: tuple[Space, ...]) -> Space:
        """The namespace of the level the state ``el`` owns (``self.namespace`` there)."""
        space = Space(owner, f"the namespace of state `{owner}`", self.r.span(el))
        ns = self.r.first(groups, "namespace")
        if ns is not None:
            _namespace(self.r, ns, space)
            space.span = self.r.span(ns)
        up = (space, *chain, self.glob)
        space.ctx = Context({"self": up, "local": up, "global": (self.glob, space, *chain),
                             "bare": (space,)})
        self.spaces.append(space)
        return space

    def level(self, owner: Element, groups: dict[str, list[Element]], chain: tuple[Space, ...],
              owner_name: str) -> Level:
        r = self.r
        level = Level(r.span(owner))
        step = r.required(groups, "timestep", owner, f"state `{owner_name}`") \
            if self.timesteps else None
        read_period(r, level, step, "timestep")
        states = LevelStates(r, level, f"among the children of `{owner_name}`",
                             f"`{owner_name}`", ", as VisualStates did")
        pending: list[tuple[LState, list[Element]]] = []
        for kid in groups.get("state", []):
            s, transitions = self.state(kid, chain)
            first = states.by_id.get(s.uid)
            states.add(s, r.attr(kid, "id")[1], kid, "initial",
                       *([f"`{first.written}` has it too"] if first is not None else []))
            pending.append((s, transitions))
        for s, transitions in pending:
            for t in transitions:
                found = self.transition(t, s, states.by_id, owner_name)
                if found is not None:
                    s.transitions.append(found)
        if level.states and level.initial is None and not self.timesteps:
            level.initial, level.initial_span = level.states[0], r.span(owner)
            r.warn("W208", f"no child of `{owner_name}` is initial: it starts at its first "
                   f"child, `{level.states[0].written}` (this file predates timesteps and "
                   "initial marks; VisualStates' editor made the first state of a level "
                   "initial)", r.span(owner))
        elif level.states and level.initial is None:
            r.error("E130", f"no child of `{owner_name}` is initial", r.span(owner),
                    f"mark one of {', '.join(s.written for s in level.states)} "
                    "with initial=\"True\"")
        return level

    def state(self, el: Element, chain: tuple[Space, ...]) -> tuple[LState, list[Element]]:
        r = self.r
        groups = r.children(el, _STATE_SINGLE, ("state", "transition"))
        uid, uid_span = r.attr(el, "id")
        if uid is None or not uid.strip():
            r.error("E102", "this state has no `id`", uid_span)
        name_el = r.required(groups, "name", el, "this state")
        written, name_span = r.value(name_el) if name_el is not None else ("", r.span(el))
        if name_el is not None and not written:
            r.error("E103", "this state's `<name>` is empty", name_span)
        what = f"state `{written}`" if written else "this state"
        code_el = r.required(groups, "code", el, what)
        code = r.text(code_el) if code_el is not None else None
        self.state_namespace(groups)
        own = self.space(el, groups, identifier(written, "state"), chain)
        # A bare `self.x` (the state object in VisualStates) looks in the namespaces too.
        ctx = Context({"local": (*chain, self.glob, own), "global": (self.glob, *chain, own),
                       "self": (*chain, self.glob, own)}, state=True)
        s = LState(norm_id(uid or ""), written, name_span, code, ctx)
        if groups.get("state"):
            s.child = self.level(el, groups, (own, *chain), written)
        elif r.first(groups, "timestep") is not None:
            step = r.first(groups, "timestep")
            assert step is not None
            r.milliseconds(step, "timestep", "E110")  # unused without children, still checked
        elif self.timesteps:
            r.required(groups, "timestep", el, what)
        return s, groups.get("transition", [])

    def transition(self, el: Element, source: LState, siblings: dict[str, LState],
                   owner_name: str) -> Transition | None:
        r = self.r
        g = r.children(el, _TRANSITION_SINGLE)
        dest = r.required(g, "destinationid", el, "this transition")
        if dest is None:
            return None
        uid, dest_span = r.value(dest)
        target = find_target(r, source, uid, dest_span, siblings, self.everywhere,
                             lambda other: f" (`{other}`), which is not a child of "
                             f"`{owner_name}`: transitions join siblings only",
                             list_states=True)
        if target is None:
            return None
        origin = r.first(g, "originid")
        if origin is not None and norm_id(r.value(origin)[0]) != source.uid:
            r.warn("W208", f"originid {r.value(origin)[0]} is not the id of `{source.written}`, "
                   "the state this transition is written in: it leaves that state",
                   r.value(origin)[1])
        name_el = r.first(g, "name")
        name = r.value(name_el)[0] if name_el is not None else ""
        code_el = r.first(g, "code")
        t = Transition(r.span(el), name or None, target, dest_span,
                       code=r.text(code_el) if code_el is not None else None)
        kind = self.kind(g, el)
        if kind == "0":
            time_el = r.required(g, "time", el, "this temporal transition")
            if time_el is not None:
                t.after_ms, t.after_span = r.milliseconds(time_el, "time")
        elif kind == "1":
            cond = r.required(g, "condition", el, "this conditional transition")
            if cond is not None:
                t.cond, t.cond_is_body = r.text(cond), True
                if not t.cond.text.strip():
                    r.error("E137", "this conditional transition's `<condition>` is empty",
                            r.span(cond), "write the body of a function that returns a bool")
        else:
            return None
        return t

    def kind(self, g: dict[str, list[Element]], el: Element) -> str | None:
        """0 temporal, 1 conditional; told by what is there when `<type>` is missing."""
        r = self.r
        type_el = r.first(g, "type")
        if type_el is None:
            if "condition" in g or "time" in g:
                return "1" if "condition" in g else "0"
            r.error("E102", "this transition has no `<type>` (0 temporal, 1 conditional)",
                    r.span(el))
            return None
        value, span = r.value(type_el)
        if value not in ("0", "1"):
            r.error("E103", f"transition `<type>` must be 0 (temporal) or 1 (conditional), "
                    f"not {value!r}", span)
            return None
        return value

