"""docs/semantics.md holds the runtime rules that code, tests and docs cite as
``docs/semantics.md §N``: its sections are numbered in order, every citation in the
repository names a section that exists, and its worked example writes, when run, the
trace the page shows."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs/semantics.md"
_SECTION = re.compile(r"^## (\d+)\. \S", re.M)
# "docs/semantics.md §4", "semantics.md §4, §13", "docs/semantics.md\n# §12": the
# numbers that follow a mention of the page (across a comment's line break).
_SEP = r"(?:[ \t,;:]|\n[ \t]*(?:#|//|\*))*"  # a line break only into a comment's next line
_CITATION = re.compile(rf"semantics\.md((?:{_SEP}(?:§\s*\d+|step \d+))+)")


def sections() -> list[int]:
    return [int(n) for n in _SECTION.findall(PAGE.read_text("utf-8"))]


def citations(text: str) -> list[int]:
    return [int(n) for group in _CITATION.findall(text) for n in re.findall(r"§\s*(\d+)", group)]


def test_the_sections_are_numbered_one_to_n() -> None:
    numbers = sections()
    assert len(numbers) >= 10
    assert numbers == list(range(1, len(numbers) + 1))


def test_the_citation_finder_reads_comments() -> None:
    text = ("# rule (docs/semantics.md §4, §13).\n# see docs/semantics.md\n# §12: and more\n"
            "// docs/semantics.md §4 step 1; §9\n§7 alone is not a citation")
    assert citations(text) == [4, 13, 12, 4, 9]


def test_every_citation_names_a_section() -> None:
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                            timeout=60, check=True).stdout.decode().split("\0")
    known = set(sections())
    bad, found = [], 0
    for name in listed:
        path = ROOT / name
        if not name or not path.is_file() or path.suffix in (".png", ".svg", ".jpg"):
            continue
        try:
            text = path.read_text("utf-8")
        except UnicodeDecodeError:
            continue
        for n in citations(text):
            found += 1
            if n not in known:
                bad.append(f"{name}: §{n}")
    assert found > 50  # the conformance cases and the runtimes cite it
    assert not bad, f"citations of docs/semantics.md sections it does not have: {bad}"


def test_the_worked_example_writes_the_trace_shown(tmp_path: Path) -> None:
    text = PAGE.read_text("utf-8")
    example = text[text.index("## 15. "):]
    model = re.search(r"^```yaml\n(.*?)^```", example, re.M | re.S)
    trace = re.search(r"^```\n(\{.*?)^```", example, re.M | re.S)
    assert model and trace
    (tmp_path / "door.yaml").write_text(model.group(1), "utf-8")
    out = tmp_path / "out"
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", "door.yaml",
                    "-o", str(out)], cwd=tmp_path, check=True, capture_output=True, timeout=120)
    run = subprocess.run([sys.executable, str(out / "door.py"), "--clock", "virtual",
                          "--trace", str(tmp_path / "door.trace")],
                         cwd=tmp_path, capture_output=True, timeout=60)
    assert run.returncode == 0, run.stderr.decode()
    assert (tmp_path / "door.trace").read_text("utf-8") == trace.group(1)
    assert run.stderr.decode().splitlines() == [
        "[    0.300] Closed: button", "[    0.300] Opening/Moving: moving",
        "[    0.350] Opening/Moving: moving", "[    0.500] door: bye"]
