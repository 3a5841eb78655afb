"""The wheel carries the schemas and templates, and works from outside the repository."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from hfsmc.web.server import SCRIPTS
from tests.conftest import ROOT


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    # --no-isolation: build with the virtualenv's setuptools, no download.
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(out)],
                   cwd=ROOT, check=True, capture_output=True, timeout=300, stdin=subprocess.DEVNULL)
    (whl,) = out.glob("hfsmc-*.whl")
    return whl


@pytest.mark.slow
def test_wheel_contents(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    for required in ("hfsmc/cli.py", "hfsmc/schemas/hfsm.schema.json", "hfsmc/schemas/hfsm.xsd",
                     "hfsmc/templates/README.md", "hfsmc/frontend/yaml.py", "hfsmc/emit/dot.py",
                     "hfsmc/templates/python/hfsmc_runtime.py",
                     "hfsmc/templates/python/hfsmc_main.py", "hfsmc/templates/python/hfsmc_load.py",
                     "hfsmc/templates/python/hfsmc_trace.py",
                     "hfsmc/templates/python/hfsmc_traceback.py",
                     "hfsmc/templates/python/component.py.j2", "hfsmc/schemas/trace.schema.json",
                     "hfsmc/emit/cpp.py", "hfsmc/templates/cpp/component.cpp.j2",
                     "hfsmc/templates/cpp/CMakeLists.txt.j2", "hfsmc/templates/cpp/hfsmc_runtime.cpp",
                     "hfsmc/templates/cpp/hfsmc/runtime.hpp", "hfsmc/templates/cpp/hfsmc/mavlink.hpp",
                     "hfsmc/web/server.py", "hfsmc/web/static/index.html",
                     *(f"hfsmc/web/static/{name}" for name in SCRIPTS), "hfsmc/web/static/app.css",
                     "hfsmc/editor/server.py", "hfsmc/web/static/editor.html",
                     "hfsmc/web/static/editor.js", "hfsmc/web/static/vendor/codemirror.js"):
        assert required in names, f"{required} missing from {wheel.name}"
    entry = next(n for n in names if n.endswith("entry_points.txt"))
    assert "hfsmc = hfsmc.cli:main" in zipfile.ZipFile(wheel).read(entry).decode()
    assert not any(n.startswith(("tests/", "examples/", "bench/")) for n in names)
    assert not any("node_modules" in n or n.endswith("package-lock.json") for n in names)


def hfsmc_from_wheel(wheel: Path, tmp_path: Path, example: str, *args: str,
                     ) -> subprocess.CompletedProcess[str]:
    """Run `hfsmc ARGS MODEL` from the unpacked wheel alone, on a copy of an example."""
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    model = tmp_path / Path(example).name
    model.write_text((ROOT / example).read_text())
    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import hfsmc, hfsmc.cli;"
        "assert hfsmc.__file__.startswith(sys.argv[1]), hfsmc.__file__;"
        "sys.argv = ['hfsmc', *sys.argv[3:], sys.argv[2]]; hfsmc.cli.main()"
    )
    return subprocess.run([sys.executable, "-c", code, str(site), str(model), *args],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)


@pytest.mark.slow
def test_wheel_runs_outside_the_repository(wheel: Path, tmp_path: Path) -> None:
    r = hfsmc_from_wheel(wheel, tmp_path, "examples/traffic_light/traffic_light.yaml", "check")
    assert r.returncode == 0, r.stderr


@pytest.mark.slow
def test_wheel_builds_a_component_that_runs(wheel: Path, tmp_path: Path) -> None:
    r = hfsmc_from_wheel(wheel, tmp_path, "examples/blinker/blinker.yaml", "build", "-o", "out")
    assert r.returncode == 0, r.stderr
    # The component needs neither hfsmc nor site-packages (-I -S): the standard library only.
    run = subprocess.run([sys.executable, "-I", "-S", "out/blinker.py", "--clock", "virtual",
                          "--until", "2s", "--trace", "-"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines()[-1] == '{"t":2000,"ev":"stop","reason":"until"}'
