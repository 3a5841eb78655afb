"""The model's `time_limit` (docs/model.md): read from YAML and XML alike, written back by
`convert`, drawn on the diagram's interrupt marker, and warned of without `on_interrupt`
(W216). How a component acts on it is the conformance suite's (82-85, both languages)."""

from __future__ import annotations

from pathlib import Path

from hfsmc.pipeline import compile_file
from tests.support import hfsmc

MODEL = """\
hfsm: 1
name: limited
language: python
{interrupt}time_limit: 90s
initial: Fly
states:
  Fly:
    transitions: [{{to: Land, after: 1m}}]
  Land:
    transitions: [{{to: Done, after: 5s}}]
  Done: {{final: true}}
"""


def test_yaml_xml_and_back_keep_it(tmp_path: Path) -> None:
    src = tmp_path / "limited.yaml"
    src.write_text(MODEL.format(interrupt="on_interrupt: Land\ninterrupt_timeout: 20s\n"))
    first = compile_file(str(src))
    assert first.ok and first.model is not None and first.model.time_limit_us == 90_000_000
    r = hfsmc("convert", str(src), "-o", str(tmp_path / "limited.xml"))
    assert r.returncode == 0, r.stderr
    xml = (tmp_path / "limited.xml").read_text()
    assert 'time_limit="90s"' in xml
    r = hfsmc("convert", str(tmp_path / "limited.xml"), "-o", str(tmp_path / "again.yaml"))
    assert r.returncode == 0, r.stderr
    assert "time_limit: 90s\n" in (tmp_path / "again.yaml").read_text()
    back = compile_file(str(tmp_path / "limited.xml"))
    assert back.model is not None and back.model.time_limit_us == 90_000_000
    r = hfsmc("build", str(src), "--dump-ir")
    assert "  time_limit 90s\n" in r.stdout, r.stdout + r.stderr
    r = hfsmc("diagram", str(src), "-o", str(tmp_path / "limited.svg"))
    assert r.returncode == 0, r.stderr
    assert "time limit 90s" in (tmp_path / "limited.svg").read_text()


def test_without_on_interrupt_it_is_a_warning_at_its_key(tmp_path: Path) -> None:
    src = tmp_path / "limited.yaml"
    src.write_text(MODEL.format(interrupt=""))
    found = [(d.code, d.severity, d.span.line, d.span.col) for d in compile_file(str(src)).diagnostics]
    assert found == [("W216", "warning", 4, 1)]
    r = hfsmc("check", "--strict", str(src))
    assert r.returncode == 1 and "warning[W216]: time_limit without on_interrupt" in r.stdout + r.stderr
