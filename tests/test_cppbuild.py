"""Fast C++ builds: what a build shows while it runs, and what a rebuild compiles.

``hfsmc build --compile`` and ``hfsmc run`` show CMake's steps (``Progress``); a
change to one snippet recompiles the component's translation unit only, not the
runtime library (counted from the steps shown; bench/cppbuild.py shows that the
precompiled headers of a component with drivers are not made again either).
"""

from __future__ import annotations

import io
import re
import shutil
import subprocess
import sys
from pathlib import Path

from hfsmc.cppcompile import Progress, step
from tests.cppbuild import need_toolchain

ROOT = Path(__file__).resolve().parent.parent
BLINKER = ROOT / "examples/blinker_cpp/blinker_cpp.yaml"


def test_steps_of_ninja_and_make_in_a_few_words() -> None:
    pch = "CMakeFiles/hfsmc_pch__hfsmc_runtime_hpp_.dir"
    assert step("[1/6] Building CXX object CMakeFiles/hfsmc_runtime.dir/src/hfsmc_runtime.cpp.o"
                ) == "[1/6] compiling hfsmc_runtime.cpp"
    assert step(f"[2/6] Building CXX object {pch}/cmake_pch.hxx.gch") \
        == "[2/6] precompiling headers"
    assert step(f"[3/6] Building CXX object {pch}/hfsmc_pch__hfsmc_runtime_hpp_.cpp.o") is None
    assert step("[6/6] Linking CXX executable blinker_cpp") == "[6/6] linking blinker_cpp"
    assert step("[ 50%] Building CXX object CMakeFiles/x.dir/src/x.cpp.o\n") \
        == "[ 50%] compiling x.cpp"
    assert step("[ 75%] Linking CXX static library libhfsmc_runtime.a") \
        == "[ 75%] linking libhfsmc_runtime.a"
    assert step("[0/1] Re-running CMake...") == "[0/1] configuring (CMake)"
    assert step("[ 50%] Built target hfsmc_runtime") is None
    assert step("src/x.cpp:3:1: error: expected ';'") is None


NINJA = ["[1/3] Building CXX object CMakeFiles/r.dir/src/r.cpp.o", "g++ said something",
         "[2/3] Building CXX object CMakeFiles/b.dir/src/b.cpp.o",
         "[3/3] Linking CXX executable b"]
PLAN = ["[0/3]", "compiling r.cpp", "compiling b.cpp", "linking b"]


def test_progress_is_a_line_per_step_off_a_terminal() -> None:
    out = io.StringIO()
    shown = Progress("b", out, tty=False)
    shown.show("configuring (CMake)")
    shown.expect(None, 2)  # Make: a step is printed as it starts
    for line in ("[ 50%] Building CXX object CMakeFiles/b.dir/src/b.cpp.o", "[ 75%] Built target b",
                 "[100%] Linking CXX executable b"):
        shown.line(line + "\n")
    shown.close()
    assert out.getvalue() == ("b: configuring (CMake)\n"
                              "b: [ 50%] compiling b.cpp\n"
                              "b: [100%] linking b\n")
    out = io.StringIO()
    shown = Progress("b", out, tty=False)
    shown.expect(PLAN, 2)  # Ninja: as it ends
    for line in NINJA:
        shown.line(line + "\n")
    shown.close()
    assert out.getvalue() == "b: [1/3] compiled r.cpp\nb: [2/3] compiled b.cpp\nb: [3/3] linked b\n"


def test_progress_on_a_terminal_names_what_runs_and_erases_its_line() -> None:
    out = io.StringIO()
    shown = Progress("b", out, tty=True)
    shown.expect(PLAN, 2)
    shown.line(NINJA[0] + "\n")
    shown.close()
    shown.close()
    frames = out.getvalue().split("\r\x1b[K")
    assert "\n" not in out.getvalue()
    assert frames[0] == "" and frames[-1] == ""
    assert re.fullmatch(r"b: \[0/3\] compiling r\.cpp, compiling b\.cpp \(\d+ s\)", frames[1])
    assert re.fullmatch(r"b: \[1/3\] compiled r\.cpp; compiling b\.cpp \(\d+ s\)", frames[2])


def _compiled(stderr: str) -> list[str]:
    """The units a build compiled, from the steps `hfsmc build --compile` shows."""
    return re.findall(r"^blinker_cpp: \[[^]]*\] (?:pre)?compil(?:ing|ed) (.*)$", stderr, re.M)


def _linked(stderr: str) -> list[str]:
    """The libraries and programs a build linked, from the steps it shows."""
    return re.findall(r"^blinker_cpp: \[[^]]*\] link(?:ing|ed) (.*)$", stderr, re.M)


def test_a_snippet_change_recompiles_the_component_unit_only(tmp_path: Path) -> None:
    need_toolchain()
    model = tmp_path / BLINKER.name
    shutil.copy(BLINKER, model)
    out = tmp_path / "blinker_cpp"
    cmd = [sys.executable, "-m", "hfsmc", "build", "-t", "cpp", model.name, "-o", str(out),
           "--compile"]

    def build() -> str:
        r = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, r.stderr
        return r.stderr

    said = build()
    assert sorted(_compiled(said)) == ["blinker_cpp.cpp", "blinker_cpp_main.cpp",
                                       "hfsmc_engine.cpp", "hfsmc_json.cpp",
                                       "hfsmc_record.cpp", "hfsmc_runtime.cpp"], said
    library = out / "build" / "libhfsmc_runtime.a"
    made = library.stat().st_mtime_ns
    text = model.read_text("utf-8")
    # One more line in Dark's entry: every snippet after it moves down a line in the model.
    grown = text.replace("      Dark:\n        entry: led = false;\n",
                         "      Dark:\n        entry: |\n          led = false;\n"
                         "          pauses += 0;\n", 1)
    assert grown != text
    model.write_text(grown, "utf-8")
    header = out / "src" / "blinker_cpp.hpp"
    declared = header.stat().st_mtime_ns
    said = build()
    # The snippet's unit only: not the class (its header is not even written again), nor
    # main() with the engine and the states, nor the runtime library.
    assert _compiled(said) == ["blinker_cpp.cpp"], said
    assert _linked(said) == ["blinker_cpp"], said
    assert library.stat().st_mtime_ns == made
    assert header.stat().st_mtime_ns == declared
    said = build()
    assert _compiled(said) == [], said


def test_a_release_build_compiles_the_automaton_as_one_unit_and_runs_the_same(
        tmp_path: Path) -> None:
    """Release: the two units in one by default (the snippets inlined into the states); the
    run is the same as with the two units apart (as RelWithDebInfo, what --compile builds,
    has them; the same flags otherwise, so the second build's libraries come from ccache)."""
    need_toolchain()
    out = tmp_path / "blinker_cpp"
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "cpp", str(BLINKER), "-o",
                    str(out)], check=True, capture_output=True, timeout=300)
    runs = []
    for name, options, one_unit in (("default", [], True), ("apart", ["-DHFSMC_UNITY=OFF"], False)):
        build = tmp_path / name
        subprocess.run(["cmake", "-S", str(out), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                        *options], check=True, capture_output=True, timeout=300)
        said = subprocess.run(["cmake", "--build", str(build)], check=True, capture_output=True,
                              text=True, timeout=900).stdout
        units = re.findall(r"Building CXX object CMakeFiles/blinker_cpp\.dir/(\S+)\.o$", said,
                           re.M)
        assert (len(units) == 1 and "unity" in units[0]) == one_unit, units
        r = subprocess.run([str(build / "blinker_cpp"), "--clock", "virtual", "--until", "20s",
                            "--trace", "-"], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        runs.append((r.stdout, r.stderr))
    assert runs[0] == runs[1]
    assert '"ev":"fire"' in runs[0][0] and "stopped after" in runs[0][1]
