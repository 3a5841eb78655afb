"""The text a model was built from: the model file and every file it uses, and their hash.

A recording carries them (schemas/recording.md: `hfsmc.sources`, `model_hash`), so that a
run can be replayed with exactly the model that made it, or told apart from a changed one.
"""

from __future__ import annotations

import os

from hfsmc.ir import Model
from hfsmc.recording import sources_hash


def model_sources(model: Model) -> tuple[tuple[str, str], ...]:
    """(path, text) of the model file, then of every file it uses in the order first used
    (nested uses too), as the front end read them; paths relative to the model's folder,
    with `/` separators."""
    home = os.path.dirname(model.file) or "."
    out = [(model.file, model.source)]
    seen = {os.path.realpath(model.file)}
    for auto in model.automata():
        inst = auto.instance
        if inst is not None and os.path.realpath(inst.file) not in seen:
            seen.add(os.path.realpath(inst.file))
            out.append((inst.file, inst.model.source))
    for i in model.interfaces:  # a user's drivers are code the model runs (docs/drivers.md)
        for f in (i.python, i.cpp):
            if f is not None and os.path.realpath(f.path) not in seen:
                seen.add(os.path.realpath(f.path))
                out.append((f.path, f.text))
    return tuple((os.path.relpath(f, home).replace(os.sep, "/"), text) for f, text in out)


def model_hash(sources: tuple[tuple[str, str], ...]) -> str:
    """``sha256:`` and the hex digest of each path and text, NUL after each."""
    return sources_hash(sources)
