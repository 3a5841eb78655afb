from __future__ import annotations

import contextlib
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
    Process,
    Tmux,
    build_blinker,
    chromium,
    compile_observers,
    stop_processes,
)

__all__ = ["ROOT", "examples", "model_language"]


# One compiler cache for every C++ build of the suite, in every worker: the runtime library
# and the precompiled driver headers (templates/cpp/CMakeLists.txt.j2 sends them through ccache)
# are then compiled once, not once per component folder; tests that point XDG_CACHE_HOME at a
# folder of their own would otherwise start ccache cold each time. A run's own CCACHE_DIR wins.
os.environ.setdefault("CCACHE_DIR", str(Path(tempfile.gettempdir()) / f"hfsmc-test-ccache-{os.getuid()}"))
os.environ.setdefault("CCACHE_MAXSIZE", "2G")
# Every DDS participant of the run (components, simulators, peers) on the loopback interface
# only (tests/ros2_support.py); a test that sets an environment of its own passes it on.
LOOPBACK_DDS = ("<CycloneDDS><Domain Id=\"any\"><General><Interfaces>"
                "<NetworkInterface name=\"lo\" multicast=\"true\"/></Interfaces></General>"
                "</Domain></CycloneDDS>")
os.environ["CYCLONEDDS_URI"] = LOOPBACK_DDS


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
def logged(tmp_path: Path) -> Iterator[Callable[..., Process]]:
    """Starts processes whose output goes to files in tmp_path, each killed at the end."""
    made: list[Process] = []

    def start(args: list[str], name: str) -> Process:
        made.append(Process(args, tmp_path, f"{name}{len(made)}"))
        return made[-1]

    yield start
    for p in made:
        p.kill()


@pytest.fixture
def browsers(tmp_path: Path) -> Iterator[Callable[..., Any]]:
    """Starts headless chromium browsers (extra flags as arguments), each quit at the end."""
    made: list[Any] = []

    def start(*flags: str) -> Any:
        made.append(chromium(tmp_path / f"profile{len(made)}", *flags))
        return made[-1]

    yield start
    for driver in made:
        with contextlib.suppress(Exception):
            driver.quit()
    shutil.rmtree(tmp_path, ignore_errors=True)


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


# --- parallel runs (`make test`: pytest-xdist, --dist loadfile --no-loadscope-reorder) ------
#
# The suite mostly waits on real time (flights, real-clock runs, terminals, a browser), so
# `make test` runs it on more workers than cores. Each test file is one group, run on one
# worker, so its module fixtures (C++ builds, copies of the repository) are made once (a
# session fixture: once per worker that needs it); the files of SPREAD are flights that share
# nothing costly, so each of their tests is a group of its own (their C++ ones together: they
# share one build). The groups are handed out in collection order, so the longest files come
# first: the short ones fill the workers at the end instead of a long one starting last.
# (The groups are given by a scheduler, not by `xdist_group` marks: pytest-xdist 3.8 renames
# a marked test's node id, which pytest 9.2 no longer lets it do, so --dist loadgroup spreads
# every test.)
LONGEST_FIRST = (
    "test_conformance.py", "test_missions.py", "test_tour.py", "test_drone_faults.py", "test_scenario.py",
    "test_lockstep.py",
    "test_replay.py", "test_monitor_area.py",  # monitor_area flies in lockstep: 10-30 s a language
    "test_px4_missions.py",  # 14 lockstep flights on PX4 and ArduPilot: 2-10 s each
    "test_cpp.py", "test_cxxcheck.py",
    "test_component_flags.py", "test_web.py", "test_cpp_drivers.py", "test_view.py",
    "test_cpp_observers.py", "test_build.py", "test_reliability.py", "test_sim_vehicle.py",
    "test_wheel.py", "test_drivers.py", "test_sim_camera.py", "test_monitor.py",
)
# test_drone_faults.py: wall-clock link faults (205 s in all), its C++ tests sharing one build.
SPREAD = {"test_missions.py", "test_monitor_area.py", "test_scenario.py", "test_drone_faults.py",
          "test_px4_missions.py"}
# Files whose tests run once per back end, each back end building its own components once
# (the conformance suite: one CMake project of all the twins for `cpp`, another for `cpp-asan`):
# a group per back end, so that the two C++ builds, the longest chain, run side by side.
BY_BACKEND = {"test_conformance.py"}
_BACKEND_ID = re.compile(r"\[(python|cpp-asan|cpp)-")


def xdist_group(nodeid: str) -> str:
    """The group of a test (by its node id) under `make test`: one worker runs a group's tests,
    in order."""
    path, _, name = nodeid.partition("::")
    if Path(path).name in BY_BACKEND:
        backend = _BACKEND_ID.search(name)
        return f"{path}::{backend.group(1) if backend else ''}"
    if Path(path).name not in SPREAD:
        return path
    return f"{path}::{'cpp' if 'cpp' in name else name}"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    from xdist.scheduler import LoadScopeScheduling  # type: ignore[import-untyped]

    class ByGroup(LoadScopeScheduling):  # type: ignore[misc]
        def _split_scope(self, nodeid: str) -> str:
            return xdist_group(nodeid)

    return ByGroup(config, log)
