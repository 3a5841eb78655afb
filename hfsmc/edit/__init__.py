"""The edit engine: a model's elements as text ranges, operations as minimal text edits
(SPEC 8.1; docs/editing.md).  ``session.py`` is the entry point: an
:class:`~hfsmc.edit.session.EditSession` holds a model's text, applies operations,
re-checks the model after each and keeps undo and redo as exact texts."""
