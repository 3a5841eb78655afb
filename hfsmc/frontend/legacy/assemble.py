"""The neutral legacy form mapped onto the plain data of a version-1 model, with spans.

:class:`Assembler` writes the keys a YAML model would have (imports,
interfaces, variables, functions, period, initial, states...) with a span
for every value and key, and each code text with the
:meth:`~.code.Mapped.segments` that put any of its characters back in
the legacy file.  Code is converted on the way: namespace prefixes dropped,
members renamed, ``self`` parameters dropped, ``global`` declared where a
function assigns a module-level name, and conditions written as function
bodies turned into helper functions.  The report of what was done goes to
``Document.notes``.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hfsmc.errors import Span
from hfsmc.frontend.legacy.code import (
    WEAK_PREFIXES,
    Mapped,
    Pos,
    add_globals,
    block,
    cpp_is_expression,
    drop_self_params,
    edit,
    guess_language,
    identifier,
    indent_lines,
    join,
    mask,
    parses,
    python_defs,
    references,
    single_return,
)
from hfsmc.frontend.legacy.form import (
    Context,
    Interface,
    Legacy,
    Level,
    LState,
    Member,
    Space,
    Transition,
)
from hfsmc.frontend.legacy.names import TF_EULER, Names
from hfsmc.frontend.legacy.reader import Reader
from hfsmc.frontend.source import PathKey
from hfsmc.ir import DEFAULT_ROOT_PERIOD_MS
from hfsmc.ros2.definitions import ros2_type_name


@dataclass(frozen=True, slots=True)
class _Converted:
    text: Mapped
    stores: dict[int, Member]  # offset in the text -> member assigned there
    refs: dict[int, Member]  # offset in the text -> member named there


_COMMENT = {"python": "#", "cpp": "//"}


_ROSPY = re.compile(r"(?<![\w.])rospy\s*\.\s*([A-Za-z_][\w.]*)")
_ROSPY_INSTEAD = {
    "loginfo": "`log(msg)`", "logwarn": "`log(msg)`", "logerr": "`log(msg)`",
    "logdebug": "`log(msg)`", "Time": "`now()` (seconds since the component started)",
    "get_time": "`now()`", "sleep": "a timed transition (`after:`) instead of sleeping",
    "Rate": "the state's `period`", "is_shutdown": "`shutdown()` to stop; it never is",
    "Publisher": "a `publish` entry of the ros2 interface",
    "Subscriber": "a `subscribe` entry of the ros2 interface",
}


class Assembler(Names):
    """The neutral form as the plain data of a version-1 model, with spans."""

    def __init__(self, reader: Reader, legacy: Legacy) -> None:
        super().__init__(reader, legacy)
        self.doc = reader.doc
        self.root_span = reader.doc.span(())
        self.why = ""  # how the language was told
        self.helpers: list[Mapped] = []  # condition functions
        self.counts = {"global": 0, "local": 0, "self": 0}  # prefixes dropped
        self.selfs: set[tuple[Pos, str]] = set()  # (text, name) of `self.x` in state code, warned
        self.said: set[Span] = set()  # W221 given here

    # -- the whole model -------------------------------------------------------
    def model(self) -> dict[str, Any]:
        lg = self.legacy
        if lg.language in ("python", "cpp"):
            self.language = "cpp" if lg.language == "cpp" else "python"
            self.why = lg.language_why
        else:
            self.language, self.why = guess_language(self._texts_for_language())
        for space in lg.spaces:
            self._read_space(space)
        d: dict[str, Any] = {}
        self._put(d, ("hfsm",), 1, self.root_span)
        name = identifier(Path(self.doc.file).stem, "model")
        self._put(d, ("name",), name, self.root_span)
        if name != Path(self.doc.file).stem:
            self.r.note(self.root_span, f"name: `{name}`, from the file name")
        self._put(d, ("language",), self.language, self.root_span)
        self._put(d, ("description",), f"Converted from the {self.r.kind} file "
                  f"{Path(self.doc.file).name}.", self.root_span)
        imports = self._imports()
        self._interfaces()
        self._implicit_members()
        self._name_members()
        self.ros2_names()
        self._name_states(lg.root, "")
        if imports:
            self._put(d, ("imports",), [t for t, _ in imports], imports[0][1])
            for i, (_, span) in enumerate(imports):
                self._put_span(("imports", i), span, span)
        self._interface_data(d)
        self._variable_data(d, "parameter", "parameters")
        self._variable_data(d)
        states = self._level(lg.root, (), d, None)
        self._functions_data(d)
        self._report(states)
        return d

    def _put(self, d: dict[str, Any], path: PathKey, value: Any, span: Span,
             key: Span | None = None) -> None:
        d[str(path[-1])] = value
        self._put_span(path, key or span, span)

    def _put_span(self, path: PathKey, key: Span, value: Span) -> None:
        self.doc.key_spans[path] = key
        self.doc.spans[path] = value

    def _put_code(self, d: dict[str, Any], path: PathKey, m: Mapped, key: Span) -> None:
        if "\n" in m.text and not m.text.endswith("\n"):  # as a YAML `|` block ends
            m = join([m, Mapped.synth("\n", m.at(len(m.text)))], m.start)
        self._put(d, path, m.text, self.r.to_span(m.start), key)
        self.doc.segments[path] = m.segments()

    def _texts_for_language(self) -> Iterator[tuple[str, bool]]:
        for space in self.legacy.spaces:
            for m in (*space.functions, *space.variables):
                yield m.text, False
        for s in self._states(self.legacy.root):
            if s.code is not None:
                yield s.code.text, False
            for t in s.transitions:
                if t.cond is not None:
                    yield t.cond.text, t.cond_is_body
                if t.code is not None:
                    yield t.code.text, False

    # -- code ------------------------------------------------------------------
    def _convert(self, m: Mapped, ctx: Context) -> _Converted:
        """Namespace prefixes dropped and members renamed; what the code assigns.

        C++ code names the members of its own namespace bare: those renamed are
        renamed there too."""
        m = self._ros1_calls(m)
        bare_names: frozenset[str] = frozenset()
        if self.language == "cpp":
            bare_names = frozenset(n for s in ctx.scopes.get("bare", ())
                                   for n, mem in s.members.items() if mem.final != n)
        edits: list[tuple[int, int, Mapped]] = []
        stores: dict[int, Member] = {}
        named: dict[int, Member] = {}
        shift = 0
        for ref in references(m.text, self.language, bare_names):
            member = ctx.find(ref)
            if member is None and (ref.scope == "bare" or ref.scope not in ctx.scopes
                                   or m.text[ref.start:ref.end].split("-")[0].strip()
                                   in WEAK_PREFIXES):
                continue  # a name of no namespace: left for the checks to point at
            if ctx.state and ref.scope == "self" and member is not None \
                    and member.kind != "implicit" and (m.start, member.name) not in self.selfs:
                self.selfs.add((m.start, member.name))
                self.r.warn("W208", f"`self.{ref.name}` in the code of a state or transition: "
                            f"{self.r.kind} looked it up on the object running that code; read as "
                            f"the namespace member `{member.final}`",
                            self.r.to_span(m.at(ref.start)))
            new = member.final if member is not None else ref.name
            if ref.scope in self.counts:
                self.counts[ref.scope] += 1
            written = m.text[ref.start:ref.end]
            tail = ref.start + len(written) - len(ref.name)
            repl = m.cut(tail, ref.end) if new == ref.name else Mapped.synth(new, m.at(tail))
            edits.append((ref.start, ref.end, repl))
            if member is not None:
                named[ref.start + shift] = member
                if ref.store:
                    stores[ref.start + shift] = member
            shift += len(new) - (ref.end - ref.start)
        return _Converted(edit(m, edits), stores, named)

    def _ros1_calls(self, m: Mapped) -> Mapped:
        """ROS 1 calls of Python code that have no ROS 2 equivalent in a component: tf's
        euler_from_quaternion becomes hfsmc's helper of that name (W221, same result);
        rospy's are named with what to write instead (W221), and left as they are."""
        if self.language != "python":
            return m
        masked = mask(m.text, "python")
        edits = []
        for found in TF_EULER.finditer(masked):
            at = self.r.to_span(m.at(found.start()))
            if at not in self.said:
                self.said.add(at)
                self.r.warn("W221", "`tf.transformations.euler_from_quaternion` (ROS 1's tf, "
                            "not in ROS 2) replaced by hfsmc's helper `euler_from_quaternion` "
                            "(the same roll, pitch and yaw; `yaw_of(q)` gives the yaw alone)", at)
            edits.append((found.start(), found.end(),
                          Mapped.synth("euler_from_quaternion", m.at(found.start()))))
        for found in _ROSPY.finditer(masked):
            at = self.r.to_span(m.at(found.start()))
            if at not in self.said:
                self.said.add(at)
                call = found.group(1)
                instead = _ROSPY_INSTEAD.get(call.split(".")[0],
                                             "nothing: the component runs the automaton itself")
                self.r.warn("W221", f"`rospy.{call}` has no equivalent in an hfsmc component "
                            f"(no rospy in ROS 2): write {instead}", at)
        return edit(m, edits) if edits else m

    def _rename_locals(self, m: Mapped) -> Mapped:
        """Bare names of legacy Python code that are now also module-level names of the
        model (``odom = self.odom`` in a function): renamed ``NAME_local`` (W206).

        In the legacy code a bare name was always a local (namespace members were
        reached through ``self.``); once prefixes are dropped, a local and a member of
        one name would be one name (``odom = odom`` does not even run)."""
        if self.language != "python" or not m.text:
            return m
        try:
            tree = ast.parse(m.text)
        except (SyntaxError, ValueError, MemoryError, RecursionError):
            return m
        module = {mem.final for space in self.legacy.spaces for mem in space.members.values()}
        rows = m.text.split("\n")
        starts = [0]
        for row in rows:
            starts.append(starts[-1] + len(row) + 1)
        hits: list[tuple[int, str]] = []
        for node in ast.walk(tree):
            name = node.id if isinstance(node, ast.Name) else \
                node.arg if isinstance(node, ast.arg) else None
            if name is None or name not in module or name == "self":
                continue
            assert isinstance(node, ast.Name | ast.arg)
            row = rows[node.lineno - 1]
            col = len(row.encode("utf-8")[:node.col_offset].decode("utf-8", "replace"))
            hits.append((starts[node.lineno - 1] + col, name))
        if not hits:
            return m
        edits: list[tuple[int, int, Mapped]] = []
        warned: set[str] = set()
        for off, name in sorted(hits):
            new = f"{name}_local"
            while new in module:
                new += "_"
            edits.append((off, off + len(name), join(
                [m.cut(off, off + len(name)), Mapped.synth(new[len(name):], m.at(off + len(name)))],
                m.at(off))))
            if name not in warned:
                warned.add(name)
                self.renames += 1
                self.r.warn("W206", f"`{name}`, a local name of this code in {self.r.kind}, "
                            f"renamed `{new}`: the model also has `{name}` at module level, "
                            "and in one module they would be one name",
                            self.r.to_span(m.at(off)), "every use of the local is renamed too")
        return edit(m, edits)

    def _snippet(self, m: Mapped | None, ctx: Context) -> Mapped | None:
        """State or transition code: a snippet that declares what it assigns at module level."""
        if m is None:
            return None
        m = block(m)
        if not m.text:
            return None
        conv = self._convert(self._rename_locals(m), ctx)
        names = sorted({mem.final for mem in conv.stores.values() if mem.kind != "variable"})
        if names and self.language == "python":
            return join([Mapped.synth(f"global {', '.join(names)}\n", m.start), conv.text],
                        m.start)
        return conv.text

    def _condition(self, t: Transition, source: LState) -> Mapped:
        cond = block(t.cond) if t.cond is not None else Mapped.synth("", self.r.pos(t.span))
        conv = self._convert(self._rename_locals(cond), source.ctx)
        text = conv.text
        lang = self.language
        expression = parses(text.text, "eval") if lang == "python" else cpp_is_expression(text)
        if not t.cond_is_body and expression:
            return text.strip()
        expr = single_return(text, lang)
        if expr is not None:
            return expr
        if t.cond_is_body and expression:
            self.r.warn("W208", f"this condition has no `return`: {self.r.kind} ran it as a "
                        "function body, so the transition never fired; hfsmc reads it as the "
                        "expression it is", self.r.to_span(text.start))
            return text.strip()
        if not t.cond_is_body and not re.search(r"\breturn\b", mask(text.text, lang)):
            return text.strip()  # an expression that does not parse: the check says where
        label = t.name or f"{source.name}_{t.target.name}"
        name = self._unique(f"cond_{identifier(label, 'transition')}")
        at = cond.start
        if lang == "python":
            body = indent_lines(text, "    ", "python")
            stores = sorted({mem.final for mem in conv.stores.values()})
            head = f"def {name}():\n" + (f"    global {', '.join(stores)}\n" if stores else "")
            parts = [Mapped.synth(head, at), body]
        else:
            parts = [Mapped.synth(f"bool {name}() {{\n", at), indent_lines(text, "    ", "cpp"),
                     Mapped.synth("\n}", text.at(len(text)))]
        self.helpers.append(join(parts, at))
        self.r.note(self.r.to_span(at), f"the condition of `{source.name}` -> `{t.target.name}` "
                    f"is a function body: it became the function `{name}` and `when: {name}()`")
        return Mapped.synth(f"{name}()", at)

    def _function_text(self, f: Mapped, space: Space) -> Mapped:
        """A namespace's functions: members renamed, prefixes and `self` parameters dropped,
        ``global`` declared where a function assigns a module-level name."""
        assert space.ctx is not None
        if self.language == "python":
            f = drop_self_params(f)
            renames = [(off, len(n), space.members[n].final) for n, off, _ in python_defs(f.text)
                       if n in space.members and space.members[n].final != n]
            f = edit(f, [(off, off + size, Mapped.synth(new, f.at(off)))
                         for off, size, new in renames])
        conv = self._convert(self._rename_locals(f), space.ctx)
        if self.language != "python":
            return conv.text
        return add_globals(conv.text, {off: m.final for off, m in conv.stores.items()})

    # -- the sections of the model -------------------------------------------
    def _interface_data(self, d: dict[str, Any]) -> None:
        if not self.legacy.interfaces:
            return
        out: dict[str, Any] = {}
        self._put(d, ("interfaces",), out, self.legacy.interfaces[0].span)
        topics = [i for i in self.legacy.interfaces if self.ros2_topic(i)]
        if topics:
            self._ros2_data(out, topics)
        for itf in self.legacy.interfaces:
            if itf in topics:
                continue
            assert itf.member is not None
            path: PathKey = ("interfaces", itf.member.final)
            spec: dict[str, Any] = {}
            self._put(out, path, spec, itf.span)
            self._put(spec, (*path, "type"), itf.type, itf.span)
            if itf.url is not None:
                self._put(spec, (*path, "url"), itf.url, itf.span)
            if itf.options:
                opts: dict[str, Any] = {}
                self._put(spec, (*path, "options"), opts, itf.span)
                for k, v in itf.options.items():
                    self._put(opts, (*path, "options", k), v, itf.span)

    def _ros2_data(self, out: dict[str, Any], topics: list[Interface]) -> None:
        """The VisualStates topics as one `ros2` interface (SPEC 5.2): ROS 1 type names
        become ROS 2's; subscriptions take the sensor-data QoS (best effort), which matches
        every publisher, as a ROS 1 subscriber matched every publisher."""
        base: PathKey = ("interfaces", self.ros_member.final)
        spec: dict[str, Any] = {}
        self._put(out, base, spec, topics[0].span)
        self._put(spec, (*base, "type"), "ros2", topics[0].span)
        for direction in ("subscribe", "publish"):
            mine = [i for i in topics if i.options["direction"] == direction]
            if not mine:
                continue
            table: dict[str, Any] = {}
            self._put(spec, (*base, direction), table, mine[0].span)
            for itf in mine:
                assert itf.member is not None and itf.url is not None
                name = itf.member.final.rpartition(".")[2].partition(" ")[0]
                path: PathKey = (*base, direction, name)
                entry: dict[str, Any] = {}
                self._put(table, path, entry, itf.span)
                self._put(entry, (*path, "topic"), itf.url, itf.span)
                self._put(entry, (*path, "type"), ros2_type_name(itf.options["message"]),
                          itf.span)
                if direction == "subscribe":
                    self._put(entry, (*path, "qos"), "sensor_data", itf.span)

    def _publishers(self) -> list[Mapped]:
        """A function per publication, named as the legacy code called it."""
        out = []
        for itf in self.legacy.interfaces:
            if self.ros2_topic(itf) and itf.options["direction"] == "publish":
                assert itf.member is not None
                name = itf.member.final
                out.append(Mapped.synth(f"def {name}(msg):\n    {self.ros_member.final}.publish("
                                        f"{name!r}, msg)\n", self.r.pos(itf.span)))
        return out

    def _variable_data(self, d: dict[str, Any], kind: str = "variable",
                       section: str = "variables") -> None:
        out: dict[str, Any] = {}
        for space in self.legacy.spaces:
            for member in space.members.values():
                if member.kind == kind:
                    path: PathKey = (section, member.final)
                    value_span = member.value_span or member.span
                    self._put(out, path, member.value, value_span, member.span)
                    if isinstance(member.value, dict):
                        for k in member.value:
                            self._put_span((*path, k), value_span, value_span)
        if out:
            first = next(iter(out))
            self._put(d, (section,), out, self.doc.key_span((section, first)))

    def _functions_data(self, d: dict[str, Any]) -> None:
        c = _COMMENT[self.language]
        parts: list[Mapped] = []

        def section(title: str, at: Pos, texts: list[Mapped]) -> None:
            if texts:
                if parts:
                    parts.append(Mapped.synth("\n\n", at))
                parts.append(Mapped.synth(f"{c} {title}\n", at))
                parts.append(join(self._interleave(texts, at), at))

        inits: list[Mapped] = []
        for space in self.legacy.spaces:
            at = self.r.pos(space.span)
            assert space.ctx is not None
            texts = [self._function_text(f, space) for f in space.functions]
            section(f"functions of {space.where}", at, texts)
            inits += [self._convert(m, space.ctx).text for m in space.inits]
        if inits:
            section("set when the component loads: values that are not plain literals, "
                    "attributes never declared", inits[0].start, inits)
        publishers = self._publishers()
        if publishers:
            section("the ROS topics' publish methods", publishers[0].start, publishers)
        if self.helpers:
            section("conditions written as function bodies", self.helpers[0].start, self.helpers)
        if parts:
            self._put_code(d, ("functions",), join(parts, parts[0].start), self.root_span)

    @staticmethod
    def _interleave(texts: list[Mapped], at: Pos) -> list[Mapped]:
        out: list[Mapped] = []
        for t in texts:
            if out:
                out.append(Mapped.synth("\n" if "\n" not in t.text.strip() else "\n\n", t.start))
            out.append(t)
        return out

    def _level(self, level: Level, path: PathKey, d: dict[str, Any],
               parent_ms: int | None) -> int:
        """A sub-automaton's keys in ``d`` (the model or a state); its number of states."""
        ms = level.period_ms
        if parent_ms is None:  # the root: always written, from the file or the default
            ms = ms if ms is not None else DEFAULT_ROOT_PERIOD_MS
            self._put(d, (*path, "period"), ms, level.period_span or level.span)
        elif ms is not None and ms != parent_ms:
            self._put(d, (*path, "period"), ms, level.period_span or level.span)
        else:
            ms = parent_ms
        initial = level.initial
        if initial is not None:
            self._put(d, (*path, "initial"), initial.name, level.initial_span or level.span)
        if path and self.legacy.history:
            self._put(d, (*path, "history"), True, level.span)
        states: dict[str, Any] = {}
        self._put(d, (*path, "states"), states, level.span)
        count = 0
        for s in level.states:
            count += 1
            sp: PathKey = (*path, "states", s.name)
            sd: dict[str, Any] = {}
            self._put(states, sp, sd, s.span)
            during = self._snippet(s.code, s.ctx)
            if during is not None:
                self._put_code(sd, (*sp, "during"), during, s.span)
            self._transitions(s, sp, sd)
            if s.child is not None:
                count += self._level(s.child, sp, sd, ms)
        return count

    def _transitions(self, s: LState, sp: PathKey, sd: dict[str, Any]) -> None:
        if not s.transitions:
            return
        items: list[Any] = []
        self._put(sd, (*sp, "transitions"), items, s.transitions[0].span)
        for i, t in enumerate(s.transitions):
            tp: PathKey = (*sp, "transitions", i)
            td: dict[str, Any] = {}
            items.append(td)
            self._put_span(tp, t.span, t.span)
            if t.name is not None:
                self._put(td, (*tp, "name"), t.name, t.span)
            self._put(td, (*tp, "to"), t.target.name, t.target_span)
            if t.after_ms is not None:
                self._put(td, (*tp, "after"), t.after_ms, t.after_span or t.span)
            if t.after_ms is None or t.cond is not None:
                self._put_code(td, (*tp, "when"), self._condition(t, s), t.span)
            do = self._snippet(t.code, s.ctx)
            if do is not None:
                self._put_code(td, (*tp, "do"), do, t.span)

    # -- the report --------------------------------------------------------------
    def _report(self, n_states: int) -> None:
        lg, r = self.legacy, self.r
        details = list(r.notes)
        r.notes.clear()
        n_trans = sum(len(s.transitions) for s in self._states(lg.root))
        r.note(self.root_span, f"{n_states} states, {n_trans} transitions, as in the source")
        r.note(self.root_span, f"language: {self.language} ({self.why})")
        root_ms = lg.root.period_ms
        r.note(lg.root.period_span or self.root_span,
               f"period: {root_ms if root_ms is not None else DEFAULT_ROOT_PERIOD_MS}ms for the root"
               + ("" if root_ms is not None else " (none written: the default)")
               + "; a sub-automaton's is written where it differs from its parent's")
        if any(s.child is not None for s in self._states(lg.root)):
            r.note(self.root_span, "re-entering a composite state " + (
                "resumes where it was left: `history: true`, as VisualHFSM did" if lg.history else
                "restarts it (`history: false`, the default), as VisualStates did"))
        if any(self.counts.values()):
            spelled = ({"global": "`self.globalNamespace.` (or `.interfaces.`, `.rosNode.`)",
                        "local": "`self.namespace.`", "self": "`self.`"}
                       if self.language == "python" else
                       {"global": "`globalNamespace->` (or `interfaces->`, `rosNode->`, `node->`)",
                        "local": "`stateNamespace->`", "self": "`this->`"})
            r.note(self.root_span, "namespace prefixes dropped: " + ", ".join(
                f"{spelled[k]}: {n}" for k, n in self.counts.items() if n))
        if self.renames:
            r.note(self.root_span, f"names changed to unique identifiers: {self.renames} "
                   "(the W206 warnings say which)")
        kinds: dict[str, int] = {}
        for space in lg.spaces:
            for member in space.members.values():
                kinds[member.kind] = kinds.get(member.kind, 0) + 1
        words = {"variable": "variables", "function": "functions", "interface": "interfaces",
                 "topic": "ROS topics read through the ros2 interface",
                 "parameter": "parameters (settable at start, as VisualStates' were)",
                 "init": "names set by statements kept in `functions`",
                 "implicit": "attributes assigned but never declared (None at first)"}
        if kinds:
            r.note(self.root_span, "namespace members: " + ", ".join(
                f"{words[k]} {n}" for k, n in sorted(kinds.items())))
        r.notes.extend(details)
        for span, what in lg.dropped:
            r.note(span, f"not carried over: {what}")
