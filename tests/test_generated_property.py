"""Property: any valid model (sub-automata and parallel regions nested) gives a Python component
that compiles, runs and writes well-nested records; with code both languages share, the Python
and the C++ component of one model write byte-identical traces (docs/semantics.md §14, §16)."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from hfsmc.component import write_component
from hfsmc.ir import Model
from hfsmc.pipeline import compile_file
from tests.conftest import ROOT
from tests.cppbuild import Superbuild, need_toolchain
from tests.support import check_nesting
from tests.test_roundtrip import DURATION, IDENT, PERIOD, automata, dump_yaml, models, states

VALIDATOR = jsonschema.Draft202012Validator(
    json.loads((ROOT / "schemas/trace.schema.json").read_text()))
UNTIL = "2s"  # each run's bound on the virtual clock


def region_paths(model: Model) -> set[str]:
    return {a.path for a in model.automata() if a.region is not None}


def check_region_order(recs: list[dict[str, Any]], model: Model) -> None:
    """docs/semantics.md §16: the regions of a state are entered in the order written and left
    in the reverse order. Between the `enter` of a state with regions and the next record
    that is neither `enter` nor `log` come its regions' entries; just before its `exit` come
    its regions' exits (with their code's `log` records)."""
    order = {s.path: [a.path for a in s.automata] for s in model.states() if s.parallel}

    def region_of(path: str, owner: str) -> int:
        """The index of the region of ``owner`` that holds ``path`` (a state under it)."""
        return next(k for k, r in enumerate(order[owner]) if path.startswith(r + "/"))

    for n, rec in enumerate(recs):
        owner = rec.get("state", "")
        if rec["ev"] not in ("enter", "exit") or owner not in order:
            continue
        step, stay = (1, "enter") if rec["ev"] == "enter" else (-1, "exit")
        seen: list[int] = []
        k = n + step
        while 0 <= k < len(recs) and recs[k]["ev"] in (stay, "log"):
            path = recs[k].get("state", "")
            if recs[k]["ev"] == "log" and path == owner:  # the parallel state's own code
                k += step
                continue
            if not path.startswith(owner + "/"):
                break
            if recs[k]["ev"] == stay:
                seen.append(region_of(path, owner))
            k += step
        # Read from the parallel state outwards: entries after it, exits before it (backwards).
        assert seen == sorted(seen), (rec, seen, recs[min(n, k):max(n, k) + 1])
        assert sorted(set(seen)) == list(range(len(order[owner]))), (rec, seen)


def check_records(recs: list[dict[str, Any]], model: Model, name: str, reasons: set[str]) -> None:
    kinds: dict[tuple[str, ...], dict[str, Any]] = {}  # one record of each shape is enough
    for rec in recs:
        kinds.setdefault((rec["ev"], *rec), rec)
    for rec in kinds.values():
        VALIDATOR.validate(rec)
    assert recs[0] == {"t": 0, "ev": "start", "name": name}
    assert recs[-1]["ev"] == "stop" and recs[-1]["reason"] in reasons, recs[-1]
    # Every state entered inside its parent (a region's states inside the state that holds
    # it), exited innermost first, and every one left before the stop.
    check_nesting(recs, region_paths(model))
    entered = [r["state"] for r in recs if r["ev"] == "enter"]
    exited = [r["state"] for r in recs if r["ev"] == "exit"]
    assert sorted(entered) == sorted(exited)
    check_region_order(recs, model)


def run_python(model: Model, tmp: Path) -> subprocess.CompletedProcess[bytes]:
    built = write_component(model, "python", tmp / "c")
    compile(built.main.read_text(), str(built.main), "exec")
    return subprocess.run([sys.executable, "-I", "-S", str(built.main), "--clock", "virtual",
                           "--until", UNTIL, "--trace", "-"], capture_output=True,
                          timeout=60, stdin=subprocess.DEVNULL)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(models())
def test_any_valid_model_builds_and_runs(data: dict[str, Any]) -> None:
    result = compile_file("m.yaml", text=dump_yaml(data))
    assert result.model is not None, result.diagnostics
    with tempfile.TemporaryDirectory() as tmp:
        run = run_python(result.model, Path(tmp))
    stderr = run.stderr.decode("utf-8", "backslashreplace")
    assert run.returncode == 0, stderr
    assert "Traceback (most recent call last):" not in stderr
    recs = [json.loads(line) for line in run.stdout.splitlines()]
    check_records(recs, result.model, data["name"], {"until", "final"})


# -- Python and C++ alike ------------------------------------------------------------------------
# Snippets both languages run the same way: Python code -> its C++ twin (variable x: int).
PORTABLE: dict[str, dict[str, str]] = {
    "code": {
        "x = x + 1": "x = x + 1;",
        "log(str(x))": "log(str(x));",
        "log(str(elapsed()))": "log(str(elapsed()));",
        "log(str(now()))": "log(str(now()));",
        'log("done" if done() else "busy")': 'log(done() ? "done" : "busy");',
        "if x > 2:\n    x = 0": "if (x > 2) {\n    x = 0;\n}",
        'log("a < b & \\"c\\" é")': 'log("a < b & \\"c\\" é");',
        "if x > 5:\n    shutdown()": "if (x > 5) {\n    shutdown();\n}",
    },
    "when": {
        "x > 2": "x > 2",
        "x % 3 == 0": "x % 3 == 0",
        "elapsed() > 0.25": "elapsed() > 0.25",
        "done()": "done()",
        "elapsed() > 0.5 and not done()": "elapsed() > 0.5 && !done()",
    },
}
SNIPPET_KEYS = ("entry", "during", "exit", "do", "when")


def portable(kind: str) -> st.SearchStrategy[str]:
    return st.sampled_from(sorted(PORTABLE["when" if kind == "when" else "code"]))


@st.composite
def portable_models(draw: st.DrawFn) -> dict[str, Any]:
    """A Python model whose snippets all have a C++ twin (``as_cpp``); its initial state has
    regions."""
    root = draw(states(2, portable))
    initial = draw(st.sampled_from(sorted(root)))
    node = root[initial]
    for key in ("final", "states", "initial", "period", "history"):
        node.pop(key, None)
    names = draw(st.lists(IDENT, min_size=2, max_size=3, unique=True))
    node["regions"] = {name: draw(automata(1, portable)) for name in names}
    m: dict[str, Any] = {"hfsm": 1, "name": "m", "language": "python", "variables": {"x": 0}}
    if draw(st.booleans()):
        m["on_interrupt"] = draw(st.sampled_from(sorted(root)))
        if draw(st.booleans()):
            m["interrupt_timeout"] = draw(DURATION)
    if draw(st.booleans()):
        m["period"] = draw(PERIOD)
    m["initial"] = initial
    m["states"] = root
    return m


def as_cpp(node: Any) -> Any:
    """The C++ twin of a portable model (or of a part of it)."""
    if isinstance(node, list):
        return [as_cpp(v) for v in node]
    if not isinstance(node, dict):
        return node
    out: dict[str, Any] = {}
    for key, value in node.items():
        if key in SNIPPET_KEYS and isinstance(value, str):
            out[key] = PORTABLE["when" if key == "when" else "code"][value]
        elif key == "language":
            out[key] = "cpp"
        else:
            out[key] = as_cpp(value)
    return out


BATCH = 5  # models per C++ build: one CMake project for all of them
DRAWN = 40  # models drawn, the BATCH richest kept (Hypothesis draws the simplest model first)


def draw_batch() -> list[dict[str, Any]]:
    """BATCH of DRAWN portable models: distinct ones with regions, from the largest to the
    smallest in even steps."""
    drawn: list[dict[str, Any]] = []

    @settings(max_examples=DRAWN, deadline=None, derandomize=True, database=None,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(portable_models())
    def collect(data: dict[str, Any]) -> None:
        drawn.append(data)

    collect()
    texts = {dump_yaml(d): d for d in drawn if d}
    ranked = sorted((t for t in texts if "regions:" in t), key=len, reverse=True)
    step = max(len(ranked) // BATCH, 1)
    return [texts[t] for t in ranked[::step][:BATCH]]


@pytest.mark.timeout(1800)
def test_python_and_cpp_write_the_same_trace(tmp_path: Path) -> None:
    """One C++ build for a batch of models with regions: each writes, under the virtual clock,
    the same trace as its Python component, and that trace nests well."""
    need_toolchain()  # make test installs it: a missing one fails here, with what to run
    batch = draw_batch()
    assert sum("regions" in dump_yaml(d) for d in batch) >= 3
    for n, data in enumerate(batch):
        data["name"] = f"m{n}"
        (tmp_path / f"m{n}.yaml").write_text(dump_yaml(data), "utf-8")
        (tmp_path / f"m{n}.cpp.yaml").write_text(dump_yaml(as_cpp(data)), "utf-8")
    build = Superbuild(tmp_path / "cpp", [tmp_path / f"m{n}.cpp.yaml" for n in range(BATCH)])
    for n in range(BATCH):
        same_trace(tmp_path, n, build)


def same_trace(base: Path, n: int, build: Superbuild) -> None:
    """Model ``n`` of the batch in ``base`` writes one trace in both languages."""
    result = compile_file(str(base / f"m{n}.yaml"))
    assert result.model is not None, result.diagnostics
    py = run_python(result.model, base / f"py{n}")
    cpp_cmd = [str(build.executable(base / f"m{n}.cpp.yaml")), "--clock", "virtual",
               "--until", UNTIL, "--trace", "-"]
    cpp = subprocess.run(cpp_cmd, capture_output=True, timeout=60, stdin=subprocess.DEVNULL)
    where = f"model m{n}:\n{(base / f'm{n}.yaml').read_text('utf-8')}"
    assert py.stdout == cpp.stdout, f"{where}\n--- python ---\n{py.stdout.decode()}\n" \
                                    f"--- c++ ---\n{cpp.stdout.decode()}"
    assert py.returncode == cpp.returncode, (where, py.stderr, cpp.stderr)
    assert b"Traceback (most recent call last):" not in py.stderr, (where, py.stderr)
    recs = [json.loads(line) for line in py.stdout.splitlines()]
    check_records(recs, result.model, f"m{n}", {"until", "final", "shutdown", "timeout"})
