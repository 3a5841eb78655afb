"""The legacy package's imports go one way (docs/legacy.md, "The code").

Read from the sources (nothing is imported): each module of
``hfsmc/frontend/legacy/`` imports only modules of a lower layer, within the package
and in hfsmc, and none imports the package's ``__init__``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "hfsmc" / "frontend" / "legacy"
PREFIX = "hfsmc.frontend.legacy"
# Top first; the modules of one line do not import each other.
LAYERS = (("load",), ("assemble",), ("names", "visualstates", "visualhfsm", "visualhfsm3"),
          ("levels",), ("reader",), ("form",), ("code",))
# What the package may import from the rest of hfsmc: nothing of a later stage.
OUTSIDE = {"hfsmc.errors", "hfsmc.ir", "hfsmc.frontend.source", "hfsmc.frontend.xmlsource"}
RANK = {name: i for i, layer in enumerate(LAYERS) for name in layer}


def hfsmc_imports(path: Path) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text("utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]  # `from hfsmc.frontend.legacy import x`: the __init__
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out.update(n for n in names if n == "hfsmc" or n.startswith("hfsmc."))
    return out


def test_every_module_has_a_layer() -> None:
    modules = {p.stem for p in PACKAGE.glob("*.py")} - {"__init__"}
    assert modules == set(RANK)


@pytest.mark.parametrize("module", sorted(RANK))
def test_imports_go_down(module: str) -> None:
    for name in sorted(hfsmc_imports(PACKAGE / f"{module}.py")):
        assert name != PREFIX, f"{module} imports the package's __init__"
        if name.startswith(PREFIX + "."):
            other = name.removeprefix(PREFIX + ".")
            assert RANK[other] > RANK[module], f"{module} imports {other}, which is not below it"
        else:
            assert name in OUTSIDE, f"{module} imports {name}"
