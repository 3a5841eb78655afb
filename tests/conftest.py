from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.support import (
    ROOT,
    SANITIZERS,
    Client,
    Tmux,
    build_blinker,
    compile_observers,
    stop_processes,
)

__all__ = ["ROOT", "examples", "model_language"]


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


@pytest.fixture
def processes() -> Iterator[list[subprocess.Popen[bytes]]]:
    """Processes a test starts: those still running at its end are killed, all reaped."""
    made: list[subprocess.Popen[bytes]] = []
    yield made
    stop_processes(made)


@pytest.fixture
def tmux() -> Iterator[Callable[..., Tmux]]:
    """Starts commands in private tmux servers, each killed at the end of the test."""
    made: list[Tmux] = []

    def start(command: str, cwd: Path, after: str = "") -> Tmux:
        made.append(Tmux(command, cwd, after))
        return made[-1]

    yield start
    for t in made:
        t.kill()


@pytest.fixture
def clients() -> Iterator[Callable[..., Client]]:
    """Connects raw monitor clients, each closed at the end of the test."""
    made: list[Client] = []

    def connect(port: int, **kw: Any) -> Client:
        made.append(Client(port, **kw))
        return made[-1]

    yield connect
    for c in made:
        c.close()


@pytest.fixture(scope="session")
def blinker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The blinker example's Python component, built once: its main file."""
    return build_blinker(tmp_path_factory.mktemp("component") / "blinker")


@pytest.fixture(scope="session")
def observers_program(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/cpp/observers_main.cpp, compiled once."""
    return compile_observers(tmp_path_factory.mktemp("observers") / "observers_main", ["-O1"])


@pytest.fixture(scope="session")
def observers_asan_program(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/cpp/observers_main.cpp with ASan and UBSan, compiled once."""
    return compile_observers(tmp_path_factory.mktemp("observers_asan") / "observers_main",
                             SANITIZERS)
