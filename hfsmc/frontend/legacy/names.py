"""Names for an imported legacy model: namespace members, imports, interfaces, states.

A legacy file has several namespaces (VisualStates: a global one and one per
level; VisualHFSM: one) whose members a version-1 model puts side by side at
module level.  This module reads what each namespace declares (its variables'
plain literal values, the names its statements and functions define, the
attributes its code assigns without declaring them), then gives every member
its model name: a global member keeps its name unless a helper, an import or
(Python) a builtin has it; a local member keeps its name unless another
namespace has it too, and is then prefixed with its owner state's name.
Every rename is a W206 at the member's definition; references follow it.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from typing import Any

from hfsmc.errors import Span
from hfsmc.frontend.legacy.code import (
    PY_RESERVED,
    Language,
    Mapped,
    block,
    cpp_declaration,
    cpp_members,
    cpp_statements,
    cpp_value,
    identifier,
    literal,
    mask,
    python_defs,
    python_import_names,
    references,
    uses,
)
from hfsmc.frontend.legacy.form import Context, Interface, Legacy, Level, LState, Member, Space
from hfsmc.frontend.legacy.reader import Reader
from hfsmc.ir import HELPERS, RESERVED_PREFIX
from hfsmc.ros2.definitions import ros2_type_name, standard_types

# ROS 1's tf.transformations.euler_from_quaternion: hfsmc's helper of that name instead
TF_EULER = re.compile(r"(?<![\w.])tf\s*\.\s*transformations\s*\.\s*euler_from_quaternion\b")


class Names:
    """What the legacy namespaces declare, and the model name of everything."""

    def __init__(self, reader: Reader, legacy: Legacy) -> None:
        self.r = reader
        self.legacy = legacy
        self.language: Language = "python"
        self.taken: set[str] = set()  # every name the model's snippets may see
        self.imported: dict[str, Span] = {}  # names the imports bind
        self.renames = 0  # W206 warnings given
        self.ros_member = Member("ros", "interface", Span("", 0, 0))  # the ros2 interface

    # -- walking the neutral form ------------------------------------------------
    def _states(self, level: Level) -> Iterator[LState]:
        for s in level.states:
            yield s
            if s.child is not None:
                yield from self._states(s.child)

    def _all_code(self) -> Iterator[tuple[Mapped, Context]]:
        """Every code text with the context it is read in."""
        for space in self.legacy.spaces:
            if space.ctx is not None:
                for m in (*space.functions, *space.inits):
                    yield m, space.ctx
        for s in self._states(self.legacy.root):
            for code in (s.code, *(c for t in s.transitions for c in (t.cond, t.code))):
                if code is not None:
                    yield code, s.ctx

    # -- namespaces ------------------------------------------------------------
    def _member(self, space: Space, name: str, kind: str, span: Span, value: Any = None,
                value_span: Span | None = None) -> Member:
        found = space.members.get(name)
        if found is None:
            found = space.members[name] = Member(name, kind, span, value, value_span)
        return found

    def _read_space(self, space: Space) -> None:
        """The members a namespace's variables and functions declare."""
        for raw in space.variables:
            m = block(raw)
            if self.language == "python":
                self._python_variables(space, m)
            else:
                self._cpp_variables(space, m)
        funcs = [block(f) for f in space.functions]
        space.functions = [f for f in funcs if f.text]
        for f in space.functions:
            found = python_defs(f.text) if self.language == "python" else cpp_members(f.text)
            for name, off, kind in found:
                self._member(space, name, kind, self.r.to_span(f.at(off)))

    def _python_variables(self, space: Space, m: Mapped) -> None:
        """``self.x = 0`` lines: plain literals become variables, the rest statements."""
        try:
            tree = ast.parse(m.text)
        except (SyntaxError, ValueError, MemoryError, RecursionError):
            space.inits.append(m)  # its syntax error is reported in `functions`, in place
            self._declare_stores(space, m)
            return
        rows = m.text.split("\n")
        starts = [0]
        for row in rows:
            starts.append(starts[-1] + len(row) + 1)

        def offset(line: int, col: int) -> int:
            return starts[line - 1] + len(rows[line - 1].encode("utf-8")[:col].decode(
                "utf-8", "replace"))

        for stmt in tree.body:
            a = offset(stmt.lineno, stmt.col_offset)
            b = offset(stmt.end_lineno or stmt.lineno, stmt.end_col_offset or 0)
            target = stmt.targets[0] if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1 \
                else None
            if (isinstance(target, ast.Attribute) and isinstance(target.value, ast.Name)
                    and target.value.id == "self" and isinstance(stmt, ast.Assign)):
                name = target.attr
                name_at = offset(target.end_lineno or target.lineno,
                                 target.end_col_offset or 0) - len(name)
                ok, value = literal(stmt.value)
                if ok and name not in space.members:
                    value_at = offset(stmt.value.lineno, stmt.value.col_offset)
                    self._member(space, name, "variable", self.r.to_span(m.at(name_at)), value,
                                 self.r.to_span(m.at(value_at)))
                    continue
                self._member(space, name, "init", self.r.to_span(m.at(name_at)))
            space.inits.append(m.cut(a, b))
            self._declare_stores(space, m.cut(a, b))

    def _declare_stores(self, space: Space, m: Mapped) -> None:
        for ref in references(m.text, "python"):
            if ref.scope == "self" and ref.store:
                self._member(space, ref.name, "init", self.r.to_span(m.at(ref.start)))

    def _cpp_variables(self, space: Space, m: Mapped) -> None:
        """``float x = 0.4;`` declarations become variables; others stay as declarations."""
        masked = mask(m.text, "cpp")
        directives = [(d.start(), d.end()) for d in re.finditer(r"^[ \t]*#.*$", masked, re.M)]
        pieces = sorted([*((a, b, False) for a, b in directives),
                         *((a, b, True) for a, b in cpp_statements(m.text))])
        for a, b, statement in pieces:
            stmt = m.cut(a, b).strip()
            decl = cpp_declaration(stmt.text) if statement else None
            if decl is None:
                space.inits.append(stmt)
                continue
            span = self.r.to_span(stmt.at(decl.name_at))
            ok, value = cpp_value(decl.type, decl.init)
            if decl.type in ("bool", "int", "float") and ok:
                data: Any = {"type": decl.type, "init": value}
            elif decl.type in ("bool", "int", "float"):
                self._member(space, decl.name, "init", span)
                space.inits.append(stmt)
                continue
            else:
                data = {"type": decl.type, "init": decl.init if decl.init is not None else "{}"}
            self._member(space, decl.name, "variable", span, data, span)

    # -- imports and interfaces ------------------------------------------------
    def _imports(self) -> list[tuple[str, Span]]:
        out: list[tuple[str, Span]] = []
        seen: set[str] = set()

        def add(text: str, span: Span) -> bool:
            if text in seen:
                return False
            seen.add(text)
            out.append((text, span))
            if self.language == "python":
                for name in python_import_names(text):
                    self.imported.setdefault(name, span)
            return True

        for text, span in self.legacy.libraries:
            if self.language == "cpp" and not text.startswith(("<", '"')):
                text = f"<{text}>"
            if self.language == "python" and text == "tf" and self._only_tf_euler():
                self.r.note(span, "`import tf` dropped: ROS 2 has no tf module, and its one use "
                            "here, `tf.transformations.euler_from_quaternion`, becomes hfsmc's "
                            "helper `euler_from_quaternion`")
                continue
            add(text, span)
        for itf in self.legacy.interfaces:
            if itf.msg_import is not None:
                text, span = itf.msg_import
                pkg, _, msg = text.partition("/")
                if pkg and msg and identifier(msg, "") == msg and identifier(pkg, "") == pkg \
                        and add(f"from {pkg}.msg import {msg}" if self.language == "python"
                                else f"<{pkg}/{msg}.h>", span):
                    self.r.note(span, f"import of the ROS message type {text} added: the code "
                                f"{self.r.kind} generated imported it")
        if self.language == "cpp":
            # The .cpp VisualStates and VisualHFSM generated included these for the code.
            for header, used in (("<iostream>", r"\bstd\s*::\s*(?:cout|cerr|clog|endl)\b"),
                                 ("<string>", r"\bstd\s*::\s*string\b")):
                at = next((self.r.to_span(m.at(f.start())) for m, _ in self._all_code()
                           if (f := re.search(used, mask(m.text, "cpp"))) is not None), None)
                if at is not None and add(header, at):
                    self.r.note(at, f"`#include {header}` added: the code {self.r.kind} "
                                "generated included it, and this model uses it")
        if self.language == "python":
            texts = [m.text for m, _ in self._all_code()]
            for package, span in self.legacy.ros_dependencies:
                if identifier(package, "") == package and package not in self.imported \
                        and self._declared(package) is None \
                        and not (package == "tf" and self._only_tf_euler()):
                    at = self._first_use(package, module=True)
                    if at is not None and add(f"import {package}", span):
                        self.r.warn("W208", f"`{package}` is used as a module, and it is a ROS "
                                    f"dependency of the file, but the legacy code never "
                                    f"imported it (the component stopped with NameError "
                                    f"here): `import {package}` added", at)
            for module in self.legacy.implicit_imports:
                if module not in self.imported and self._declared(module) is None:
                    at = self._first_use(module)
                    if at is not None and uses(texts, module, "python"):
                        add(module, at)
                        self.r.note(at, f"`import {module}` added: the code {self.r.kind} "
                                    "generated imported it, and this model uses it")
        return out

    def _only_tf_euler(self) -> bool:
        """Whether Python code uses `tf` only as tf.transformations.euler_from_quaternion."""
        any_tf = re.compile(r"(?<![\w.])tf\b")
        for m, _ in self._all_code():
            text = TF_EULER.sub("", mask(m.text, "python"))
            if any_tf.search(text):
                return False
        return True

    def _declared(self, name: str) -> Member | None:
        for space in self.legacy.spaces:
            if name in space.members:
                return space.members[name]
        return None

    def _first_use(self, name: str, module: bool = False) -> Span | None:
        """Where code first names ``name`` (``module``: as a module, ``name.attr``)."""
        pattern = re.compile(r"(?<![\w.])" + re.escape(name) + (r"[ \t]*\.[ \t]*[A-Za-z_]"
                                                                 if module else r"\b"))
        for m, _ in self._all_code():
            found = pattern.search(mask(m.text, self.language))
            if found is not None:
                return self.r.to_span(m.at(found.start()))
        return None

    def ros2_topic(self, itf: Interface) -> bool:
        """A VisualStates ROS topic a Python model can reach through a `ros2` interface: it
        has a name, a message type and a direction (SPEC 5.2; docs/legacy.md)."""
        return self.language == "python" and itf.type == "ros_topic" and bool(itf.url) \
            and itf.options.get("direction") in ("publish", "subscribe") \
            and ros2_type_name(itf.options.get("message", "")) in standard_types("jazzy")

    def _interfaces(self) -> None:
        texts = [m.text for m, _ in self._all_code()]
        glob = self.legacy.spaces[0]
        topics = [i for i in self.legacy.interfaces if self.ros2_topic(i)]
        if topics:
            name, n = "ros", 2
            while name in glob.members or name in self.imported:
                name, n = f"ros_{n}", n + 1
            self.ros_member = self._member(glob, name, "interface", topics[0].span)
        for itf in self.legacy.interfaces:
            name = next((c for c in itf.candidates if uses(texts, c, self.language)),
                        itf.candidates[0])
            base, n = name, 2
            while name in glob.members:
                name, n = f"{base}_{n}", n + 1
            if itf in topics:
                publish = itf.options["direction"] == "publish"
                itf.member = self._member(glob, name, "function" if publish else "topic",
                                          itf.span)
                self.r.note(itf.span, f"{itf.what} becomes the "
                            f"{'publication' if publish else 'subscription'} `{name}` of the "
                            f"ros2 interface `{self.ros_member.name}`: "
                            + (f"`{name}(msg)` is kept as a function that publishes msg"
                               if publish else f"code reads `{name}` as `{self.ros_member.name}."
                               f"{name}`, the latest message"))
                continue
            itf.member = self._member(glob, name, "interface", itf.span)
            if name != base:
                self.renames += 1
                self.r.warn("W206", f"{itf.what} renamed `{name}`: `{base}` is already the "
                            f"name of a {glob.members[base].kind}", itf.span)
            named = "an interface" if f"`{name}`" in itf.what else f"interface `{name}`"
            message = itf.options.get("message", "")
            why = f" (its message type `{message}` is not one of ROS 2's standard messages: " \
                  "give its .msg file in a ros2 interface's `messages` and move the topic " \
                  "there, docs/ros2.md)" if itf.type == "ros_topic" and message \
                  and self.language == "python" else ""
            self.r.warn("W205", f"{itf.what} kept as {named} of type {itf.type}: "
                        f"hfsmc components cannot drive it{why}", itf.span,
                        "the component starts, and fails with a clear message when a snippet "
                        "uses it" if self.language != "cpp" else
                        "it has no operations in C++: a snippet that uses it does not compile "
                        "(build --compile shows where)")

    def ros2_names(self) -> None:
        """After the members are named: a subscription is read as ``ros.NAME``."""
        for itf in self.legacy.interfaces:
            if self.ros2_topic(itf) and itf.member is not None and itf.member.kind == "topic":
                itf.member.final = f"{self.ros_member.final}.{itf.member.final}"

    # -- names -----------------------------------------------------------------
    def _implicit_members(self) -> None:
        """Python code may assign ``self.x`` that no namespace declares: declare it (None).

        A name only read, never declared nor assigned, stays undefined: the check reports
        it (E141), as the legacy component failed there (AttributeError)."""
        if self.language != "python":
            return
        for m, ctx in self._all_code():
            for ref in references(m.text, "python"):
                if ref.plain and ctx.find(ref) is None and ctx.scopes.get(ref.scope):
                    # a state's `self.x = ...` (VisualStates: an attribute of the state
                    # object) becomes a module-level name: the global namespace's
                    space = self.legacy.spaces[0] if ctx.state and ref.scope == "self" \
                        else ctx.scopes[ref.scope][0]
                    member = self._member(space, ref.name, "implicit",
                                          self.r.to_span(m.at(ref.start)))
                    space.inits.append(Mapped.synth(f"self.{ref.name} = None",
                                                    self.r.pos(member.span)))

    def _unique(self, base: str) -> str:
        name, n = base, 2
        while name in self.taken or name.startswith(RESERVED_PREFIX):
            name = f"{base}_{n}" if not base.startswith(RESERVED_PREFIX) else f"x{base}_{n}"
            n += 1
        self.taken.add(name)
        return name

    def _name_members(self) -> None:
        """Global members keep their names unless a helper, an import or (Python) a
        builtin has it; a local member keeps its name unless another namespace has it."""
        reserved = set(HELPERS) | set(self.imported)
        if self.language == "python":
            reserved |= PY_RESERVED
        self.taken = set(reserved)
        glob, *local = self.legacy.spaces
        for member in glob.members.values():
            base = identifier(member.name, "name")
            clash = base in reserved or base.startswith(RESERVED_PREFIX)
            member.final = self._unique(f"{base}_" if clash else base)
            if clash:
                self._renamed(member, glob, f"`{base}` is taken by {self._taker(base)}")
            elif member.final != member.name:
                self._renamed(member, glob, "model names are ASCII identifiers")
        count: dict[str, int] = {}
        for space in local:
            for name in space.members:
                base = identifier(name, "name")
                count[base] = count.get(base, 0) + 1
        for space in local:
            for member in space.members.values():
                base = identifier(member.name, "name")
                clash = base in self.taken or count[base] > 1 or base.startswith(RESERVED_PREFIX)
                member.final = self._unique(f"{space.owner}_{base}" if clash else base)
                if clash:
                    self._renamed(member, space, "other namespaces have the same name")
                elif member.final != member.name:
                    self._renamed(member, space, "model names are ASCII identifiers")

    def _taker(self, name: str) -> str:
        if name in HELPERS:
            return "an hfsmc helper"
        if name in self.imported:
            return "an import"
        return "a Python builtin or keyword"

    def _renamed(self, member: Member, space: Space, why: str) -> None:
        self.renames += 1
        self.r.warn("W206", f"`{member.name}` of {space.where} renamed `{member.final}`: {why}",
                    member.span, "every reference to it is renamed too")

    def _name_states(self, level: Level, owner: str) -> None:
        seen: set[str] = set()
        for s in level.states:
            name = identifier(s.written, "state")
            base, n = name, 2
            while name in seen:
                name, n = f"{base}_{n}", n + 1
            seen.add(name)
            s.name = name
            if name != s.written:
                why = "names are identifiers" if base != s.written else \
                    "sibling states need distinct names"
                where = f" in `{owner}`" if owner else ""
                self.renames += 1
                self.r.warn("W206", f"state `{s.written}` (id {s.uid}){where} renamed "
                            f"`{name}`: {why}", s.span)
            if s.child is not None:
                self._name_states(s.child, f"{owner}/{name}" if owner else name)
