"""Property: any valid model whose states `use` other files (used files using others, one file
used several times, parameters bound by `with` to literals and to `$NAME`, used files with
regions and uses inside regions) gives a Python component that runs and writes well-nested
records, and a C++ component that writes the same trace byte for byte (docs/semantics.md §14,
§17)."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from hfsmc.ir import Model
from hfsmc.pipeline import compile_file
from tests.conftest import ROOT
from tests.cppbuild import Superbuild, need_toolchain
from tests.test_roundtrip import dump_yaml

VALIDATOR = jsonschema.Draft202012Validator(
    json.loads((ROOT / "schemas/trace.schema.json").read_text()))
ARGS = ("--clock", "virtual", "--until", "1500ms", "--param", "p=3")  # p: every model's int

# Snippets both languages run alike, Python -> C++. Every model has the variable x (int) and
# the parameters p (int) and q (float), so a used file's snippets read its own.
CODE: dict[str, str] = {
    "x = x + p": "x = x + p;",
    "log(str(x))": "log(str(x));",
    "log(str(p) + ' ' + str(q))": 'log(str(p) + " " + str(q));',
    "log(str(elapsed()))": "log(str(elapsed()));",
    'log("done" if done() else "busy")': 'log(done() ? "done" : "busy");',
    "shutdown()": "shutdown();",
}
WHEN: dict[str, str] = {
    "x > p": "x > p",
    "x % 3 == 0": "x % 3 == 0",
    "elapsed() > 0.25": "elapsed() > 0.25",
    "done()": "done()",
    "q > 1.0 and not done()": "q > 1.0 && !done()",
}
SNIPPETS = ("entry", "during", "exit")
PERIOD = st.sampled_from(["20ms", "50ms", "100ms"])
AFTER = st.sampled_from(["50ms", "100ms", "300ms"])


@dataclass
class Files:
    """What one example writes: the using model and its used files, by file stem."""

    main: dict[str, Any]
    libs: dict[str, dict[str, Any]]


def binding(draw: st.DrawFn) -> dict[str, Any]:
    """A `with` for a used file, in a model that has the parameters p (int) and q (float)."""
    out: dict[str, Any] = {}
    if draw(st.booleans()):
        out["p"] = draw(st.sampled_from([0, 1, 2, 5, "$p"]))
    if draw(st.booleans()):
        out["q"] = draw(st.sampled_from([2, 0.5, 1.5, "$p", "$q"]))  # an int is a valid float
    return out


@st.composite
def states(draw: st.DrawFn, depth: int, uses: list[str]) -> dict[str, Any]:
    """1-3 sibling states: leaves, final states, sub-automata, two regions, or a `use` of one of
    ``uses`` (paths relative to the using file), down to ``depth`` levels."""
    names = [f"S{k}" for k in range(draw(st.integers(1, 3)))]
    kinds = ["leaf", "final"] + (["states", "regions"] if depth else []) + (["use"] * 2 if uses else [])
    out: dict[str, Any] = {}
    for name in names:
        kind = draw(st.sampled_from(kinds))
        node: dict[str, Any] = {}
        for key in SNIPPETS:
            if draw(st.integers(0, 3)) == 0:
                node[key] = draw(st.sampled_from(sorted(set(CODE) - {"shutdown()"})))
        if kind == "final":
            node["final"] = True
            out[name] = node
            continue
        if kind == "states":
            node.update(automaton(draw, depth - 1, uses))
        elif kind == "regions":
            node["regions"] = {r: automaton(draw, depth - 1, uses) for r in ("R0", "R1")}
        elif kind == "use":
            node["use"] = draw(st.sampled_from(uses))
            if bound := binding(draw):
                node["with"] = bound
        trans = []
        for _ in range(draw(st.integers(0, 2))):
            t: dict[str, Any] = {"to": draw(st.sampled_from(names))}
            if draw(st.booleans()):
                t["after"] = draw(AFTER)
            if "after" not in t or draw(st.booleans()):
                t["when"] = draw(st.sampled_from(sorted(WHEN)))
            if draw(st.integers(0, 3)) == 0:
                t["do"] = draw(st.sampled_from(sorted(CODE)))
            trans.append(t)
        if trans:
            node["transitions"] = trans
        out[name] = node
    return out


def automaton(draw: st.DrawFn, depth: int, uses: list[str]) -> dict[str, Any]:
    sub = draw(states(depth, uses))
    node: dict[str, Any] = {"initial": draw(st.sampled_from(sorted(sub))), "states": sub}
    if draw(st.integers(0, 2)) == 0:
        node["period"] = draw(PERIOD)
    if draw(st.integers(0, 2)) == 0:
        node["history"] = True
    return node


def model(draw: st.DrawFn, name: str, depth: int, uses: list[str]) -> dict[str, Any]:
    m: dict[str, Any] = {"hfsm": 1, "name": name, "language": "python",
                         "parameters": {"p": {"type": "int", "default": draw(st.integers(0, 4))},
                                        "q": {"type": "float", "default": 0.5}},
                         "variables": {"x": 0}}
    m.update(automaton(draw, depth, uses))
    return m


@st.composite
def using_models(draw: st.DrawFn) -> Files:
    """1-3 used files (file k may use files 0..k-1, all named `lib`: the component keeps them
    apart by file), and a model that uses at least one of them."""
    libs: dict[str, dict[str, Any]] = {}
    for k in range(draw(st.integers(1, 3))):
        libs[f"lib{k}"] = model(draw, "lib", 1, [f"{stem}.yaml" for stem in libs])
    main = model(draw, "m", 2, [f"lib/{stem}.yaml" for stem in libs])
    first = main["states"][main["initial"]]
    if '"lib/' not in json.dumps(main) or first.get("final"):  # the run starts in a use
        for key in ("states", "regions", "initial", "period", "history", "final", "with"):
            first.pop(key, None)
        first["use"] = f"lib/{draw(st.sampled_from(sorted(libs)))}.yaml"
    return Files(main, libs)


def as_cpp(node: Any) -> Any:
    """The C++ twin of a generated model (or of a part of it)."""
    if isinstance(node, list):
        return [as_cpp(v) for v in node]
    if not isinstance(node, dict):
        return node
    out: dict[str, Any] = {}
    for key, value in node.items():
        if key in (*SNIPPETS, "do"):
            out[key] = CODE[value]
        elif key == "when":
            out[key] = WHEN[value]
        elif key == "language":
            out[key] = "cpp"
        elif key == "use":
            out[key] = value.replace(".yaml", ".cpp.yaml")
        else:
            out[key] = as_cpp(value)
    return out


def write(files: Files, folder: Path, name: str) -> tuple[Path, Path]:
    """The example's Python and C++ files under ``folder``; the two using models' paths."""
    (folder / "lib").mkdir(parents=True)
    for stem, lib in files.libs.items():
        (folder / "lib" / f"{stem}.yaml").write_text(dump_yaml(lib), "utf-8")
        (folder / "lib" / f"{stem}.cpp.yaml").write_text(
            dump_yaml(as_cpp(lib)), "utf-8")
    main = {**files.main, "name": name}
    py, cpp = folder / f"{name}.yaml", folder / f"{name}.cpp.yaml"
    py.write_text(dump_yaml(main), "utf-8")
    cpp.write_text(dump_yaml(as_cpp(main)), "utf-8")
    return py, cpp


def shown(folder: Path) -> str:
    return "\n".join(f"--- {p.relative_to(folder)}\n{p.read_text('utf-8')}"
                     for p in sorted(folder.rglob("*.yaml")) if ".cpp." not in p.name)


def check_records(recs: list[dict[str, Any]], model: Model, name: str) -> None:
    """Valid records, first `start`, last `stop`; every state of the model (paths through
    instances and regions), entered inside its parent state and left innermost first."""
    kinds: dict[tuple[str, ...], dict[str, Any]] = {}  # one record of each shape is enough
    for rec in recs:
        kinds.setdefault((rec["ev"], *rec), rec)
    for rec in kinds.values():
        VALIDATOR.validate(rec)
    assert recs[0] == {"t": 0, "ev": "start", "name": name}
    assert recs[-1]["ev"] == "stop" and recs[-1]["reason"] in ("until", "final", "shutdown")
    assert [r["ev"] for r in recs].count("stop") == 1
    paths = {s.path for s in model.states()}

    def parent(path: str) -> str:  # the nearest enclosing state: region segments skipped
        head = path.rpartition("/")[0]
        while head and head not in paths:
            head = head.rpartition("/")[0]
        return head

    active: set[str] = set()
    for r in recs:
        path = r.get("state", "")
        if r["ev"] == "enter":
            assert path in paths and path not in active, (r, sorted(active))
            assert not parent(path) or parent(path) in active, (r, sorted(active))
            active.add(path)
        elif r["ev"] == "exit":
            assert path in active, (r, sorted(active))
            assert not any(a.startswith(path + "/") for a in active), (r, sorted(active))
            active.remove(path)
    assert not active, sorted(active)


def run(cmd: list[str]) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([*cmd, *ARGS, "--trace", "-"], capture_output=True, timeout=60,
                          stdin=subprocess.DEVNULL)


def run_python(model: Path, out: Path) -> tuple[Model, subprocess.CompletedProcess[bytes]]:
    result = compile_file(str(model))
    assert result.model is not None, "\n".join(str(d) for d in result.diagnostics
                                                if d.severity == "error")
    build = subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(model),
                            "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert build.returncode == 0, build.stderr
    proc = run([sys.executable, str(out / f"{result.model.name}.py")])
    stderr = proc.stderr.decode("utf-8", "backslashreplace")
    assert proc.returncode == 0, stderr
    assert "Traceback (most recent call last):" not in stderr, stderr
    return result.model, proc


# Each example builds a component: no shrinking (the failure shows the example's files).
@settings(max_examples=12, deadline=None, derandomize=True, phases=[Phase.generate],
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(using_models())
def test_any_model_using_files_runs(files: Files) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        py, _ = write(files, base, "m")
        try:
            built, proc = run_python(py, base / "out")
            recs = [json.loads(line) for line in proc.stdout.splitlines()]
            check_records(recs, built, "m")
        except AssertionError as e:
            raise AssertionError(f"{e}\n{shown(base)}") from None


BATCH = 3  # examples per C++ build: one CMake project for all of them


def batch() -> list[Files]:
    """BATCH distinct examples (Hypothesis's first one is its simplest: left out)."""
    found: list[Files] = []

    @settings(max_examples=2 * BATCH + 1, deadline=None, derandomize=True, database=None,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(using_models())
    def collect(files: Files) -> None:
        found.append(files)

    collect()
    distinct = {repr(f): f for f in found[1:]}
    return list(distinct.values())[:BATCH]


@pytest.mark.timeout(1800)
def test_python_and_cpp_instances_write_the_same_trace() -> None:
    need_toolchain()  # make test installs it: a missing one fails here, with what to run
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        models = [write(files, base / f"m{n}", f"m{n}") for n, files in enumerate(batch())]
        assert len(models) == BATCH
        build = Superbuild(base / "cpp", [cpp for _, cpp in models])
        for n, (py, cpp) in enumerate(models):
            where = shown(base / f"m{n}")
            built, pyrun = run_python(py, base / f"py{n}")
            cpprun = run([str(build.executable(cpp))])
            assert pyrun.stdout == cpprun.stdout, (f"{where}\n--- python ---\n{pyrun.stdout.decode()}"
                                                   f"\n--- c++ ---\n{cpprun.stdout.decode()}")
            assert pyrun.returncode == cpprun.returncode, (where, cpprun.stderr)
            check_records([json.loads(line) for line in pyrun.stdout.splitlines()], built, f"m{n}")
