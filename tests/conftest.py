from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True, scope="session")
def _repo_cwd() -> None:
    """Tests run from the repository root, so model paths in diagnostics are relative."""
    os.chdir(ROOT)


def examples() -> list[Path]:
    """Example models: examples/NAME/NAME.yaml (worlds and other files beside them are not)."""
    return sorted(p for p in (ROOT / "examples").glob("*/*.yaml") if p.stem == p.parent.name)
