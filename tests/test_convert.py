"""hfsmc convert and diagram: file modes, in-place edits that keep the user's text, comments."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from hfsmc import cli
from hfsmc.commands.convert import yaml_comments
from hfsmc.fsutil import write_atomic

MODEL = """\
# yaml-language-server: $schema=../../schemas/hfsm.schema.json
hfsm: 1
name: m
description: |
  # a heading, not a comment
parameters:
  gain: {type: float, default: 2.0, description: how hard to steer}  # tune me
variables:
  v: 0.0   # speed
  w: 1.50
  n: 0x10
  s: 'a # b'
  xs: [1, 2]
period: 100ms
initial: A
states:
  # the first -- state
  A:
    entry: |
      x = 1  # code, kept as code
    transitions:
      - {to: B, after: 1s}  # one second
  B: {final: true}
"""


def run(*args: str) -> tuple[int, str]:
    r = CliRunner().invoke(cli.main, list(args))
    return r.exit_code, r.stderr


@pytest.fixture
def umask_027() -> Iterator[None]:
    old = os.umask(0o027)
    yield
    os.umask(old)


def mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def test_write_atomic_new_file_takes_umask_existing_keeps_mode(tmp_path: Path,
                                                                umask_027: None) -> None:
    new = tmp_path / "new.txt"
    assert write_atomic(new, "a")
    assert mode(new) == 0o640
    old = tmp_path / "old.txt"
    old.write_text("a")
    old.chmod(0o604)
    assert write_atomic(old, "b")
    assert mode(old) == 0o604 and old.read_text() == "b"


def test_convert_and_diagram_files_have_the_users_mode(tmp_path: Path, umask_027: None) -> None:
    src = tmp_path / "m.yaml"
    src.write_text(MODEL)
    src.chmod(0o664)
    assert run("convert", str(src), "-o", str(tmp_path / "m.xml"))[0] == 0
    assert run("diagram", str(src), "-o", str(tmp_path / "m.dot"))[0] == 0
    assert mode(tmp_path / "m.xml") == 0o640
    assert mode(tmp_path / "m.dot") == 0o640
    assert run("convert", str(src), "-o", str(src))[0] == 0
    assert mode(src) == 0o664  # an in-place edit keeps the file's mode


def test_xml_back_onto_the_yaml_changes_nothing(tmp_path: Path) -> None:
    """XML names every variable's type; the YAML's bare `v: 0.0` stays as written,
    and `language`, which the YAML left to its default, is not added."""
    src = tmp_path / "m.yaml"
    src.write_text(MODEL)
    assert run("convert", str(src), "-o", str(tmp_path / "m.xml"))[0] == 0
    assert run("convert", str(tmp_path / "m.xml"), "-o", str(src))[0] == 0
    assert src.read_text() == MODEL


def test_xml_changes_reach_the_yaml_and_only_them(tmp_path: Path) -> None:
    src = tmp_path / "m.yaml"
    src.write_text(MODEL)
    xml = tmp_path / "m.xml"
    assert run("convert", str(src), "-o", str(xml))[0] == 0
    xml.write_text(xml.read_text().replace('init="0.0"', 'init="0.5"'))
    assert run("convert", str(xml), "-o", str(src))[0] == 0
    assert src.read_text() == MODEL.replace("v: 0.0   # speed", "v: 0.5   # speed")


def test_yaml_comments_become_xml_comments(tmp_path: Path) -> None:
    src = tmp_path / "m.yaml"
    src.write_text(MODEL)
    xml = tmp_path / "m.xml"
    assert run("convert", str(src), "-o", str(xml))[0] == 0
    lines = [line.strip() for line in xml.read_text().splitlines()]
    assert lines[lines.index("<!-- tune me -->") + 1].startswith('<parameter name="gain"')
    assert 'description="how hard to steer"' in lines[lines.index("<!-- tune me -->") + 1]
    assert lines[lines.index("<!-- speed -->") + 1].startswith('<variable name="v"')
    assert lines[lines.index("<!-- the first - - state -->") + 1] == '<state name="A">'
    assert lines[lines.index("<!-- one second -->") + 1].startswith('<transition to="B"')
    assert "x = 1  # code, kept as code" in lines
    assert not any("yaml-language-server" in line or ("heading" in line and "<!--" in line)
                   for line in lines)
    # The XML with its comments reads back as the same model.
    assert run("check", str(xml))[0] == 0


def test_yaml_comments_skip_block_scalars_and_quoted_hashes() -> None:
    got = yaml_comments(MODEL.splitlines(keepends=True))
    assert got == [(7, "tune me"), (9, "speed"), (17, "the first -- state"), (22, "one second")]


REGIONS = """\
hfsm: 1
name: arm
variables: {n: 0}
initial: Work
states:
  Work:
    regions:
      # the joints move
      Joints:
        period: 50ms  # fast
        initial: Move
        states:
          Move: {transitions: [{to: Still, after: 1s}]}
          Still: {final: true}
      # the gripper closes
      Gripper:
        initial: Open
        states:
          Open:
            during: n += 1
            transitions: [{to: Closed, when: n > 3}]  # squeeze
          Closed: {final: true}
    transitions:
      - {to: Done, when: done()}  # both regions final
  Done: {final: true}
"""


def test_regions_convert_both_ways_keeping_comments(tmp_path: Path) -> None:
    src = tmp_path / "arm.yaml"
    src.write_text(REGIONS)
    xml = tmp_path / "arm.xml"
    assert run("convert", str(src), "-o", str(xml))[0] == 0
    lines = [line.strip() for line in xml.read_text().splitlines()]
    assert lines[lines.index("<!-- the joints move -->") + 2].startswith('<region name="Joints"')
    assert lines[lines.index("<!-- the gripper closes -->") + 1].startswith(
        '<region name="Gripper" initial="Open">')
    assert lines[lines.index("<!-- squeeze -->") + 1] == '<transition to="Closed">'
    assert lines[lines.index("<!-- both regions final -->") + 1] == '<transition to="Done">'
    # The regions come before the state's transition, as in the YAML.
    assert lines.index("</region>") < lines.index('<transition to="Done">')
    # An edit in the XML reaches the YAML, whose comments and layout stay.
    xml.write_text(xml.read_text().replace('initial="Open"', 'initial="Closed"'))
    assert run("convert", str(xml), "-o", str(src))[0] == 0
    assert src.read_text() == REGIONS.replace("initial: Open", "initial: Closed")


USED = """\
hfsm: 1
name: wait
initial: Waiting
states:
  Waiting: {transitions: [{to: Over, after: 1s}]}
  Over: {final: true}
"""
USING = """\
hfsm: 1
name: twice
initial: A
states:
  A:
    use: lib/wait.yaml
    transitions: [{to: B, when: done()}]
  B: {final: true}
"""


def test_convert_to_another_folder_rewrites_use_paths_from_there(tmp_path: Path) -> None:
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "wait.yaml").write_text(USED, "utf-8")
    (tmp_path / "twice.yaml").write_text(USING, "utf-8")
    (tmp_path / "out" / "deep").mkdir(parents=True)
    code, text = run("convert", str(tmp_path / "twice.yaml"), "-o", str(tmp_path / "out" / "deep" / "twice.xml"))
    assert code == 0, text
    assert "lib/wait.yaml -> ../../lib/wait.yaml" in text
    xml = (tmp_path / "out" / "deep" / "twice.xml").read_text("utf-8")
    assert 'use="../../lib/wait.yaml"' in xml
    code, text = run("check", str(tmp_path / "out" / "deep" / "twice.xml"))
    assert code == 0, text
    # beside the source: the path stays as written, and nothing is said about it
    code, text = run("convert", str(tmp_path / "twice.yaml"), "-o", str(tmp_path / "twice.xml"))
    assert code == 0 and "use` paths" not in text
    assert 'use="lib/wait.yaml"' in (tmp_path / "twice.xml").read_text("utf-8")
