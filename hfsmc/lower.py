"""Lowering: the ordered list of named passes run on the built IR.

Each pass takes the model and the diagnostics bag and returns the model
(unchanged for pure checks).  The order matters and is stated next to each
pass; ``hfsmc check --dump-ir`` prints the result of the whole list.
"""

from __future__ import annotations

import keyword
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from hfsmc.cppsnippets import check_cpp_snippets
from hfsmc.errors import Diagnostics, Span, did_you_mean
from hfsmc.ir import HELPERS, RESERVED_PREFIX, Automaton, Model, State, Transition
from hfsmc.pycheck import check_python_snippets

Pass = Callable[[Model, Diagnostics], Model]


@dataclass(frozen=True, slots=True)
class NamedPass:
    name: str
    run: Pass
    why: str


def _walk_autos(model: Model) -> Iterator[tuple[Automaton, State | None]]:
    """Every sub-automaton and region with its owning state (None for the root), those
    inside used files' instances left out: the used file was checked on its own."""
    yield model.root, None
    for s in model.own_states():
        for a in s.automata:
            if a.instance is None:
                yield a, s


def _where(auto: Automaton, owner: State | None) -> str:
    if owner is None:
        return "the root"
    if auto.region is not None:
        return f"region `{auto.region}` of state `{owner.path}`"
    return f"state `{owner.path}`"


def resolve_initials(model: Model, diags: Diagnostics) -> Model:
    for auto, owner in _walk_autos(model):
        where = _where(auto, owner)
        if not auto.initial:
            diags.error("E130", f"the sub-automaton of {where} has no `initial` state",
                        auto.initial_span, f"its states: {', '.join(s.name for s in auto.states)}")
        elif auto.state(auto.initial) is None:
            names = [s.name for s in auto.states]
            elsewhere = [s.path for s in model.states() if s.name == auto.initial]
            note = did_you_mean(auto.initial, names)
            notes = [note] if note else []
            if elsewhere:
                notes.append(f"`{auto.initial}` is at {', '.join(elsewhere)}, not a child of {where}")
            diags.error("E131", f"initial state `{auto.initial}` is not a child of {where}",
                        auto.initial_span, *notes)
    return model


def resolve_targets(model: Model, diags: Diagnostics) -> Model:
    for auto, owner in _walk_autos(model):
        names = [s.name for s in auto.states]
        siblings = set(names)  # a set: sub-automata may have hundreds of states
        others = [a for a in owner.automata if a is not auto] if owner is not None else []
        for state in auto.states:
            for t in state.transitions:
                if t.target in siblings:
                    continue
                across = [a for a in others if a.state(t.target) is not None]
                if across and owner is not None:
                    diags.error("E162", f"`{state.path}` -> `{t.target}`: `{t.target}` is in region "
                                f"`{across[0].region}`, and nothing crosses from one region of "
                                f"`{owner.path}` to another", t.target_span,
                                "regions run side by side; to coordinate them, test "
                                f"active(\"{across[0].path}/{t.target}\") or a variable, or leave "
                                f"`{owner.path}` with a transition of its own")
                    continue
                elsewhere = [s.path for s in model.states() if s.name == t.target]
                if elsewhere:
                    diags.error("E133", f"`{state.path}` -> `{t.target}`: transitions join siblings only",
                                t.target_span, f"`{t.target}` is at {', '.join(elsewhere)}",
                                "leave the parent state, or move the transition up a level")
                else:
                    note = did_you_mean(t.target, names)
                    diags.error("E132", f"transition to unknown state `{t.target}`", t.target_span,
                                *((note,) if note else (f"siblings: {', '.join(names)}",)))
    return model


def resolve_interrupt(model: Model, diags: Diagnostics) -> Model:
    target = model.on_interrupt
    if target is not None and model.root.state(target) is None:
        note = did_you_mean(target, [s.name for s in model.root.states])
        diags.error("E136", f"on_interrupt names `{target}`, which is not a state of the root "
                    "sub-automaton", model.on_interrupt_span or model.span, *((note,) if note else ()))
    if model.interrupt_timeout_us is not None and target is None:
        diags.error("E139", "interrupt_timeout has no effect without on_interrupt",
                    model.interrupt_timeout_span or model.span)
    if model.time_limit_us is not None and target is None:
        diags.warning("W216", "time_limit without on_interrupt stops the component where it is: "
                      "nothing lands a vehicle then", model.time_limit_span or model.span,
                      "name a landing state in `on_interrupt` (examples/lib/land.yaml)")
    return model


def check_snippets(model: Model, diags: Diagnostics) -> Model:
    if model.language == "python":
        check_python_snippets(model, diags)
    else:
        check_cpp_snippets(model, diags)
    return model


def _always_first(earlier: Transition, later: Transition) -> bool:
    """``earlier`` holds whenever ``later`` could first fire, so ``later`` never fires."""
    unconditional = earlier.when is None or earlier.when.text.strip() == "True"
    return unconditional and (earlier.after_us or 0) <= (later.after_us or 0)


def check_flow(model: Model, diags: Diagnostics) -> Model:
    """Reachability, dead ends and shadowed transitions (warnings only)."""
    leavable = _leavable(model)
    for auto, owner in _walk_autos(model):
        by_name = {s.name: s for s in auto.states}
        if auto.initial not in by_name:
            continue  # E130/E131 already said so; reachability would only repeat it
        exits_above = owner is not None and leavable[owner.path]
        reached = {auto.initial}
        if owner is None and model.on_interrupt:
            reached.add(model.on_interrupt)
        todo = list(reached)
        while todo:
            s = by_name.get(todo.pop())
            for t in s.transitions if s else ():
                if t.target not in reached:
                    reached.add(t.target)
                    todo.append(t.target)
        for s in auto.states:
            if s.name not in reached:
                diags.warning("W201", f"state `{s.path}` is unreachable", s.span,
                              f"no transition of its siblings leads to it from `{auto.initial}`")
            elif not s.final and not s.transitions and not exits_above:
                diags.warning("W202", f"state `{s.path}` has no way out and is not final", s.span,
                              "add a transition, or mark it `final: true`")
            for i, later in enumerate(s.transitions):
                for earlier in s.transitions[:i]:
                    if _always_first(earlier, later):
                        diags.warning("W203", f"transition {later.index} of `{s.path}` never fires: "
                                      f"transition {earlier.index} always fires first", later.span)
                        break
    _check_interrupt_ends(model, diags)
    return model


def _check_interrupt_ends(model: Model, diags: Diagnostics) -> None:
    start = model.root.state(model.on_interrupt) if model.on_interrupt else None
    if start is None:
        return
    seen, todo = {start.name}, [start]
    while todo:
        s = todo.pop()
        if s.final:
            return
        for t in s.transitions:
            nxt = model.root.state(t.target)
            if nxt is not None and nxt.name not in seen:
                seen.add(nxt.name)
                todo.append(nxt)
    diags.warning("W204", f"on_interrupt state `{start.name}` never reaches a final state, so an "
                  "interrupted component stops only at interrupt_timeout or a second signal",
                  start.span)


# Words a variable, parameter or interface cannot be called in each snippet language.
# C++: the keywords and alternative tokens of C++17/20, plus the namespaces that the
# generated class names inside its own scope (a member `std` would hide `std::`).
CPP_RESERVED = frozenset((
    "alignas", "alignof", "and", "and_eq", "asm", "auto", "bitand", "bitor", "bool", "break",
    "case", "catch", "char", "char8_t", "char16_t", "char32_t", "class", "compl", "concept",
    "const", "consteval", "constexpr", "constinit", "const_cast", "continue", "co_await",
    "co_return", "co_yield", "decltype", "default", "delete", "do", "double", "dynamic_cast",
    "else", "enum", "explicit", "export", "extern", "false", "float", "for", "friend", "goto",
    "if", "inline", "int", "long", "mutable", "namespace", "new", "noexcept", "not", "not_eq",
    "nullptr", "operator", "or", "or_eq", "private", "protected", "public", "register",
    "reinterpret_cast", "requires", "return", "short", "signed", "sizeof", "static",
    "static_assert", "static_cast", "struct", "switch", "template", "this", "thread_local",
    "throw", "true", "try", "typedef", "typeid", "typename", "union", "unsigned", "using",
    "virtual", "void", "volatile", "wchar_t", "while", "xor", "xor_eq", "std", "hfsmc", "main"
))


def check_names(model: Model, diags: Diagnostics) -> Model:
    """Variables, parameters, interfaces and helpers share one namespace in snippets."""
    seen: dict[str, str] = {name: "a helper" for name in HELPERS}
    declared: list[tuple[Span, str, str]] = sorted(
        [(v.span, "variable", v.name) for v in model.variables]
        + [(p.span, "parameter", p.name) for p in model.parameters]
        + [(i.span, "interface", i.name) for i in model.interfaces])
    for span, kind, name in declared:  # in file order: the later declaration is the wrong one
        if (model.language == "python" and keyword.iskeyword(name)) or \
                (model.language == "cpp" and name in CPP_RESERVED):
            language = "Python" if model.language == "python" else "C++"
            diags.error("E124", f"{kind} `{name}`: `{name}` is a reserved word in {language} "
                        "snippets; choose another name", span)
            continue
        if name.startswith(RESERVED_PREFIX):
            diags.error("E123", f"{kind} `{name}`: names starting with `{RESERVED_PREFIX}` are "
                        "reserved for generated code", span)
            continue
        other = seen.get(name)
        if other is not None:
            diags.error("E122", f"{kind} `{name}` is already {other}", span)
        else:
            seen[name] = f"a {kind}"
    return model


def _leavable(model: Model) -> dict[str, bool]:
    """For each state path: whether it or one of its ancestors has a transition out."""
    out: dict[str, bool] = {}
    for auto in model.automata():  # parents before children
        above = out.get(auto.owner, False)
        for s in auto.states:
            out[s.path] = bool(s.transitions) or above
    return out


PASSES: tuple[NamedPass, ...] = (
    NamedPass("check_names", check_names,
              "first: snippet checks below assume one meaning per name"),
    NamedPass("resolve_initials", resolve_initials,
              "before flow analysis, which walks sub-automata from their initial state"),
    NamedPass("resolve_targets", resolve_targets,
              "before flow analysis, which follows transitions to their targets"),
    NamedPass("resolve_interrupt", resolve_interrupt,
              "on_interrupt is an extra entry point for reachability"),
    NamedPass("check_snippets", check_snippets,
              "needs the final sets of variables, parameters and functions, not the states"),
    NamedPass("check_flow", check_flow,
              "last: warnings only, meaningful once names and targets resolve"),
)


def lower(model: Model, diags: Diagnostics) -> Model:
    for p in PASSES:
        model = p.run(model, diags)
    return model
