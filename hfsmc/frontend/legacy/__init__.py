"""Legacy VisualStates and VisualHFSM files as version-1 models (docs/legacy.md).

A legacy file is told by its root element (``<VisualStates>``, ``<VisualHFSM>``)
and read in two steps (:func:`load_legacy`, in :mod:`.load`):

1. a reader per format (:mod:`.visualstates`, :mod:`.visualhfsm`,
   :mod:`.visualhfsm3`) walks the tree, direct children only, with the element
   access of :mod:`.reader` and the sub-automaton building of :mod:`.levels`,
   and turns it into a small neutral form (:mod:`.form`: levels of states,
   namespaces, interfaces), reporting everything broken with its position;
2. :class:`~.assemble.Assembler` maps that form, the same way for every
   format, onto the version-1 data a YAML model gives (names from
   :mod:`.names`, code rewritten by :mod:`.code`), with a span for every value
   and key and the segments of every code text, so that the ordinary pipeline
   (schema, IR builder, passes, back ends) runs unchanged and every diagnostic
   or traceback lands in the legacy file.

Imports go one way: ``load`` -> ``assemble`` -> ``names``, and ``load`` -> the
format readers -> ``levels`` -> ``reader`` -> ``form`` -> ``code``; no module
here imports this package's ``__init__``.

What the mapping did is written to ``Document.notes`` (the ``convert`` report);
what matters to a user is a warning (W205-W208).  The decisions are listed in
``docs/legacy.md``.
"""

from hfsmc.frontend.legacy.load import load_legacy

__all__ = ["load_legacy"]
