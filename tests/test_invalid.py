"""Every bad model under ``tests/invalid/`` gives its diagnostic at its position.

``tests/invalid/EXPECTED`` holds one line per file, ``FILENAME CODE LINE:COL``:
the diagnostic that file must produce (it may produce others too).  Lines
starting with ``#`` are comments.  Paths are relative to the repository root,
which is the working directory of the tests (see ``conftest.py``).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from hfsmc.cli import main
from hfsmc.errors import CODES, Diagnostic
from hfsmc.frontend import is_xml
from hfsmc.pipeline import compile_file

INVALID = Path(__file__).resolve().parent / "invalid"
EXPECTED_FILE = INVALID / "EXPECTED"
MIN_CORPUS = 40
_LINE = re.compile(r"^(?P<file>\S+)\s+(?P<code>[EW]\d{3})\s+(?P<line>\d+):(?P<col>\d+)\s*$")


@dataclass(frozen=True, slots=True)
class Expected:
    file: str
    code: str
    line: int
    col: int

    @property
    def path(self) -> str:
        """The path as given to hfsmc, relative to the repository root."""
        return f"tests/invalid/{self.file}"

    @property
    def where(self) -> str:
        return f"{self.path}:{self.line}:{self.col}"


def read_expected() -> list[Expected]:
    """The lines of EXPECTED; a malformed line fails loudly, naming its line number."""
    out: list[Expected] = []
    for n, raw in enumerate(EXPECTED_FILE.read_text("utf-8").splitlines(), 1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        m = _LINE.match(text)
        if m is None:
            raise ValueError(f"{EXPECTED_FILE}:{n}: not `FILENAME CODE LINE:COL`: {raw!r}")
        out.append(Expected(m["file"], m["code"], int(m["line"]), int(m["col"])))
    return out


CASES = read_expected()
IDS = [c.file for c in CASES]


def corpus_files() -> list[str]:
    return sorted(p.name for p in INVALID.iterdir() if p.is_file() and p.name != "EXPECTED")


def run_cli(*args: str) -> Result:
    return CliRunner().invoke(main, list(args))


def source_lines(path: str) -> list[str]:
    """The file's lines as YAML and XML number them: only CR, LF and CRLF end a line
    (not U+2028, NEL or form feed, as ``str.splitlines`` has it); bad UTF-8 replaced."""
    text = Path(path).read_bytes().decode("utf-8", errors="replace")
    lines = re.split(r"\r\n|\r|\n", text)
    return lines[:-1] if lines and not lines[-1] else lines


def short(diags: list[Diagnostic]) -> str:
    return "\n".join(f"  {d.span}: {d.severity}[{d.code}]: {d.message}" for d in diags) or "  (none)"


# ---------------------------------------------------------------------------
# the corpus itself


def test_expected_is_well_formed() -> None:
    files = [c.file for c in CASES]
    duplicates = sorted({f for f in files if files.count(f) > 1})
    assert not duplicates, f"files listed twice in EXPECTED: {duplicates}"
    unknown_codes = sorted({c.code for c in CASES} - CODES.keys())
    assert not unknown_codes, f"codes not in hfsmc.errors.CODES: {unknown_codes}"
    missing = sorted(f for f in files if not (INVALID / f).is_file())
    assert not missing, f"EXPECTED names files that do not exist: {missing}"
    assert all(c.line >= 1 and c.col >= 1 for c in CASES)


def test_every_file_has_an_expected_line() -> None:
    listed = {c.file for c in CASES}
    forgotten = [f for f in corpus_files() if f not in listed]
    assert not forgotten, f"add these to tests/invalid/EXPECTED: {forgotten}"


def test_corpus_is_large_enough() -> None:
    assert len(corpus_files()) >= MIN_CORPUS


# ---------------------------------------------------------------------------
# each bad model


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_expected_diagnostic(case: Expected) -> None:
    result = compile_file(case.path)
    errors = [d for d in result.diagnostics if d.severity == "error"]
    assert errors, f"{case.path} compiled without errors:\n{short(result.diagnostics)}"
    assert result.model is None
    assert not result.ok
    found = [(d.code, str(d.span)) for d in result.diagnostics]
    assert (case.code, case.where) in found, (
        f"expected {case.code} at {case.where}; got:\n{short(result.diagnostics)}")


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_cli_check_json(case: Expected) -> None:
    result = run_cli("check", "--format", "json", case.path)
    assert "Traceback" not in result.output
    assert "internal error" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert result.exit_code == 1, result.output
    diags = json.loads(result.stdout)
    assert any(d["severity"] == "error" for d in diags)
    for d in diags:
        assert {"file", "line", "col", "severity", "code", "message", "notes"} <= d.keys()
        assert d["file"] == case.path
    assert any(d["code"] == case.code and (d["line"], d["col"]) == (case.line, case.col)
               for d in diags), f"expected {case.code} at {case.where}; got:\n{result.stdout}"


_HEAD = re.compile(r"^(?P<file>.+?):(?P<line>\d+):(?P<col>\d+): (?:error|warning)\[[EW]\d{3}\]: \S.*$")
_SUMMARY = re.compile(r"^\d+ model\(s\): \d+ error\(s\), \d+ warning\(s\)$")


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_cli_text_has_compiler_shape(case: Expected) -> None:
    """``FILE:LINE:COL: error[E123]: message``, the source line, a caret under the column."""
    result = run_cli("check", case.path)
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    out = result.stderr.rstrip("\n").split("\n")
    assert out, "no diagnostics printed"
    assert _SUMMARY.match(out[-1]), f"last line is not the summary: {out[-1]!r}"
    src = source_lines(case.path)
    heads: list[str] = []
    i = 0
    while i < len(out) - 1:
        m = _HEAD.match(out[i])
        assert m, f"line {i + 1} of the output is not `FILE:LINE:COL: error[E123]: ...`: {out[i]!r}"
        assert m["file"] == case.path
        heads.append(out[i])
        line, col = int(m["line"]), int(m["col"])
        i += 1
        if 1 <= line <= len(src):
            # control characters are shown as U+FFFD, one column each
            shown = "".join(c if c >= " " or c == "\t" else "\ufffd" for c in src[line - 1])
            shown = shown.expandtabs(1)
            want = shown if len(shown) <= 200 else shown[:200] + "..."
            assert out[i] == "  " + want, (
                f"source line of {m['file']}:{line} is shown as {out[i]!r}, not {want!r}")
            caret = out[i + 1]
            assert caret.strip() == "^" and caret.endswith("^"), f"no caret line: {caret!r}"
            if col - 1 <= len(shown):
                assert caret.index("^") == 2 + col - 1, (
                    f"caret at column {caret.index('^') - 1}, not {col}:\n{out[i]}\n{caret}")
            i += 2
        while i < len(out) - 1 and out[i].startswith("  note: "):
            i += 1
    same = [f"{d.span}: {d.severity}[{d.code}]: {d.message}" for d in compile_file(case.path).diagnostics]
    assert heads == same, "the text output does not list the diagnostics of compile_file"


# ---------------------------------------------------------------------------
# diagnostics that name a thing put the caret on it


# code -> the message's name of the thing the caret must sit on
_NAMED = {
    "E003": re.compile(r'duplicate key "([^"]+)"'),
    "E100": re.compile(r"unknown key `([^`]+)`"),
    "E120": re.compile(r"`([^`]+)` is not an identifier"),
    "E131": re.compile(r"initial state `([^`]+)`"),
    "E132": re.compile(r"unknown state `([^`]+)`"),
    "E133": re.compile(r"-> `([^`]+)`"),
    "E136": re.compile(r"on_interrupt names `([^`]+)`"),
    "E141": re.compile(r"undefined name `([^`]+)`"),
    "E142": re.compile(r"parameter `([^`]+)`"),
    "E162": re.compile(r"-> `([^`]+)`"),
}

YAML_CASES = [c for c in CASES if (INVALID / c.file).is_file()
              and not is_xml((INVALID / c.file).read_bytes().decode("utf-8", errors="replace"))]


@pytest.mark.parametrize("case", YAML_CASES, ids=[c.file for c in YAML_CASES])
def test_caret_sits_on_the_named_thing(case: Expected) -> None:
    src = source_lines(case.path)
    for d in compile_file(case.path).diagnostics:
        pattern = _NAMED.get(d.code)
        m = pattern.search(d.message) if pattern else None
        if m is None:
            continue
        name = m[1]
        assert d.span.line in range(1, len(src) + 1), f"{d.span} is outside the file"
        at = src[d.span.line - 1][d.span.col - 1:]
        assert re.match(re.escape(name) + r"(?![A-Za-z0-9_])", at), (
            f"{d.span}: {d.code} {d.message!r}: the caret is on {at[:30]!r}, not on `{name}`")


def test_all_problems_reported_in_one_run() -> None:
    """docs/commands.md: every problem of a model in one run, not only the first."""
    result = compile_file("tests/invalid/several_problems.yaml")
    codes = {d.code for d in result.diagnostics if d.severity == "error"}
    assert {"E111", "E132", "E134", "E141"} <= codes, short(result.diagnostics)


# ---------------------------------------------------------------------------
# done() and regions: W215 is for a state without a sub-automaton only

_DONE = """\
hfsm: 1
name: arm
language: {language}
initial: Work
states:
  Work:
    regions:
      Joints: {{initial: Move, states: {{Move: {{final: true}}}}}}
      Gripper: {{initial: Open, states: {{Open: {{final: true}}}}}}
    transitions:
      - {{to: Idle, when: done()}}
  Idle:
    transitions:
      - {{to: Work, when: {idle}}}
"""


@pytest.mark.parametrize("language", ["python", "cpp"])
def test_done_in_a_state_with_regions_is_not_w215(language: str) -> None:
    """docs/model.md: done() of a state with regions is true once every region is final."""
    result = compile_file("m.yaml", text=_DONE.format(language=language, idle="done()"))
    assert [(d.code, str(d.span)) for d in result.diagnostics] == [("W215", "m.yaml:14:26")]
    clean = compile_file("m.yaml", text=_DONE.format(language=language, idle="elapsed() > 1"))
    assert clean.diagnostics == [] and clean.model is not None


@pytest.mark.parametrize("path", ["tests/invalid/region_transition_across.yaml",
                                  "tests/invalid/xml_region_transition_across.xml"])
def test_a_transition_across_regions_says_how_to_coordinate(path: str) -> None:
    d = next(d for d in compile_file(path).diagnostics if d.code == "E162")
    assert d.message == ("`Work/Joints/Move` -> `Closed`: `Closed` is in region `Gripper`, and "
                         "nothing crosses from one region of `Work` to another")
    assert d.notes == ('regions run side by side; to coordinate them, test '
                       'active("Work/Gripper/Closed") or a variable, or leave `Work` with a '
                       'transition of its own',)


def test_region_errors_speak_the_language_of_the_file() -> None:
    """E160 and E161 name `states`/`regions` in YAML, `<automaton>`/`<region>` in XML."""
    notes = {path: next(d for d in compile_file(f"tests/invalid/{path}").diagnostics
                        if d.code == code).notes[0]
             for path, code in (("region_and_states.yaml", "E160"), ("region_single.yaml", "E161"),
                                ("xml_region_beside_automaton.xml", "E160"),
                                ("xml_region_single.xml", "E161"))}
    assert notes == {
        "region_and_states.yaml": "move the states into a region, or drop `regions`",
        "region_single.yaml": "write the region's `initial` and `states` on `Work` itself",
        "xml_region_beside_automaton.xml": "move the automaton's states into a `<region>`, or "
                                           "drop the `<region>` elements",
        "xml_region_single.xml": "write the region as an `<automaton>` of `Work`",
    }
