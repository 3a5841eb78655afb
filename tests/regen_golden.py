"""Regenerate the golden files of every example (``make golden``).

tests/golden/NAME.ir.txt  the lowered IR (``hfsmc check --dump-ir``)
tests/golden/NAME.dot     the Graphviz source of ``hfsmc diagram``
tests/golden/NAME.component.py.txt  the generated Python component (``hfsmc build -t python``),
                                    then the modules of the files it uses
tests/golden/NAME.component.cpp.txt  the generated C++ sources (``hfsmc build -t cpp``): the
                                     automaton's class, its snippets, its states and main()
tests/golden/NAME.cmake.txt  its CMakeLists.txt
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = ROOT / "tests" / "golden"
sys.path.insert(0, str(ROOT))

from hfsmc.emit import cpp, python  # noqa: E402
from hfsmc.emit.dot import to_dot  # noqa: E402
from hfsmc.emit.ir_text import dump  # noqa: E402
from hfsmc.ir import Model  # noqa: E402
from hfsmc.pipeline import compile_file  # noqa: E402
from tests.conftest import examples, model_language  # noqa: E402


def python_component(model: Model) -> str:
    """The component's module, then the module of each used file (`use`) after a banner."""
    files = python.component_files(model)
    text = files[f"{model.name}.py"].decode("utf-8")
    for name in sorted(f for f in files if f.startswith("_hfsm_use_")):
        text += f"\n# ===== {name} =====\n" + files[name].decode("utf-8")
    return text


def cpp_component(model: Model) -> str:
    """The component's own files: the class (src/NAME.hpp), then its two units after a banner,
    then the class of each ros2 interface (include/hfsmc_ros2/NAME.hpp)."""
    files = cpp.component_files(model)
    text = files[f"src/{model.name}.hpp"].decode("utf-8")
    ros2 = sorted(f for f in files if f.startswith("include/hfsmc_ros2/"))
    for name in (f"src/{model.name}.cpp", f"src/{model.name}_main.cpp", *ros2):
        text += f"\n// ===== {name} =====\n" + files[name].decode("utf-8")
    return text


def cpp_cmake(model: Model) -> str:
    return cpp.component_files(model)["CMakeLists.txt"].decode("utf-8")


GENERATORS: dict[str, Callable[[Model], str]] = {
    "ir.txt": dump, "dot": to_dot, "component.py.txt": python_component,
    "component.cpp.txt": cpp_component, "cmake.txt": cpp_cmake}
# Generators that only apply to models of one snippet language.
LANGUAGE = {"component.py.txt": "python", "component.cpp.txt": "cpp", "cmake.txt": "cpp"}


def applies(example: Path, suffix: str) -> bool:
    return LANGUAGE.get(suffix, model_language(example)) == model_language(example)


def render(example: Path, suffix: str) -> str:
    rel = example.relative_to(ROOT)
    result = compile_file(str(rel))
    assert result.model is not None, f"{rel} does not compile: {result.diagnostics}"
    return GENERATORS[suffix](result.model)


# Models with golden files that are not examples: what a feature needs shown in its output.
EXTRA = [ROOT / "tests" / "ros2" / "models" / "pingpong_cpp" / "pingpong_cpp.yaml"]


def golden_models() -> list[Path]:
    return [*examples(), *EXTRA]


def golden_path(example: Path, suffix: str) -> Path:
    return GOLDEN / f"{example.stem}.{suffix}"


def main() -> None:
    import os

    os.chdir(ROOT)  # spans and file names in the output are relative to the repository
    GOLDEN.mkdir(exist_ok=True)
    for ex in golden_models():
        for suffix in GENERATORS:
            if not applies(ex, suffix):
                continue
            path = golden_path(ex, suffix)
            text = render(ex, suffix)
            old = path.read_text("utf-8") if path.exists() else None
            if old != text:
                path.write_text(text, "utf-8")
                print(f"updated {path.relative_to(ROOT)}")
    from tests.test_legacy import regenerate  # golden YAML of the legacy corpus

    for path in regenerate():
        print(f"updated {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
