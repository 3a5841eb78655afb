"""Operations on a YAML model's declarations beyond add, delete and rename (those are in
:mod:`hfsmc.edit.yaml_ops`): one field of a parameter, a variable or an interface set,
a variable written short (`stage: 0`) given a type, an import line changed in place;
and a value typed in a form turned into the literal it means for the declared type.
Each returns the :class:`TextEdit` s that make it, as the other operations do."""

from __future__ import annotations

from typing import Any

import yaml

from hfsmc.edit import yaml_render as render
from hfsmc.edit import yaml_splice as splice
from hfsmc.edit.text import EditError, TextEdit
from hfsmc.edit.yaml_ops import SECTIONS, YamlOps

# The fields a form sets, per kind of declaration (SPEC 2); an interface's other keys
# (a ROS 2 interface's topics, say) are edited in the file.
FIELDS = {"parameter": ("type", "default"), "variable": ("type", "init"),
          "interface": ("type", "url")}


def literal(text: str, declared: str | None) -> Any:
    """The value ``text`` (typed in a form) means as a ``declared`` type (`int`, `float`,
    `bool`, `str`; another type or none: as YAML reads it, `[1, 2]` a list, else the
    text itself)."""
    text = text.strip() if declared != "str" else text
    if declared == "str":
        return text
    if declared == "int":
        try:
            return int(text, 0)
        except ValueError:
            raise EditError(f"`{text}` is not an int") from None
    if declared == "float":
        try:
            return float(text)
        except ValueError:
            raise EditError(f"`{text}` is not a float") from None
    if declared == "bool":
        if text.lower() not in ("true", "false"):
            raise EditError(f"`{text}` is not a bool (true or false)")
        return text.lower() == "true"
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return text if value is None else value


def set_declaration_field(o: YamlOps, kind: str, name: str, key: str,
                          value: Any) -> list[TextEdit]:
    """Set (None: clear) field ``key`` of the declaration ``name``. A variable written
    short (`stage: 0`) keeps its short form for `init`, and becomes `{type: T, init: V}`
    when given a type."""
    if kind not in FIELDS:
        raise EditError(f"no kind of declaration `{kind}`")
    if key not in FIELDS[kind]:
        raise EditError(f"`{key}` is not a field of a {kind} the page edits")
    path = (SECTIONS[kind], name)
    node = o.sp.tree.find(path)
    if node is None:
        raise EditError(f"no {kind} `{name}` in this model")
    if node.kind == "map":
        if value is None and key == "type" and kind != "variable":
            raise EditError(f"a {kind} needs its `type`")
        return o.set_field((*path, key), value)
    if kind != "variable" or node.kind != "scalar":
        raise EditError(f"the {kind} `{name}` is not written as a mapping: edit it in the file")
    if key == "init":
        if value is None:
            raise EditError(f"the variable `{name}` needs a value")
        return o.set_field(path, value)
    if value is None:
        return []  # a short variable has no type to clear
    current = yaml.safe_load(o.text[node.start:node.end]) if node.end > node.start else None
    body = {"type": value, "init": current}
    section = o.sp.tree.find(path[:-1])
    if section is not None and splice._prefer_flow(section):  # as its siblings are written
        return [TextEdit(node.start, node.end, render.flow(body))]
    return o.set_field(path, body)


def declared_type(o: YamlOps, kind: str, name: str) -> str | None:
    """The `type` written for a declaration, if any."""
    node = o.sp.tree.find((SECTIONS[kind], name, "type"))
    return str(node.value) if node is not None and node.kind == "scalar" else None


def set_import(o: YamlOps, index: int, line: str) -> list[TextEdit]:
    """Change import ``index`` to ``line`` in place."""
    node = o.sp.tree.find(("imports",))
    count = len(node.items) if node is not None and node.kind == "seq" else 0
    if not 0 <= index < count:
        raise EditError(f"no import number {index + 1}")
    if not line.strip():
        raise EditError("an import line is not empty: delete the import instead")
    return o.set_field(("imports", index), line.strip())


def delete_import(o: YamlOps, index: int) -> list[TextEdit]:
    """Remove import ``index`` (the same line may be written twice)."""
    node = o.sp.tree.find(("imports",))
    count = len(node.items) if node is not None and node.kind == "seq" else 0
    if not 0 <= index < count:
        raise EditError(f"no import number {index + 1}")
    return o.set_field(("imports", index), None)
