"""The project documents itself: README.md and docs/ hold what a user needs,
every relative link resolves inside the repository, and the reference pages
keep up with the code they describe (driver methods, component flags, model
examples)."""

from __future__ import annotations

import inspect
import re
import subprocess
from pathlib import Path

import pytest

from hfsmc.commands.completion import component_flags
from hfsmc.pipeline import compile_file
from tests.conftest import ROOT

DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


def _tracked_markdown() -> list[Path]:
    """The project's other Markdown files (bench/, schemas/, tests/...): their links must
    resolve too."""
    listed = subprocess.run(["git", "ls-files", "-z", "*.md"], cwd=ROOT, capture_output=True,
                            timeout=60).stdout.decode().split("\0")
    return sorted({ROOT / name for name in listed if name and (ROOT / name).exists()} - set(PAGES))


OTHER_PAGES = _tracked_markdown()
_FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.M | re.S)
_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_HEADING = re.compile(r"^#{1,6}[ \t]+(.+?)[ \t]*#*[ \t]*$", re.M)


def prose(text: str) -> str:
    """The text without its fenced code blocks (a link there is an example, not a link)."""
    return _FENCE.sub("", text)


def links(page: Path) -> list[str]:
    return _LINK.findall(prose(page.read_text("utf-8")))


def anchors(page: Path) -> set[str]:
    """GitHub's anchors of a Markdown page's headings."""
    found: set[str] = set()
    for title in _HEADING.findall(prose(page.read_text("utf-8"))):
        slug = re.sub(r"[^\w\- ]", "", title.replace("`", "").strip().lower()).replace(" ", "-")
        n, candidate = 0, slug
        while candidate in found:
            n += 1
            candidate = f"{slug}-{n}"
        found.add(candidate)
    return found


def test_the_pages_link_what_they_must() -> None:
    names = {p.name for p in DOCS.glob("*.md")}
    assert {"README.md", "model.md", "interfaces.md", "component.md"} <= names
    index = (DOCS / "README.md").read_text("utf-8")
    for name in sorted(names - {"README.md"}):
        assert f"]({name})" in index, f"docs/README.md does not list {name}"
    readme = links(ROOT / "README.md")
    for target in ("docs/README.md", "docs/model.md", "docs/interfaces.md", "docs/component.md"):
        assert target in readme


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_the_user_documentation_stands_alone(page: Path) -> None:
    """Nothing sends a reader to a file a clone does not have."""
    text = page.read_text("utf-8")
    assert "../shared" not in text and "SPEC" not in text


@pytest.mark.parametrize("page", PAGES + OTHER_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves_inside_the_repository(page: Path) -> None:
    problems = []
    for target in links(page):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:: not a file of ours
            continue
        path, _, anchor = target.partition("#")
        resolved = (page.parent / path).resolve() if path else page
        if not resolved.is_relative_to(ROOT):
            problems.append(f"{target}: outside the repository")
        elif not resolved.exists():
            problems.append(f"{target}: no such file")
        elif anchor and resolved.suffix == ".md" and anchor not in anchors(resolved):
            problems.append(f"{target}: no heading `#{anchor}` in {resolved.name}")
    assert not problems, f"{page.relative_to(ROOT)}:\n" + "\n".join(problems)


def test_the_link_checker_sees_links_and_skips_code() -> None:
    page = "see [a](docs/a.md#x), ![b](b.svg) and [`c`](c/)\n```\n[d](nowhere.md)\n```\n"
    assert _LINK.findall(prose(page)) == ["docs/a.md#x", "b.svg", "c/"]


# -- the interfaces: every method the drivers expose -------------------------------------

def python_methods(module: str, cls: str) -> set[str]:
    """The public methods of a driver's live class; of a driver built on the driver base
    (hfsmc_driver.Driver), not the base's runtime protocol (docs/drivers.md), except
    those it gives snippets too (``PUBLIC``)."""
    mod = pytest.importorskip(f"hfsmc.templates.python.{module}")
    live = getattr(mod, cls)
    base = next((c for c in live.__mro__ if c.__name__ == "Driver"), None)
    runtime = set() if base is None else set(vars(base)) - set(live.PUBLIC)
    return {n for n, _ in inspect.getmembers(live, inspect.isfunction)
            if not n.startswith("_") and n not in runtime}


def cpp_methods(header: str, cls: str) -> set[str]:
    """Public member functions of ``class cls`` in a driver header (members are indented
    by two spaces in the project's style; bodies deeper)."""
    text = (ROOT / "templates/cpp/hfsmc" / header).read_text("utf-8")
    body = text[re.search(rf"class {cls}\b[^;{{]*{{", text).start():]  # type: ignore[union-attr]
    public = body[body.index(" public:"):body.index(" private:")]
    found = set()
    for m in re.finditer(r"^  (?![ /#])[^;{}()]*?\b([A-Za-z_]\w*)\(", public, re.M):
        if m.group(1) not in (cls, "operator"):
            found.add(m.group(1))
    return found


DRIVERS = [("hfsmc_mavlink", "Vehicle", "mavlink.hpp", "Mavlink"),
           ("hfsmc_camera", "Camera", "camera.hpp", "Camera")]


@pytest.mark.parametrize(("module", "cls", "header", "cpp_cls"), DRIVERS,
                         ids=[d[0] for d in DRIVERS])
def test_every_driver_method_is_documented(module: str, cls: str, header: str,
                                           cpp_cls: str) -> None:
    doc = (DOCS / "interfaces.md").read_text("utf-8")
    py = python_methods(module, cls)
    cpp = cpp_methods(header, cpp_cls)
    assert {"frame", "age"} <= py | cpp or {"connected", "arm", "goto"} <= py  # parsed at all
    assert {"close"} <= py & cpp
    missing = sorted(m for m in py | cpp if f"`{m}(" not in doc)
    assert not missing, f"docs/interfaces.md does not document {missing}"


def test_the_cpp_header_parser_finds_the_public_methods() -> None:
    cpp = cpp_methods("mavlink.hpp", "Mavlink")
    assert {"connected", "go_to", "last_ack", "name", "position", "set_velocity"} <= cpp
    assert not {"Mavlink", "command", "run", "say", "operator"} & cpp  # private or special
    assert "goto" in python_methods("hfsmc_mavlink", "Vehicle") and "goto" not in cpp


# -- the component: every flag ------------------------------------------------------------

def test_every_component_flag_is_documented() -> None:
    doc = (DOCS / "component.md").read_text("utf-8")
    flags = component_flags()
    assert "--display" in flags and "--until" in flags
    missing = [f for f in flags if f"`{f}" not in doc]
    assert not missing, f"docs/component.md does not document {missing}"


# -- the model: its examples are models ----------------------------------------------------

def test_the_complete_examples_of_model_md_are_clean_models(tmp_path: Path) -> None:
    text = (DOCS / "model.md").read_text("utf-8")
    blocks = [b for b in re.findall(r"^```yaml\n(.*?)^```", text, re.M | re.S)
              if re.search(r"^hfsm: 1", b, re.M)]
    assert blocks
    for i, block in enumerate(blocks):
        path = tmp_path / f"example{i}.yaml"
        path.write_text(block, "utf-8")
        result = compile_file(str(path))
        assert result.ok and not result.diagnostics, [str(d) for d in result.diagnostics]


def test_every_key_of_the_schema_is_in_model_md() -> None:
    import json

    schema = json.loads((ROOT / "schemas/hfsm.schema.json").read_text("utf-8"))
    keys = set(schema["properties"])
    for name in ("state", "transition", "parameter", "variable", "interface"):
        keys |= set(schema["$defs"][name].get("properties", {}))
        keys |= set(schema["$defs"][name].get("then", {}).get("properties", {}))
    doc = (DOCS / "model.md").read_text("utf-8")
    missing = sorted(k for k in keys if f"`{k}`" not in doc)
    assert not missing, f"docs/model.md does not document {missing}"
