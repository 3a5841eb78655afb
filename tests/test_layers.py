"""The code's layers (docs/architecture.md): a pipeline stage imports only
earlier stages, no package of hfsmc has an import cycle (the contracts of lint-imports in
pyproject.toml), and the component's runtime modules ship alone, without hfsmc."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def lint_imports(cwd: Path) -> subprocess.CompletedProcess[str]:
    """lint-imports over the package hfsmc/ found in ``cwd``, with the project's contracts."""
    config = str(ROOT / "pyproject.toml")
    return subprocess.run([str(LINT_IMPORTS), "--no-cache", "--config", config], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_the_import_contracts_are_kept() -> None:
    run = lint_imports(ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


@pytest.mark.parametrize(("module", "line", "broken"), [
    # the bottom of the pipeline reaching up to its driver
    ("ir.py", "import hfsmc.pipeline", "hfsmc.ir -> hfsmc.pipeline"),
    # a stage reaching into command code
    ("emit/dot.py", "import hfsmc.commands.view", "hfsmc.emit.dot -> hfsmc.commands.view"),
    # a cycle inside one package, which the layers alone do not see
    ("sim/world.py", "import hfsmc.sim.vehicle", "No cycles are allowed in hfsmc.sim"),
])
def test_an_import_against_the_layers_is_refused(tmp_path: Path, module: str, line: str,
                                                 broken: str) -> None:
    shutil.copytree(ROOT / "hfsmc", tmp_path / "hfsmc",
                    ignore=shutil.ignore_patterns("__pycache__", "static"))
    path = tmp_path / "hfsmc" / module
    path.write_text(path.read_text("utf-8") + f"\n{line}  # noqa\n", "utf-8")
    run = lint_imports(tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    assert broken in " ".join(run.stdout.split()), run.stdout


RUNTIME = ROOT / "templates" / "python"
# The Python runtime's core, top to bottom (docs/architecture.md): each imports only those
# below it; `|` separates modules of one layer that import neither each other nor those above.
RUNTIME_LAYERS = ("hfsmc_main", "hfsmc_load", "hfsmc_runtime", "hfsmc_trace | hfsmc_traceback")


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, top-level module) of every import in ``path``, at any depth."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text("utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level:
            names = [node.module or a.name for a in node.names]  # from . import x
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        found += [(node.lineno, name.split(".")[0]) for name in names]
    return found


def test_the_runtime_modules_import_nothing_of_hfsmc() -> None:
    """templates/python/*.py are copied into every component, which runs without hfsmc:
    they import the standard library, optional packages, and each other only."""
    own = {p.stem for p in RUNTIME.glob("*.py")}
    found = [f"{path.name}:{line}: {top}" for path in sorted(RUNTIME.glob("*.py"))
             for line, top in imports(path)
             if top == "hfsmc" or (top.startswith("hfsmc_") and top not in own)]
    assert own >= {"hfsmc_runtime", "hfsmc_monitor", "hfsmc_view"}
    assert found == []


def test_the_runtime_core_imports_go_one_way() -> None:
    """The engine imports neither the command line nor the loading of used files; the
    loading does not import the command line; the trace and the reports import none."""
    layers = [[m.strip() for m in layer.split("|")] for layer in RUNTIME_LAYERS]
    core = {m for layer in layers for m in layer}
    wrong: list[str] = []
    for k, layer in enumerate(layers):
        allowed = {m for below in layers[k + 1:] for m in below}
        for module in layer:
            for line, top in imports(RUNTIME / f"{module}.py"):
                if top in core and top not in allowed:
                    wrong.append(f"{module}.py:{line}: imports {top}")
    assert wrong == []
    assert len(core) == 5 and all((RUNTIME / f"{m}.py").is_file() for m in core)
