"""A legacy document read by the reader of its format, then assembled into a model."""

from __future__ import annotations

from lxml import etree

from hfsmc.errors import Diagnostics
from hfsmc.frontend.legacy.assemble import Assembler
from hfsmc.frontend.legacy.reader import Reader
from hfsmc.frontend.legacy.visualhfsm import read as read_visualhfsm
from hfsmc.frontend.legacy.visualhfsm3 import is_visualhfsm3
from hfsmc.frontend.legacy.visualhfsm3 import read as read_visualhfsm3
from hfsmc.frontend.legacy.visualstates import read as read_visualstates
from hfsmc.frontend.source import Document
from hfsmc.frontend.xmlsource import Element, XmlIndex


def load_legacy(root: Element, index: XmlIndex, diags: Diagnostics) -> Document:
    """The version-1 model of a ``<VisualStates>`` or ``<VisualHFSM>`` document."""
    kind = etree.QName(root).localname
    doc = Document(index.src.file, "visualstates" if kind == "VisualStates" else "visualhfsm",
                   index.src.lines())
    doc.spans[()] = index.span(root)
    doc.data = {}
    reader = Reader(doc, index, diags, kind)
    if kind == "VisualStates" and root.find("state") is None \
            and root.find("SubAutomata") is not None:
        # VisualStates' C++ editor (2016-2017) saved VisualHFSM 5's layout under this root
        read = read_visualhfsm
    elif kind == "VisualStates":
        read = read_visualstates
    elif is_visualhfsm3(root):
        read = read_visualhfsm3
    else:
        read = read_visualhfsm
    legacy = read(reader, root)
    if legacy is not None and not diags.has_errors:
        doc.data = Assembler(reader, legacy).model()
    return doc
