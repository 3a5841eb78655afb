"""Front ends: read a model file of any supported format into a :class:`Document`.

The format is told by the content, not the file name: a document whose first
non-blank character is ``<`` is XML (hfsm version 1, or a legacy VisualStates /
VisualHFSM file, by root element); anything else is YAML. ``schema.py``
then validates the Document against the JSON Schema, for every format alike.
"""

from __future__ import annotations

from pathlib import Path

from hfsmc.errors import Diagnostics, ParseError, Span, fail
from hfsmc.frontend.source import MAX_FILE_BYTES, Document
from hfsmc.frontend.yaml import load_yaml


def read_text(path: str) -> str:
    """The file's text, or a positioned E001 (missing, too large, binary, not UTF-8)."""
    p = Path(path)
    start = Span(path, 1, 1)
    try:
        size = p.stat().st_size
        if size > MAX_FILE_BYTES:
            fail(ParseError, "E001", f"the file is {size} bytes; models are limited to "
                 f"{MAX_FILE_BYTES // (1024 * 1024)} MiB", start)
        raw = p.read_bytes()
    except IsADirectoryError:
        fail(ParseError, "E001", "is a directory, not a model file", start)
    except OSError as e:
        fail(ParseError, "E001", f"cannot read the file: {e.strerror or e}", start)
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    nul = raw.find(b"\x00")
    if nul >= 0:
        fail(ParseError, "E001", "binary file (NUL byte): not a model", _offset_span(path, raw, nul))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        fail(ParseError, "E001", f"not UTF-8 text (byte 0x{raw[e.start]:02x})",
             _offset_span(path, raw, e.start))
    if not text.strip():
        fail(ParseError, "E001", "the file is empty", start)
    return text


def _offset_span(path: str, raw: bytes, offset: int) -> Span:
    before = raw[:offset]
    line = before.count(b"\n") + 1
    col = len(before) - (before.rfind(b"\n") + 1) + 1
    return Span(path, line, col)


def is_xml(text: str) -> bool:
    return text.lstrip().startswith("<")


def load(path: str, diags: Diagnostics, text: str | None = None) -> Document:
    """Read and parse ``path`` (or the given ``text`` under that name)."""
    if text is None:
        text = read_text(path)
    if is_xml(text):
        from hfsmc.frontend.xml import load_xml

        doc = load_xml(path, text, diags)
    else:
        doc = load_yaml(path, text, diags)
        if not isinstance(doc.data, dict):
            fail(ParseError, "E005", "not an hfsm model: the document must be a mapping that "
                 "starts with `hfsm: 1`", doc.span(()))
    doc.text = text
    return doc
