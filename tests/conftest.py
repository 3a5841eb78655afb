from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True, scope="session")
def _repo_cwd() -> None:
    """Tests run from the repository root, so model paths in diagnostics are relative."""
    os.chdir(ROOT)


@pytest.fixture(autouse=True, scope="session")
def _cxx_cache() -> Iterator[None]:
    """One cache for `hfsmc check`'s g++ runs (hfsmc/cxxcheck.py) for the whole session,
    not the user's ~/.cache: its precompiled headers are made once per session."""
    folder = tempfile.mkdtemp(prefix="hfsmc-test-cxx-")
    before = os.environ.get("HFSMC_CACHE_DIR")
    os.environ["HFSMC_CACHE_DIR"] = folder
    yield
    if before is None:
        os.environ.pop("HFSMC_CACHE_DIR", None)
    else:
        os.environ["HFSMC_CACHE_DIR"] = before
    shutil.rmtree(folder, ignore_errors=True)


def examples(language: str | None = None) -> list[Path]:
    """Example models: examples/NAME/NAME.yaml (worlds and other files beside them are not);
    only those whose snippets are in ``language`` when it is given."""
    found = sorted(p for p in (ROOT / "examples").glob("*/*.yaml") if p.stem == p.parent.name)
    return [p for p in found if language is None or model_language(p) == language]


def model_language(model: Path) -> str:
    """The `language:` a model file declares (python when it says none)."""
    m = re.search(r"^language:\s*(\w+)", model.read_text("utf-8"), re.MULTILINE)
    return m.group(1) if m else "python"
