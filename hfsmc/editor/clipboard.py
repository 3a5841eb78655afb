"""Copy and paste of states in the page (docs/editor.md, "Copy and paste"): a state and
its subtree copied as the YAML text the file has (`Name:` and its body, which pastes into
any text editor), and YAML text pasted into a sub-automaton through the engine's paste
(a name taken among the siblings gets a number: `Land2`). What the pasted state's arrows
name outside it is said, since it may not be there (or be another state) where pasted."""

from __future__ import annotations

from typing import Any

import yaml

from hfsmc.edit.session import EditSession
from hfsmc.edit.text import EditError

MAX_PASTE = 256 * 1024  # a state's text: larger is not something a person copied


def copy(session: EditSession, path: str) -> dict[str, Any]:
    """The reply to the page that asked: the state's YAML text."""
    if not path:
        raise EditError("select a state to copy (the root is the whole file)")
    return {"type": "clipboard", "path": path, "text": session.ops().copy_state(path)}


def outside(text: str) -> list[str]:
    """The states the pasted state's own arrows go to (outside the copied subtree)."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError:
        return []
    if not isinstance(data, dict) or len(data) != 1:
        return []
    ((name, body),) = data.items()
    trans = body.get("transitions") if isinstance(body, dict) else None
    out: list[str] = []
    for t in trans if isinstance(trans, list) else []:
        to = t.get("to") if isinstance(t, dict) else None
        if to is not None and str(to) != str(name) and str(to) not in out:
            out.append(str(to))
    return out


def paste(session: EditSession, parent: str, text: str) -> str:
    """Paste ``text`` into ``parent``'s sub-automaton; what the page is told."""
    if len(text) > MAX_PASTE:
        raise EditError("the pasted text is larger than 256 KiB: not a state")
    if parent and session.ops().element(parent).use is not None:
        raise EditError(f"`{parent}` is another file's automaton: paste there in its own tab")
    made: list[str] = []

    def op(o: Any) -> Any:
        edits, name = o.paste_state(parent, text)
        made.append(name)
        return edits
    session.apply(op)
    said = f"pasted `{made[0]}`"
    away = outside(text)
    if away:
        here = set(session.ops().index.elements)
        prefix = parent + "/" if parent else ""
        missing = [t for t in away if prefix + t not in here]
        said += (f"; its arrows go to {', '.join(away)}, outside what was copied: check they "
                 "are the states you mean here")
        if missing:
            said += f" ({', '.join(missing)} not here)"
    return said
