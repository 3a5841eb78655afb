"""What both code back ends share around their templates: the Jinja environment and
the copy of the runtime files into a component folder.

Templates live in ``templates/TARGET/`` (shipped as the data package
``hfsmc.templates``); a template receives one frozen view dataclass, read by
attribute, and only loops and prints.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from importlib.resources import files
from importlib.resources.abc import Traversable
from typing import Any

import jinja2


def template_folder(target: str) -> Traversable:
    """``templates/TARGET``, wherever hfsmc is installed."""
    return files("hfsmc.templates").joinpath(target)


def environment(target: str, filters: Mapping[str, Callable[..., Any]]) -> jinja2.Environment:
    """The Jinja environment of a back end: its templates, strict about undefined names,
    whitespace handled by the block tags, nothing escaped (the output is code)."""
    folder = template_folder(target)
    loader = jinja2.FunctionLoader(lambda name: folder.joinpath(name).read_text("utf-8"))
    env = jinja2.Environment(loader=loader, undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True,
                             autoescape=False)
    env.filters.update(filters)
    return env


def runtime_files(folder: Traversable, always: Sequence[str],
                  by_interface: Mapping[str, Sequence[str]], interface_types: Iterable[str],
                  into: str = "") -> dict[str, bytes]:
    """The runtime files a component needs, read from ``folder``, by path in the component
    (``into`` + name): the ``always`` ones, then those of each interface type it uses, once
    each and in that order. A listed file that is missing is a broken installation:
    FileNotFoundError (the command line reports it as an internal error)."""
    needed = list(always)
    for kind in interface_types:
        needed += [name for name in by_interface.get(kind, ()) if name not in needed]
    out: dict[str, bytes] = {}
    for name in needed:
        source = folder.joinpath(name)
        if not source.is_file():
            raise FileNotFoundError(f"runtime file {name} missing from {folder} "
                                    "(reinstall hfsmc)")
        out[into + name] = source.read_bytes()
    return out
