from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True, scope="session")
def _repo_cwd() -> None:
    """Tests run from the repository root, so model paths in diagnostics are relative."""
    os.chdir(ROOT)


def examples(language: str | None = None) -> list[Path]:
    """Example models: examples/NAME/NAME.yaml (worlds and other files beside them are not);
    only those whose snippets are in ``language`` when it is given."""
    found = sorted(p for p in (ROOT / "examples").glob("*/*.yaml") if p.stem == p.parent.name)
    return [p for p in found if language is None or model_language(p) == language]


def model_language(model: Path) -> str:
    """The `language:` a model file declares (python when it says none)."""
    m = re.search(r"^language:\s*(\w+)", model.read_text("utf-8"), re.MULTILINE)
    return m.group(1) if m else "python"
