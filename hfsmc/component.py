"""`hfsmc build` and `hfsmc run`: a checked model becomes a component folder."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from hfsmc.errors import UsageError
from hfsmc.fsutil import write_atomic, write_tree
from hfsmc.ir import Model

TARGETS = ("python", "cpp")


@dataclass(frozen=True)
class WrittenComponent:
    folder: Path
    files: tuple[str, ...]  # every file of the component, relative to folder
    changed: tuple[str, ...]  # the ones this build rewrote
    main: Path  # what to run


def component_files(model: Model, target: str) -> tuple[dict[str, bytes], frozenset[str], str]:
    """The files of the component, the executable ones, and the one to run."""
    if target == "python":
        from hfsmc.emit import python

        return python.component_files(model), frozenset({f"{model.name}.py"}), f"{model.name}.py"
    if target == "cpp":
        from hfsmc.emit import cpp

        return cpp.component_files(model), frozenset(), f"build/{model.name}"
    raise UsageError(f"unknown target `{target}`: python or cpp")


def write_component(model: Model, target: str, folder: Path,
                    depfile: Path | None = None) -> WrittenComponent:
    """Write the component (only files whose bytes changed) and, if asked, a make depfile."""
    files, executable, main = component_files(model, target)
    changed = write_tree(folder, files, executable)
    if depfile is not None:
        write_depfile(depfile, [str(folder / f) for f in sorted(files)], model)
    return WrittenComponent(folder, tuple(sorted(files)), tuple(sorted(changed)), folder / main)


def write_depfile(depfile: Path, outputs: list[str], model: Model) -> None:
    """A make depfile: ``outputs`` depend on the model's file and the files it uses."""
    targets = " ".join(_make_escape(f) for f in outputs)
    inputs = " ".join(_make_escape(f) for f in model_files(model))
    write_atomic(depfile, f"{targets}: {inputs}\n")


def model_files(model: Model) -> list[str]:
    """The model's file, then the files its states `use` (nested ones too), each once."""
    files = [model.file]
    for automaton in model.automata():
        if automaton.instance is not None and automaton.instance.file not in files:
            files.append(automaton.instance.file)
    for i in model.interfaces:  # a ros2 interface's own .msg files
        files += [m.path for m in (i.ros2.messages if i.ros2 is not None else ())
                  if m.path not in files]
    return files


def _make_escape(path: str) -> str:
    return path.replace("$", "$$").replace(" ", "\\ ").replace("#", "\\#")


def cache_folder(model_path: str, name: str) -> Path:
    """Where `hfsmc run` keeps the component of a model: one folder per model file."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hfsmc" / "run"
    digest = hashlib.sha256(os.fsencode(os.path.abspath(model_path))).hexdigest()[:12]
    return base / f"{name}-{digest}"
