"""Diagrams (`hfsmc diagram`, hfsmc.emit.dot): structure, rendering, escaping, errors.

The DOT source is read back with Graphviz itself (`dot -Tjson0`) and compared
with the model: one cluster per composite state, double circles for initial
states, one labelled edge per transition.  SVG output is parsed as XML and its
text compared with the model's names and conditions.
"""

from __future__ import annotations

import html
import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import graphviz
import pytest
from click.testing import CliRunner
from lxml import etree

from hfsmc.cli import main
from hfsmc.compiler import compile_file
from hfsmc.durations import format_us
from hfsmc.emit import dot
from hfsmc.errors import UsageError
from hfsmc.ir import Automaton, Model, State
from tests.conftest import examples

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = examples()
SVG_TEXT = "{http://www.w3.org/2000/svg}text"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# A composite state with two children, transitions into and out of it, a
# self-transition on it, a nested composite and a final state.
NESTED = """\
hfsm: 1
name: nested
language: python
variables:
  seen: false
  stage: 0
period: 50ms
initial: TakeOff
states:
  TakeOff:
    transitions:
      - {to: Follow, when: stage > 0}
      - {to: Land, after: 20s}
  Follow:
    period: 100ms
    initial: Track
    history: true
    states:
      Track:
        initial: Approach
        states:
          Approach: {transitions: [{to: Hold, when: seen}]}
          Hold: {transitions: [{to: Approach, after: 2500ms}]}
        transitions: [{to: Lost, when: not seen}]
      Lost:
        transitions:
          - {to: Track, when: seen}
          - {to: Lost, name: retry, after: 1s}
    transitions:
      - {to: Land, when: stage >= 4}
      - {to: Follow, name: reset, when: stage == 2}
  Land:
    transitions: [{to: Done, when: not seen}]
  Done: {final: true}
"""

# Names that trip naive DOT writers: keywords, a node named like a cluster,
# `__` that a mangling scheme could confuse with `/`, unicode and markup in
# transition names, every special character in conditions.
NASTY = """\
hfsm: 1
name: graph
language: python
variables: {a: 1, b: 2, c: "x", d: 3}
initial: node
states:
  node:
    transitions:
      - {name: '<b>bold</b> "quoted" \\N {x|y}', to: edge, when: 'a < b and c == "x" or d > {1}'}
  edge:
    transitions:
      - {name: "\\u00e9t\\u00e9 \\u2192 \\U0001F600", to: A__B, when: 'c == "\\\\N\\\\l&amp;\\\\"', after: 1.5s}
  A__B:
    transitions: [{to: A, when: 'c != "<>" and a | b & d'}]
  A:
    initial: B
    states:
      B: {transitions: [{to: cluster_A, after: 1s}]}
      cluster_A: {final: true}
    transitions: [{to: cluster_A, when: done()}]
  cluster_A:
    transitions: [{to: strict, after: 2m}]
  strict:
    initial: subgraph
    states:
      subgraph: {final: true}
    transitions: [{to: node, when: done()}]
"""


# ---------------------------------------------------------------------------
# helpers


def compile_model(path: Path) -> Model:
    result = compile_file(str(path))
    assert result.ok, [str(d) for d in result.diagnostics]
    assert result.model is not None
    return result.model


def write_model(tmp_path: Path, text: str, name: str = "model.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def run_cli(*args: str) -> Any:
    return CliRunner().invoke(main, ["diagram", *args])


def read_dot(source: str) -> dict[str, Any]:
    """The DOT source as Graphviz reads it (fails on any warning or error)."""
    proc = subprocess.run(["dot", "-Tjson0"], input=source.encode(), capture_output=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr.decode()
    assert proc.stderr == b"", proc.stderr.decode()  # no warnings (e.g. bad ltail/lhead)
    data: dict[str, Any] = json.loads(proc.stdout)
    return data


def esc_lines(label: str) -> list[str]:
    """A Graphviz escString label as the lines it displays."""
    lines: list[str] = []
    cur = ""
    i = 0
    while i < len(label):
        ch = label[i]
        if ch == "\\" and i + 1 < len(label):
            nxt = label[i + 1]
            if nxt in "nlr":
                lines.append(cur)
                cur = ""
            else:
                cur += nxt
            i += 2
            continue
        cur += ch
        i += 1
    if cur or not label.endswith(("\\n", "\\l", "\\r")):
        lines.append(cur)
    return [html.unescape(line) for line in lines]


def svg_texts(data: bytes) -> list[str]:
    root = etree.fromstring(data)
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    return ["".join(str(s) for s in t.itertext()) for t in root.iter(SVG_TEXT)]


def line_matches(shown: str, full: str) -> bool:
    """``shown`` is ``full``, or ``full`` shortened with an ellipsis."""
    if shown == full:
        return True
    if full.startswith("[") and shown.startswith("[") and shown.endswith("]"):
        shown, full = shown[1:-1], full[1:-1]
    return (shown.endswith("…") and len(shown) <= dot.LABEL_LIMIT
            and full.startswith(shown[:-1].rstrip()) and len(shown) < len(full))


def leaves(auto: Automaton) -> list[tuple[State, bool]]:
    """Every simple state under ``auto`` with whether it is initial in its parent."""
    out: list[tuple[State, bool]] = []
    for s in auto.states:
        if s.automaton is None:
            out.append((s, s.name == auto.initial))
        else:
            out.extend(leaves(s.automaton))
    return out


def composites(auto: Automaton) -> list[State]:
    out: list[State] = []
    for s in auto.states:
        if s.automaton is not None:
            out.append(s)
            out.extend(composites(s.automaton))
    return out


def expected_transitions(auto: Automaton) -> list[tuple[str, str, list[str]]]:
    """(source path, target path, full label lines) of every transition under ``auto``."""
    out: list[tuple[str, str, list[str]]] = []
    for s in auto.states:
        parent = s.path.rpartition("/")[0]
        for t in s.transitions:
            lines = []
            if t.name:
                lines.append(t.name)
            if t.when is not None:
                lines.append("[" + " ".join(ln.strip() for ln in t.when.text.splitlines()
                                            if ln.strip()) + "]")
            if t.after_us is not None:
                lines.append(f"after {format_us(t.after_us)}")
            out.append((s.path, f"{parent}/{t.target}" if parent else t.target, lines))
        if s.automaton is not None:
            out.extend(expected_transitions(s.automaton))
    return out


def drawn_transitions(graph: dict[str, Any]) -> list[tuple[str, str, list[str]]]:
    """(source, target, label lines) of the arrows in a graph read by ``read_dot``.

    An end clipped at a cluster (``ltail`` / ``lhead``) stands for the
    composite state; an arrow through a helper node (``#...``, which carries
    the label) counts once.
    """
    objects = {o["_gvid"]: o for o in graph.get("objects", []) if "nodes" not in o}
    edges = graph.get("edges", [])
    out = []
    for e in edges:
        tail, head = objects[e["tail"]]["name"], objects[e["head"]]["name"]
        if tail.startswith("#"):
            continue  # second half of an arrow through a helper node
        src = e["ltail"].removeprefix("cluster_") if "ltail" in e else tail
        label = e.get("label", "")
        if head.startswith("#"):
            assert e.get("arrowhead") == "none"
            label = objects[e["head"]]["label"]
            (back,) = [b for b in edges if b["tail"] == e["head"]]
            head = objects[back["head"]]["name"]
            e = {**e, "lhead": back.get("lhead")}
        dst = e["lhead"].removeprefix("cluster_") if e.get("lhead") else head
        out.append((src, dst, esc_lines(label)))
    return out


def check_structure(model: Model, source: str, auto: Automaton | None = None) -> dict[str, Any]:
    """The DOT of ``model`` (or of the sub-automaton ``auto``) against the model."""
    auto = auto or model.root
    graph = read_dot(source)
    assert graph["compound"] == "true"
    assert graph["rankdir"] == "LR"
    assert graph["newrank"] == "true"
    objects = graph.get("objects", [])
    clusters = {o["name"]: o for o in objects if "nodes" in o}
    nodes = {o["name"]: o for o in objects if "nodes" not in o and not o["name"].startswith("#")}

    # one cluster per composite state, labelled with its name and period
    assert set(clusters) == {f"cluster_{s.path}" for s in composites(auto)}
    for s in composites(auto):
        assert s.automaton is not None
        lines = esc_lines(clusters[f"cluster_{s.path}"]["label"])
        assert lines[0] == s.name
        assert f"period {format_us(s.automaton.period_ms * 1000)}" in lines[1]
        assert ("history" in lines[1]) == s.automaton.history
        members = set(clusters[f"cluster_{s.path}"].get("nodes", []))
        member_names = {o["name"] for o in objects if o["_gvid"] in members}
        assert {n for n in member_names if not n.startswith("#")} == {
            leaf.path for leaf, _ in leaves(s.automaton)}

    # simple states: a circle, a double circle when initial, grey when final
    expected = leaves(auto)
    assert set(nodes) == {s.path for s, _ in expected}
    for s, initial in expected:
        node = nodes[s.path]
        assert esc_lines(node["label"]) == [s.name]
        assert node["shape"] == ("doublecircle" if initial else "circle"), s.path
        assert (node["fillcolor"] == dot.FINAL_FILL) == s.final, s.path

    # a transition's label node sits in the cluster of its own sub-automaton
    # (else dot routes the arrow out of that cluster and back)
    for e in graph.get("edges", []):
        head = next(o for o in objects if o["_gvid"] == e["head"])
        if not head["name"].startswith("#") or e.get("arrowhead") != "none":
            continue
        tail = next(o for o in objects if o["_gvid"] == e["tail"])["name"]
        src = e["ltail"].removeprefix("cluster_") if "ltail" in e else tail
        parent = src.rpartition("/")[0]
        holders = [c for c in clusters.values() if e["head"] in c.get("nodes", [])]
        innermost = max((c["name"] for c in holders), key=len, default=None)
        assert innermost == (f"cluster_{parent}" if parent != auto.owner else None), src

    # one arrow per transition, between the right states, with its label
    drawn = drawn_transitions(graph)
    want = expected_transitions(auto)
    assert Counter((s, d) for s, d, _ in drawn) == Counter((s, d) for s, d, _ in want)
    for src, dst, lines in want:
        candidates = [shown for s, d, shown in drawn if (s, d) == (src, dst)]
        assert any(len(shown) == len(lines) and all(map(line_matches, shown, lines))
                   for shown in candidates), (src, dst, lines, candidates)
    return graph


# ---------------------------------------------------------------------------
# every example


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.stem)
def test_example_svg_through_cli(example: Path, tmp_path: Path) -> None:
    out = tmp_path / f"{example.stem}.svg"
    result = run_cli(str(example), "-o", str(out))
    assert result.exit_code == 0, result.output
    texts = svg_texts(out.read_bytes())
    model = compile_model(example)
    for s in model.states():
        assert s.name in texts, s.path


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.stem)
@pytest.mark.parametrize("how", ["script", "module"])
def test_example_svg_in_a_subprocess(example: Path, how: str, tmp_path: Path) -> None:
    script = Path(sys.executable).with_name("hfsmc")
    if how == "script":
        assert script.exists(), "the hfsmc console script is installed beside the interpreter"
        cmd = [str(script)]
    else:
        cmd = [sys.executable, "-m", "hfsmc"]
    out = tmp_path / "out.svg"
    proc = subprocess.run([*cmd, "diagram", str(example), "-o", str(out)],
                          capture_output=True, text=True, check=False, timeout=120)
    assert proc.returncode == 0, proc.stderr
    texts = svg_texts(out.read_bytes())
    for s in compile_model(example).states():
        assert s.name in texts, s.path


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.stem)
def test_example_dot_structure(example: Path) -> None:
    model = compile_model(example)
    check_structure(model, dot.to_dot(model))


def test_examples_exist() -> None:
    assert EXAMPLES, "no examples/*/*.yaml found"


def test_traffic_light_labels() -> None:
    model = compile_model(ROOT / "examples/traffic_light/traffic_light.yaml")
    graph = read_dot(dot.to_dot(model))
    labels = {(s, d): lines for s, d, lines in drawn_transitions(graph)}
    assert labels[("Green", "Amber")] == ["button", "[button]"]
    assert labels[("Red", "Night")] == ["done", "[count >= cycles]"]
    assert labels[("Red", "Green")] == ["after 5s"]
    assert graph["label"].startswith("traffic_light")


# ---------------------------------------------------------------------------
# composite states


def test_nested_structure(tmp_path: Path) -> None:
    model = compile_model(write_model(tmp_path, NESTED))
    graph = check_structure(model, dot.to_dot(model))
    edges = graph["edges"]
    # transitions into and out of composites are clipped at the clusters
    assert any(e.get("lhead") == "cluster_Follow" for e in edges)
    assert any(e.get("ltail") == "cluster_Follow" for e in edges)
    assert any(e.get("lhead") == "cluster_Follow/Track" for e in edges)
    assert any(e.get("ltail") == "cluster_Follow/Track" for e in edges)
    # a self-transition of a simple state is a loop
    names = {o["_gvid"]: o["name"] for o in graph["objects"]}
    assert any(names[e["tail"]] == names[e["head"]] == "Follow/Lost" for e in edges)


def test_nested_renders_svg_and_png(tmp_path: Path) -> None:
    path = write_model(tmp_path, NESTED)
    for suffix in (".svg", ".png"):
        out = tmp_path / f"nested{suffix}"
        result = run_cli(str(path), "-o", str(out))
        assert result.exit_code == 0, result.output
    texts = svg_texts((tmp_path / "nested.svg").read_bytes())
    for name in ("TakeOff", "Follow", "Track", "Approach", "Hold", "Lost", "Land", "Done"):
        assert name in texts
    assert "period 100ms · history" in texts
    assert (tmp_path / "nested.png").read_bytes().startswith(PNG_SIGNATURE)


def test_initial_final_state_is_recognisable(tmp_path: Path) -> None:
    text = NESTED.replace(
        "  Done: {final: true}",
        "  Done:\n    initial: Idle\n    states:\n      Idle: {final: true}",
    )
    model = compile_model(write_model(tmp_path, text))
    graph = check_structure(model, dot.to_dot(model))
    nodes = {o["name"]: o for o in graph["objects"]}
    idle = nodes["Done/Idle"]
    assert idle["shape"] == "doublecircle"
    assert idle["fillcolor"] == dot.FINAL_FILL
    assert nodes["Follow/Lost"]["fillcolor"] != dot.FINAL_FILL


def test_png_output(tmp_path: Path) -> None:
    out = tmp_path / "tl.png"
    result = run_cli(str(ROOT / "examples/traffic_light/traffic_light.yaml"), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert out.read_bytes().startswith(PNG_SIGNATURE)


def test_dot_output_is_the_source(tmp_path: Path) -> None:
    path = write_model(tmp_path, NESTED)
    out = tmp_path / "nested.dot"
    result = run_cli(str(path), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert out.read_text(encoding="utf-8") == dot.to_dot(compile_model(path))


def test_default_output_is_svg_beside_the_model(tmp_path: Path) -> None:
    path = write_model(tmp_path, NESTED, "beside.yaml")
    result = run_cli(str(path))
    assert result.exit_code == 0, result.output
    svg_texts((tmp_path / "beside.svg").read_bytes())


# ---------------------------------------------------------------------------
# --state


def test_state_draws_only_that_sub_automaton(tmp_path: Path) -> None:
    path = write_model(tmp_path, NESTED)
    model = compile_model(path)
    follow = model.find("Follow")
    assert follow is not None and follow.automaton is not None
    graph = check_structure(model, dot.to_dot(model, "Follow"), follow.automaton)
    names = {o["name"] for o in graph["objects"]}
    assert "TakeOff" not in names and "Land" not in names and "cluster_Follow" not in names
    assert "Follow/Lost" in names and "cluster_Follow/Track" in names

    out = tmp_path / "follow.svg"
    result = run_cli(str(path), "--state", "Follow", "-o", str(out))
    assert result.exit_code == 0, result.output
    texts = svg_texts(out.read_bytes())
    assert {"Track", "Approach", "Hold", "Lost"} <= set(texts)
    assert not {"TakeOff", "Land", "Done"} & set(texts)


def test_state_nested_path(tmp_path: Path) -> None:
    model = compile_model(write_model(tmp_path, NESTED))
    track = model.find("Follow/Track")
    assert track is not None and track.automaton is not None
    graph = check_structure(model, dot.to_dot(model, "Follow/Track"), track.automaton)
    assert {o["name"] for o in graph["objects"]} == {"Follow/Track/Approach", "Follow/Track/Hold"}


@pytest.mark.parametrize(("state", "message"), [
    ("Nowhere", "no such state"),
    ("Folow", "did you mean `Follow`"),
    ("Follow/Nowhere", "no such state"),
    ("Land", "has no sub-automaton"),
    ("Follow/Lost", "has no sub-automaton"),
    ("", "no such state"),
])
def test_state_errors(tmp_path: Path, state: str, message: str) -> None:
    path = write_model(tmp_path, NESTED)
    with pytest.raises(UsageError, match=message):
        dot.to_dot(compile_model(path), state)
    out = tmp_path / "out.svg"
    result = run_cli(str(path), "--state", state, "-o", str(out))
    assert result.exit_code == 2, result.output
    assert message in result.stderr
    assert "Traceback" not in result.output
    assert not out.exists()


# ---------------------------------------------------------------------------
# labels and escaping


def test_long_condition_is_shortened_with_an_ellipsis(tmp_path: Path) -> None:
    cond = " and ".join(f"stage != {i}" for i in range(20))
    text = NESTED.replace("{to: Done, when: not seen}", f"{{to: Done, when: '{cond}'}}")
    path = write_model(tmp_path, text)
    model = compile_model(path)
    source = dot.to_dot(model)
    assert cond not in source
    graph = check_structure(model, source)
    (shown,) = [lines for s, d, lines in drawn_transitions(graph) if (s, d) == ("Land", "Done")]
    assert len(shown) == 1
    assert shown[0].startswith("[stage != 0 and stage != 1")
    assert shown[0].endswith("…]")
    assert len(shown[0]) <= dot.LABEL_LIMIT

    out = tmp_path / "long.svg"
    assert run_cli(str(path), "-o", str(out)).exit_code == 0
    assert shown[0] in svg_texts(out.read_bytes())


def test_multi_line_condition_is_joined(tmp_path: Path) -> None:
    text = NESTED.replace("{to: Done, when: not seen}",
                          "{to: Done, when: \"(stage > 1 and\\n   not seen)\"}")
    model = compile_model(write_model(tmp_path, text))
    graph = check_structure(model, dot.to_dot(model))
    labels = {(s, d): lines for s, d, lines in drawn_transitions(graph)}
    assert labels[("Land", "Done")] == ["[(stage > 1 and not seen)]"]


def test_escaping_renders_valid_svg(tmp_path: Path) -> None:
    path = write_model(tmp_path, NASTY)
    model = compile_model(path)
    check_structure(model, dot.to_dot(model))
    out = tmp_path / "nasty.svg"
    result = run_cli(str(path), "-o", str(out))
    assert result.exit_code == 0, result.output
    texts = svg_texts(out.read_bytes())
    for s in model.states():
        assert s.name in texts, s.path
    assert '[a < b and c == "x" or d > {1}]' in texts
    assert '<b>bold</b> "quoted" \\N {x|y}' in texts
    assert "été → \U0001F600" in texts
    assert '[c == "\\\\N\\\\l&amp;\\\\"]' in texts
    assert "[c != \"<>\" and a | b & d]" in texts
    assert "after 1.5s" in texts
    png = tmp_path / "nasty.png"
    assert run_cli(str(path), "-o", str(png)).exit_code == 0
    assert png.read_bytes().startswith(PNG_SIGNATURE)


def test_control_characters_do_not_break_svg(tmp_path: Path) -> None:
    text = NESTED.replace("{to: Done, when: not seen}",
                          "{to: Done, name: \"a\\x01b\\u2028c\", when: not seen}")
    model = compile_model(write_model(tmp_path, text))
    source = dot.to_dot(model)
    svg = dot.render(source, "svg")
    # \x01 is shown escaped; U+2028 breaks the line, which is joined with a space
    assert "a\\x01b c" in svg_texts(svg)


def test_the_graph_has_the_required_attributes() -> None:
    model = compile_model(ROOT / "examples/traffic_light/traffic_light.yaml")
    graph = read_dot(dot.to_dot(model))
    assert graph["fontname"] == dot.FONT
    assert "sans" in graph["fontname"].lower()


# ---------------------------------------------------------------------------
# determinism


def test_same_model_same_dot(tmp_path: Path) -> None:
    path = write_model(tmp_path, NASTY)
    assert dot.to_dot(compile_model(path)) == dot.to_dot(compile_model(path))
    outs = []
    for seed in ("0", "12345"):
        out = tmp_path / f"out{seed}.dot"
        env = {**os.environ, "PYTHONHASHSEED": seed}
        proc = subprocess.run([sys.executable, "-m", "hfsmc", "diagram", str(path), "-o", str(out)],
                              capture_output=True, text=True, env=env, check=False, timeout=120)
        assert proc.returncode == 0, proc.stderr
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert outs[0].decode("utf-8") == dot.to_dot(compile_model(path))


# ---------------------------------------------------------------------------
# Graphviz missing or failing


def test_missing_dot_is_a_usage_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_model(tmp_path, NESTED)
    out = tmp_path / "out.svg"
    out.write_bytes(b"old")
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(UsageError, match=r"Graphviz `dot` not found: install the graphviz"):
        dot.write_diagram(compile_model(path), out, None)
    result = run_cli(str(path), "-o", str(out))
    assert result.exit_code == 2
    assert "apt-get install graphviz" in result.stderr
    assert out.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.yaml", "out.svg"]
    # .dot needs no Graphviz
    assert run_cli(str(path), "-o", str(tmp_path / "out.dot")).exit_code == 0


def test_failing_dot_is_a_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def fail(*args: object, **kwargs: object) -> bytes:
        raise graphviz.CalledProcessError(1, ["dot", "-Tsvg"], b"", b"Error: trouble in init_rank\n")

    path = write_model(tmp_path, NESTED)
    out = tmp_path / "out.png"
    monkeypatch.setattr(graphviz.Source, "pipe", fail)
    with pytest.raises(UsageError, match=r"Graphviz `dot` failed \(exit status 1\).*init_rank"):
        dot.write_diagram(compile_model(path), out, None)
    result = run_cli(str(path), "-o", str(out))
    assert result.exit_code == 2
    assert "trouble in init_rank" in result.stderr
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.yaml"]


def test_unknown_suffix_is_a_usage_error(tmp_path: Path) -> None:
    path = write_model(tmp_path, NESTED)
    with pytest.raises(UsageError, match=r"\.svg, \.png or \.dot"):
        dot.write_diagram(compile_model(path), tmp_path / "out.pdf", None)
    assert not (tmp_path / "out.pdf").exists()
