"""What the code back ends hand their templates: a frozen view per target, read by
attribute, and the shared Jinja environment and runtime copy (hfsmc/emit/templating.py).
The generated text itself is checked by tests/test_golden.py."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jinja2
import pytest

from hfsmc.emit import cpp, python
from hfsmc.emit.templating import environment, runtime_files
from hfsmc.emit.walk import AutomatonView
from hfsmc.ir import Model
from hfsmc.pipeline import compile_file

LAMP = """hfsm: 1
name: lamp
language: {language}
variables:
  ok: false
initial: "Off"
states:
  "Off":
    transitions:
      - {{name: switch, to: "On", when: ok}}
  "On":
    initial: Dim
    states:
      Dim:
        transitions:
          - {{to: Bright, after: 1s}}
      Bright: {{}}
    transitions:
      - {{to: "Off", after: 5s}}
"""
AUTOMATA = (AutomatonView(index=0, owner=-1, region=None, use=None, period_ms=100, initial=0, history=False),
            AutomatonView(index=1, owner=1, region=None, use=None, period_ms=100, initial=2, history=False))


def lamp(language: str) -> Model:
    result = compile_file("lamp.yaml", LAMP.format(language=language))
    assert result.model is not None, result.diagnostics
    return result.model


def test_the_python_view_names_transitions_by_path() -> None:
    view = python.component_view(lamp("python"))
    assert [s.path for s in view.machine.states] == ["Off", "On", "On/Dim", "On/Bright"]
    assert view.machine.automata == AUTOMATA
    assert view.transition_paths == (
        python.TransitionPaths("Off", "On", 0, "switch"),
        python.TransitionPaths("On", "Off", 0, None),
        python.TransitionPaths("On/Dim", "On/Bright", 0, None))
    assert [(s.sid, s.kind, s.owner) for s in view.machine.snippets] == [(0, "when", 0)]


def test_the_cpp_view_numbers_transitions_by_index() -> None:
    view = cpp.component_view(lamp("cpp"))
    assert [s.path for s in view.machine.states] == ["Off", "On", "On/Dim", "On/Bright"]
    assert view.machine.automata == AUTOMATA
    assert view.transition_indices == (
        cpp.TransitionIndices(0, 1, 0, '"switch"'),
        cpp.TransitionIndices(1, 0, 0, '""'),
        cpp.TransitionIndices(2, 3, 0, '""'))
    assert (view.name, view.name_literal, view.interrupt_timeout_us) == ("lamp", '"lamp"', -1)


def test_views_are_frozen() -> None:
    view = python.component_view(lamp("python"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        view.name = "other"  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        view.machine.states[0].path = "Elsewhere"  # type: ignore[misc]


def test_a_template_reading_a_field_the_view_lacks_fails() -> None:
    view = cpp.component_view(lamp("cpp"))
    env = environment("cpp", {})
    template = env.from_string("{{ view.name }}:{{ view.machine.automata | length }}")
    assert template.render(view=view) == "lamp:2"
    with pytest.raises(jinja2.UndefinedError, match="transitions"):
        env.from_string("{{ view.transitions }}").render(view=view)


def test_runtime_files_are_copied_once_each_in_order(tmp_path: Path) -> None:
    for name in ("core.py", "radio.py", "eye.py"):
        (tmp_path / name).write_bytes(name.encode())
    out = runtime_files(tmp_path, ("core.py",), {"radio": ("radio.py", "core.py"),
                                                 "camera": ("eye.py",)},
                        ("camera", "radio", "camera", "unknown"), into="lib/")
    assert out == {"lib/core.py": b"core.py", "lib/eye.py": b"eye.py",
                   "lib/radio.py": b"radio.py"}
    assert list(out) == ["lib/core.py", "lib/eye.py", "lib/radio.py"]
