"""An editing session over one model file: operations, the check after each, undo
and redo as exact texts, and the file on disk watched for other writers (SPEC 8.1)."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hfsmc.edit.references import Index, Names
from hfsmc.edit.text import EditError, TextEdit, apply_edits
from hfsmc.edit.xml_tree import XmlNames
from hfsmc.edit.yaml_ops import YamlOps
from hfsmc.errors import Diagnostic
from hfsmc.frontend import is_xml
from hfsmc.frontend.yaml_ranges import YamlTree
from hfsmc.fsutil import write_atomic
from hfsmc.pipeline import compile_file


class Conflict(EditError):
    """The file changed on disk under unsaved edits."""


@dataclass
class EditSession:
    """A model's text being edited; ``path`` names it in diagnostics and on save."""

    path: str
    text: str
    undo_stack: list[str] = field(default_factory=list)
    redo_stack: list[str] = field(default_factory=list)
    diagnostics: list[Diagnostic] = field(default_factory=list)
    disk: str | None = None  # the text last read from or written to the disk

    @classmethod
    def open(cls, path: str) -> EditSession:
        text = Path(path).read_text("utf-8")
        s = cls(path, text, disk=text)
        s.check()
        return s

    def ops(self) -> Any:
        if is_xml(self.text):
            from hfsmc.edit.xml_ops import XmlOps

            return XmlOps(self.text)
        return YamlOps(self.text)

    def apply(self, op: Callable[[Any], list[TextEdit]]) -> list[TextEdit]:
        """Make ``op(ops)`` (an operation of :class:`YamlOps` or ``XmlOps``) and check."""
        edits = op(self.ops())
        self.replace(apply_edits(self.text, edits))
        return edits

    def replace(self, text: str) -> None:
        """A new text (an operation's or the user's), undoable."""
        if text == self.text:
            return
        self.undo_stack.append(self.text)
        self.redo_stack.clear()
        self.text = text
        self.check()

    def undo(self) -> bool:
        if not self.undo_stack:
            return False
        self.redo_stack.append(self.text)
        self.text = self.undo_stack.pop()
        self.check()
        return True

    def redo(self) -> bool:
        if not self.redo_stack:
            return False
        self.undo_stack.append(self.text)
        self.text = self.redo_stack.pop()
        self.check()
        return True

    def check(self) -> list[Diagnostic]:
        """The model's diagnostics, as ``hfsmc check`` gives them (C++ not compiled)."""
        self.diagnostics = compile_file(self.path, self.text).diagnostics
        return self.diagnostics

    def by_element(self) -> dict[str, list[Diagnostic]]:
        """The diagnostics of this file keyed by the innermost state or region they are
        in (`""`: the root; other files by their name)."""
        out: dict[str, list[Diagnostic]] = {}
        index: Names | None
        try:
            index = XmlNames(self.text) if is_xml(self.text) else Index(YamlTree(self.text))
        except Exception:
            index = None
        starts = [0, *(m.end() for m in re.finditer(r"\r\n|\r|\n", self.text))]
        for d in self.diagnostics:
            key = d.span.file if os.path.normpath(d.span.file) != os.path.normpath(self.path) else ""
            if not key and index is not None:
                off = starts[min(d.span.line, len(starts)) - 1] + d.span.col - 1
                best = None
                for el in index.elements.values():
                    s = el.key.start
                    e = max(el.node.end, el.key.end)
                    if s <= off <= e and (best is None or e - s < best[1]):
                        best = (el.path, e - s)
                key = best[0] if best else ""
            out.setdefault(key, []).append(d)
        return out

    def save(self, force: bool = False) -> None:
        """Write the text; a file changed on disk since it was read is a :class:`Conflict`
        (``force`` overwrites it)."""
        try:
            now = Path(self.path).read_text("utf-8")
        except FileNotFoundError:
            now = None
        if not force and self.disk is not None and now != self.disk:
            raise Conflict(f"{self.path} changed on disk since it was opened: reload it or save "
                           "with force")
        write_atomic(Path(self.path), self.text)
        self.disk = self.text
