"""Generated output of every example matches its golden file (``make golden`` updates them)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import examples
from tests.regen_golden import GENERATORS, applies, golden_models, golden_path, render

CASES = [(ex, suffix) for ex in golden_models() for suffix in GENERATORS if applies(ex, suffix)]


@pytest.mark.parametrize(("example", "suffix"), CASES, ids=[f"{e.stem}.{s}" for e, s in CASES])
def test_golden(example: Path, suffix: str) -> None:
    path = golden_path(example, suffix)
    assert path.exists(), f"missing {path}: run `make golden`"
    assert render(example, suffix) == path.read_text("utf-8"), f"{path} is stale: run `make golden` and review the diff"


def test_every_example_has_golden_files() -> None:
    assert len(examples()) >= 2
    for ex in examples():
        for suffix in GENERATORS:
            assert golden_path(ex, suffix).exists() == applies(ex, suffix), (ex, suffix)
