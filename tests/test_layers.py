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


def test_the_runtime_modules_import_nothing_of_hfsmc() -> None:
    """templates/python/*.py are copied into every component, which runs without hfsmc:
    they import the standard library, optional packages, and each other only."""
    runtime = ROOT / "templates" / "python"
    own = {p.stem for p in runtime.glob("*.py")}
    found: list[str] = []
    for path in sorted(runtime.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text("utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level:
                names = [node.module or a.name for a in node.names]  # from . import x
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top == "hfsmc" or (top.startswith("hfsmc_") and top not in own):
                    found.append(f"{path.name}:{node.lineno}: {name}")
    assert own >= {"hfsmc_runtime", "hfsmc_monitor", "hfsmc_view"}
    assert found == []
