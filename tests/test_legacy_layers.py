"""The legacy package's imports go one way (docs/legacy.md, "The code").

Read from the sources (nothing is imported), against the package's layers contract in
pyproject.toml (which lint-imports enforces, see test_layers.py): each module of
``hfsmc/frontend/legacy/`` imports only modules of a lower layer, none imports the
package's ``__init__``, and outside the package only the bottom of hfsmc.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "hfsmc" / "frontend" / "legacy"
PREFIX = "hfsmc.frontend.legacy"
# What the package may import from the rest of hfsmc: nothing of a later stage.
OUTSIDE = {"hfsmc.errors", "hfsmc.ir", "hfsmc.frontend.source", "hfsmc.frontend.xmlsource",
           "hfsmc.ros2.definitions"}


def layers() -> dict[str, int]:
    """Module -> its layer (0 the top), from the contract in pyproject.toml."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))
    contract, = (c for c in config["tool"]["importlinter"]["contracts"]
                 if c.get("containers") == [PREFIX])
    return {name.strip(): i for i, layer in enumerate(contract["layers"])
            for name in layer.split("|")}


def hfsmc_imports(path: Path) -> list[tuple[int, str]]:
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text("utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]  # `from hfsmc.frontend.legacy import x`: the __init__
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out += [(node.lineno, n) for n in names if n == "hfsmc" or n.startswith("hfsmc.")]
    return out


def test_every_module_has_a_layer() -> None:
    assert {p.stem for p in PACKAGE.glob("*.py")} - {"__init__"} == set(layers())


def test_imports_go_down() -> None:
    rank = layers()
    wrong: list[str] = []
    for module in sorted(rank):
        for line, name in hfsmc_imports(PACKAGE / f"{module}.py"):
            other = name.removeprefix(PREFIX + ".")
            if name == PREFIX:
                wrong.append(f"{module}.py:{line}: imports the package's __init__")
            elif name.startswith(PREFIX + ".") and rank[other] <= rank[module]:
                wrong.append(f"{module}.py:{line}: imports {other}, which is not below it")
            elif not name.startswith(PREFIX + ".") and name not in OUTSIDE:
                wrong.append(f"{module}.py:{line}: imports {name}")
    assert wrong == []
