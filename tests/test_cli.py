"""The command line: exit statuses, output shapes, one real subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from hfsmc import cli
from tests.conftest import ROOT, examples

TRAFFIC = "examples/traffic_light/traffic_light.yaml"

WARNY = """\
hfsm: 1
name: warny
initial: A
states:
  A:
    transitions:
      - {to: B, after: 1s}
      - {to: B, after: 2s}
  B: {final: true}
  Lonely: {final: true}
"""

BROKEN = """\
hfsm: 1
name: broken
initial: A
states:
  A:
    entry: x = nowhere
    transitions: [{to: Z, after: 1s}]
"""


def run(*args: str) -> tuple[int, str, str]:
    r = CliRunner().invoke(cli.main, list(args))
    return r.exit_code, r.stdout, r.stderr


def write(tmp_path: Path, name: str, text: str) -> str:
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_examples_check_clean() -> None:
    code, _out, err = run("check", *map(str, examples()))
    assert code == 0, err
    assert err == ""


def test_errors_exit_1_with_compiler_shape(tmp_path: Path) -> None:
    path = write(tmp_path, "broken.yaml", BROKEN)
    code, _out, err = run("check", path)
    assert code == 1
    lines = err.splitlines()
    assert lines[0] == f"{path}:6:16: error[E141]: undefined name `nowhere` in entry of `A`"
    assert lines[1] == "      entry: x = nowhere"
    assert lines[2].index("^") == lines[1].index("nowhere")
    assert f"{path}:7:24: error[E132]: transition to unknown state `Z`" in err
    assert "1 model(s): 2 error(s), 0 warning(s)" in err


def test_all_models_reported_in_one_run(tmp_path: Path) -> None:
    a = write(tmp_path, "a.yaml", BROKEN)
    b = write(tmp_path, "b.yaml", BROKEN.replace("nowhere", "elsewhere"))
    code, out, _ = run("check", "--format", "json", a, TRAFFIC, b)
    assert code == 1
    diags = json.loads(out)
    assert {(d["file"], d["code"]) for d in diags} == {(a, "E141"), (a, "E132"), (b, "E141"), (b, "E132")}
    assert all(set(d) == {"file", "line", "col", "severity", "code", "message", "notes"} for d in diags)


def test_warnings_pass_unless_strict(tmp_path: Path) -> None:
    path = write(tmp_path, "warny.yaml", WARNY)
    code, _, err = run("check", path)
    assert code == 0
    assert "warning[W203]" in err and "warning[W201]" in err
    code, _, _ = run("check", "--strict", path)
    assert code == 1


def test_usage_errors_exit_2() -> None:
    assert run("check")[0] == 2
    assert run("check", "--no-such-flag", TRAFFIC)[0] == 2
    assert run("frobnicate")[0] == 2


def test_missing_file_is_a_positioned_error(tmp_path: Path) -> None:
    missing = str(tmp_path / "nope.yaml")
    code, _, err = run("check", missing)
    assert code == 1
    assert err.startswith(f"{missing}:1:1: error[E001]: cannot read the file")


def test_dump_ir() -> None:
    code, out, _ = run("check", "--dump-ir", TRAFFIC)
    assert code == 0
    assert out.startswith("model traffic_light (python) from traffic_light.yaml\n")
    assert "transition 1 -> Green after 5s @43:9" in out


def test_internal_error_shows_no_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(path: str, text: str | None = None, cxx: bool = False) -> None:
        raise RuntimeError("kaboom")

    monkeypatch.setattr(cli, "compile_file", boom)
    code, _, err = run("check", TRAFFIC)
    assert code == 3
    assert "internal error: RuntimeError: kaboom" in err
    assert "Traceback" not in err


def test_real_subprocess() -> None:
    r = subprocess.run([sys.executable, "-m", "hfsmc", "check", "--format", "json", TRAFFIC],
                       cwd=ROOT, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == []
    r = subprocess.run([sys.executable, "-m", "hfsmc", "--version"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0 and "hfsmc" in r.stdout


def test_convert_in_place_keeps_comments(tmp_path: Path) -> None:
    src = tmp_path / "tl.yaml"
    original = (ROOT / TRAFFIC).read_text()
    src.write_text(original)
    code, _, err = run("convert", str(src), "-o", str(src))
    assert code == 0, err
    assert src.read_text() == original  # nothing changed, every comment kept


def test_convert_edits_existing_yaml(tmp_path: Path) -> None:
    """Converting over an existing YAML model keeps its comments where keys survive."""
    old = tmp_path / "old.yaml"
    old.write_text(WARNY.replace("name: warny", "name: warny  # the component\n# about states"))
    new = tmp_path / "new.yaml"
    new.write_text(WARNY.replace("after: 2s", "after: 3s"))
    code, _, err = run("convert", str(new), "-o", str(old))
    assert code == 0, err
    text = old.read_text()
    assert "# the component" in text and "# about states" in text
    assert "after: 3s" in text and "after: 2s" not in text


def test_convert_rejects_unknown_suffix(tmp_path: Path) -> None:
    code, _, err = run("convert", TRAFFIC, "-o", str(tmp_path / "x.json"))
    assert code == 2
    assert "must end in .yaml, .yml or .xml" in err


def test_convert_in_place_keeps_equivalent_spellings(tmp_path: Path) -> None:
    """`5000ms` means `5s` and `true` means `True`: an in-place edit leaves them as written."""
    src = tmp_path / "m.yaml"
    original = WARNY.replace("name: warny", "name: warny\nlanguage: python").replace(
        "after: 2s", "after: 2000ms").replace(
        "  A:\n", "  A:\n    during: 'x = 1'\n").replace("after: 1s}", "after: 1000, when: true}")
    src.write_text(original)
    code, _, err = run("convert", str(src), "-o", str(src))
    assert code == 0, err
    assert src.read_text() == original
