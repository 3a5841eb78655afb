"""A state of a library (a model other models `use`) renamed: the literal `active()`
paths of the models that use it, which name its states through the using state
(`active("TakeOff/Airborne")`), are renamed too.

The models are looked for under a folder (the editor's workspace); a model file that
cannot be written is left as it is and named, with the positions that would change."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from hfsmc.edit.references import Index, Names, Ref
from hfsmc.edit.text import EditError, TextEdit
from hfsmc.edit.xml_tree import XmlNames
from hfsmc.frontend import is_xml
from hfsmc.frontend.yaml_ranges import YamlTree

MAX_FILES = 5000  # a workspace scan stops there
_SKIP = {".git", ".venv", "venv", "node_modules", "build", "__pycache__", ".tox", ".mypy_cache"}
_SUFFIXES = (".yaml", ".yml", ".xml")


@dataclass
class UserEdits:
    """What a library rename changes in the models that use the library."""

    edits: dict[str, list[TextEdit]] = field(default_factory=dict)  # file -> edits
    texts: dict[str, str] = field(default_factory=dict)  # file -> its text (the edits' base)
    read_only: list[str] = field(default_factory=list)  # `file:line:col` not changed

    def message(self) -> str | None:
        if not self.read_only:
            return None
        return ("read-only, not renamed there: " + ", ".join(self.read_only[:10]) +
                (f" and {len(self.read_only) - 10} more" if len(self.read_only) > 10 else ""))


def model_files(root: Path) -> Iterator[Path]:
    """The YAML and XML files under ``root`` (hidden folders, virtual environments and
    build folders skipped; at most :data:`MAX_FILES`)."""
    n = 0
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in _SKIP and not d.startswith("."))
        for f in sorted(files):
            if f.endswith(_SUFFIXES):
                n += 1
                if n > MAX_FILES:
                    return
                yield Path(folder) / f


def names_of(text: str) -> Names | None:
    """The names of a model's text, YAML or XML (None when it does not parse)."""
    try:
        return XmlNames(text) if is_xml(text) else Index(YamlTree(text))
    except (yaml.YAMLError, EditError):
        return None


def writable(path: Path) -> bool:
    """Whether the file may be written: the system says so and some write bit is set (a
    file made read-only on purpose stays so, even for root)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return os.access(path, os.W_OK) and bool(mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def rename_in_users(library: Path, state: str, new: str, candidates: Iterator[Path] | list[Path]
                    ) -> UserEdits:
    """The edits renaming state ``state`` (its path in ``library``) to ``new`` in the
    `active()` paths of every model among ``candidates`` that uses ``library``."""
    if "/" in new or not new:
        raise EditError(f"`{new}` is not a valid state name")
    lib = library.resolve()
    out = UserEdits()
    for path in candidates:
        if path.resolve() == lib:
            continue
        try:
            text = path.read_text("utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        if lib.name not in text:
            continue
        index = names_of(text)
        if index is None:
            continue
        refs = list(_refs(index, path, lib, state))
        if not refs:
            continue
        if not writable(path):
            out.read_only += [f"{path}:{_line_col(text, r.start)}" for r in refs]
            continue
        out.texts[str(path)] = text
        out.edits[str(path)] = sorted((TextEdit(r.start, r.end, new) for r in refs),
                                      key=lambda e: e.start)
    return out


def _refs(index: Names, path: Path, lib: Path, state: str) -> Iterator[Ref]:
    for el in index.elements.values():
        if el.use is None or (path.parent / el.use).resolve() != lib:
            continue
        target = f"{el.path}/{state}"
        for r in index.refs:
            if r.kind == "state" and r.via == "active" and r.target == target:
                yield r


def _line_col(text: str, off: int) -> str:
    line = text.count("\n", 0, off) + 1
    return f"{line}:{off - (text.rfind(chr(10), 0, off) + 1) + 1}"
