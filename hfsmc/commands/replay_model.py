"""The model a replay runs: the user's (``--model``) or, when asked, the recorded one.

A recording carries its model's sources, and a model is code: its snippets run in
the component.  So the recorded model is compiled here as data (in memory: nothing is
written, nothing runs) to name its transitions in the report, and it is built and run
only with ``--allow-recorded-code`` (docs/recording.md, "Trust").  Its component then
goes into a cache folder named from the hash recomputed from the sources (the reader
checked that the recorded hash is that one), whose real path is checked to be inside
the cache before anything is written.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from hfsmc.errors import HfsmcError
from hfsmc.ir import Model
from hfsmc.pipeline import compile_file
from hfsmc.recording import Recording, RecordingError, sources_hash

ALLOW_FLAG = "--allow-recorded-code"
VIRTUAL_ROOT = "/recording"  # where the recorded sources seem to be (never on disk)


class ReplayFailed(Exception):
    """Replay could not run (a model that does not compile, a component that failed)."""

    def __init__(self, message: str, details: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.details = tuple(details)
        self.report: object | None = None  # what was said before it failed (a Report)


class NotAllowed(Exception):
    """The replay would build and run the recorded model's code, which was not asked."""


@dataclass(frozen=True)
class Built:
    model: Model
    label: str  # how the report names it
    recorded: bool  # the recorded model (same hash)
    files: Mapping[str, str]  # a model file's path as spans give it -> as the report shows it


def virtual_sources(sources: Sequence[tuple[str, str]]) -> tuple[str, dict[str, str]]:
    """The recorded sources under VIRTUAL_ROOT, deep enough for their `..`: the model
    file's path and every file's text by normalised path."""
    ups = 0
    for path, _ in sources:
        depth = 0
        for part in path.split("/"):
            depth += -1 if part == ".." else 1
            ups = max(ups, -depth)
    home = os.path.join(VIRTUAL_ROOT, *(["m"] * ups))
    texts = {os.path.normpath(os.path.join(home, p)): text for p, text in sources}
    return os.path.join(home, sources[0][0]), texts


def recorded_model(rec: Recording) -> Built:
    """The recorded model, compiled from the text the recording holds (as data: nothing is
    read from or written to the disk); HfsmcError when it does not compile."""
    main, texts = virtual_sources(rec.sources)
    result = compile_file(main, texts=texts)
    if not result.ok or result.model is None:
        raise HfsmcError(result.diagnostics)
    home = os.path.dirname(main)
    files = {os.path.normpath(os.path.join(home, p)): p for p, _ in rec.sources}
    return Built(result.model, f"the recorded model ({rec.sources[0][0]})", True, files)


def given_model(rec: Recording, path: str) -> tuple[Built, list[str]]:
    """The model of ``--model``, and what the report says of it against the recorded one."""
    from hfsmc.model_sources import model_hash, model_sources

    result = compile_file(path)
    if not result.ok or result.model is None:
        raise HfsmcError(result.diagnostics)
    sources = model_sources(result.model)
    digest = model_hash(sources)
    same = digest == rec.model_hash
    if same:
        notes = [f"{path} is the recorded model ({digest[:19]}...)"]
    elif result.model.language != rec.language:
        notes = [f"{path} is a {result.model.language} model, the recorded one "
                 f"({rec.sources[0][0]}) {rec.language}: replayed as its twin"]
    else:
        recorded = dict(rec.sources)
        main = sources[0][0]
        if main != rec.sources[0][0]:  # the model file itself, whatever its name now
            recorded.pop(rec.sources[0][0])
            recorded[main] = rec.sources[0][1]
        changed = [p for p, text in sources if p in recorded and recorded[p] != text]
        new = [p for p, _ in sources if p not in recorded]
        gone = [p for p in recorded if p not in dict(sources)]
        what = "; ".join(x for x in (
            f"changed: {', '.join(changed)}" if changed else "",
            f"not in the recording: {', '.join(new)}" if new else "",
            f"recorded but not used now: {', '.join(gone)}" if gone else "") if x)
        notes = [f"{path} is not the recorded model ({what or 'other paths'}; hash "
                 f"{digest[:19]}... against the recorded {rec.model_hash[:19]}...)"]
    return Built(result.model, path, same, {}), notes


def cache_base() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hfsmc" / "replay"


def recorded_folder(rec: Recording, target: str) -> Path:
    """The cache folder of the recorded model's component: named from the hash recomputed
    from the sources, and inside the cache by its real path (a link planted in the cache
    cannot send the build elsewhere)."""
    digest = sources_hash(rec.sources).removeprefix("sha256:")
    base = cache_base()
    folder = base / digest[:16] / target
    base.mkdir(parents=True, exist_ok=True)
    inside = os.path.realpath(base) + os.sep
    for _ in range(2):  # before anything is made in it, and once made
        if not os.path.realpath(folder).startswith(inside):
            raise RecordingError(f"the replay cache folder {folder} leads out of {base} (a "
                                 "symbolic link?): not built")
        folder.mkdir(parents=True, exist_ok=True)
    return folder


def build(built: Built, target: str, model_arg: str | None, rec: Recording) -> list[str]:
    """Write (and for C++ compile) the component; its command line."""
    from hfsmc.component import cache_folder, write_component

    model = built.model
    if model_arg is not None:
        folder = cache_folder(model_arg, model.name + ("-cpp" if target == "cpp" else ""))
    else:
        folder = recorded_folder(rec, target)
    written = write_component(model, target, folder)
    if target == "python":
        return [sys.executable, str(written.main)]
    from hfsmc.cppcompile import compile_component

    diags = compile_component(folder, model.file)
    if any(d.severity == "error" for d in diags):
        raise ReplayFailed("the C++ component did not build",
                           [f"{d.span}: {d.message}" for d in diags][:10])
    return [str(written.main)]


def what_it_carries(rec: Recording, name: str) -> list[str]:
    """What a recording holds, for a replay that was not allowed to run its model: its
    files, the hash recomputed from them, and the two ways to replay it."""
    lines = [f"{name} holds a run of the {rec.language} component `{rec.component}` "
             f"(hfsmc {rec.run.get('hfsmc', '?')}), 0-{rec.end_us / 1e6:.3f} s, and the model "
             "it ran:"]
    for path, text in rec.sources:
        lines.append(f"  {path} ({len(text.encode())} bytes, {len(text.splitlines())} lines)")
    lines.append(f"  hash {sources_hash(rec.sources)} (recomputed from these files: the "
                 "recorded hash)")
    lines += ["A model is code: replaying builds and runs it. Replay the run with your model:",
              f"  hfsmc replay {name} --model PATH/{rec.sources[0][0]}",
              "or, for a recording you trust, build and run the code it carries:",
              f"  hfsmc replay {name} {ALLOW_FLAG}"]
    return lines
