"""Try every legacy file of a folder as a new user would, and print a table.

    .venv/bin/python scripts/legacy_sweep.py FOLDER [--cpp-compile] [--keep DIR]

For each ``*.xml`` under FOLDER (VisualStates, VisualHFSM 3.x or 5 files):

1. ``hfsmc convert FILE -o NAME.yaml`` exits 0, with no traceback;
2. the converted model has as many states and transitions as the file
   (counted here in the XML, independently of the importer);
3. ``hfsmc diagram NAME.yaml`` draws it;
4. ``hfsmc build NAME.yaml -t LANGUAGE`` writes the component;
5. Python: every file of the component byte-compiles; C++: with
   ``--cpp-compile``, ``hfsmc check`` compiles the snippets with g++; a snippet
   that uses a ROS/ICE interface cannot compile (hfsmc has no driver for them),
   and the stage says ``skip`` when those are the only errors.

The last lines count the files that pass each stage and the failures by kind
(the stage, then the first diagnostic code).  Used to measure the legacy import
against the history of JdeRobot VisualStates (docs/legacy.md).
"""

from __future__ import annotations

import argparse
import py_compile
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

from lxml import etree

from hfsmc.pipeline import Result, compile_file

STAGES = ("convert", "counts", "diagram", "build", "compile")


def source_counts(path: Path) -> tuple[int, int]:
    """States and transitions written in the file (a VisualStates root state excluded)."""
    root = etree.parse(str(path), etree.XMLParser(resolve_entities=False)).getroot()
    subs = root.findall("SubAutomata")
    if subs and any(s.find("Estado") is not None or s.find("idSub") is not None for s in subs):
        states = root.findall("SubAutomata/Estado")  # VisualHFSM 3.x
        return len(states), len(root.findall("SubAutomata/Estado/transiciones/transicion"))
    if subs:
        return len(root.findall("SubAutomata/state")), len(root.findall("SubAutomata/transition"))
    top = root.find("state")
    if top is None:
        return 0, 0
    inner = [s for s in top.iter("state") if s is not top]
    return len(inner), sum(len(s.findall("transition")) for s in inner)


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hfsmc", *args], cwd=cwd, text=True,
                          capture_output=True, timeout=300, check=False)


def _why(out: str) -> str:
    if "Traceback" in out or "internal error" in out:
        return "traceback"
    codes = re.findall(r"error\[(E\d+)\]", out)
    return codes[0] if codes else (out.strip().splitlines() or ["?"])[-1][:60]


def _cpp_check(yaml: Path, here: Path) -> str:
    """``hfsmc check`` compiles a C++ model's snippets with g++ (-fsyntax-only)."""
    r = _run(["check", str(yaml)], here)
    if r.returncode == 0:
        return "ok"
    errors = [x for x in r.stderr.splitlines() if "error[" in x]
    if any(re.search(r"Unavailable|JdeRobotTypes|jderobot|_msgs/|ros/|Ice::", x) for x in errors):
        return "skip (code needs ROS/ICE)"  # what follows the first such error is its echo
    return f"FAIL {(errors or ['?'])[0].split(': ', 1)[-1][:70]}"


def _converted_model(path: Path) -> Result:
    """What `convert` compiled the file to (its model even when the file's code has errors)."""
    try:
        from hfsmc.commands.convert import compile_for_convert
    except ImportError:  # an hfsmc older than convert's W220 (to measure "before")
        return compile_file(str(path))
    return compile_for_convert(str(path))


def sweep(folder: Path, cpp_compile: bool, keep: Path | None) -> list[dict[str, str]]:
    rows: list[dict[str, str]] = []
    files = sorted(p for p in folder.rglob("*.xml") if p.is_file())
    with tempfile.TemporaryDirectory() as tmp:
        work = keep or Path(tmp)
        for n, path in enumerate(files):
            row = {"file": str(path.relative_to(folder))}
            rows.append(row)
            here = work / f"{n:03d}"
            shutil.rmtree(here, ignore_errors=True)
            here.mkdir(parents=True)
            name = re.sub(r"\W", "_", path.stem) or "model"
            yaml = here / f"{name}.yaml"
            r = _run(["convert", str(path.resolve()), "-o", str(yaml)], here)
            out = r.stdout + r.stderr
            if r.returncode != 0 or "Traceback" in out or not yaml.exists():
                row["convert"] = f"FAIL {_why(out)}"
                continue
            row["convert"] = "ok"
            row["warnings"] = str(len(re.findall(r"warning\[", out)))
            if "warning[W220]" in out:  # errors of the file's own code, carried over
                row["file_code"] = "yes"
            result = _converted_model(path)
            if result.model is None:
                row["counts"] = f"FAIL {_why(str(result.diagnostics))}"
                continue
            got = (sum(1 for _ in result.model.states()),
                   sum(len(s.transitions) for s in result.model.states()))
            want = source_counts(path)
            row["counts"] = "ok" if got == want else f"FAIL {got} != {want}"
            r = _run(["diagram", str(yaml), "-o", str(here / f"{name}.svg")], here)
            row["diagram"] = "ok" if r.returncode == 0 else f"FAIL {_why(r.stdout + r.stderr)}"
            lang = result.model.language
            comp = here / "component"
            r = _run(["build", str(yaml), "-t", lang, "-o", str(comp)], here)
            if r.returncode != 0:
                row["build"] = f"FAIL {_why(r.stdout + r.stderr)}"
                continue
            row["build"] = f"ok ({lang})"
            if lang == "python":
                try:
                    for src in sorted(comp.glob("*.py")):
                        py_compile.compile(str(src), cfile=str(here / "x.pyc"), doraise=True)
                    row["compile"] = "ok"
                except py_compile.PyCompileError as e:
                    row["compile"] = f"FAIL {str(e).splitlines()[-1][:60]}"
            elif not cpp_compile:
                row["compile"] = "skip (no --cpp-compile)"
            else:
                row["compile"] = _cpp_check(yaml, here)
    return rows


def report(rows: list[dict[str, str]]) -> str:
    width = max(len(r["file"]) for r in rows) if rows else 4
    lines = [f"{'file':{width}}  " + "  ".join(f"{s:9}" for s in STAGES)]
    for r in rows:
        cells = []
        for s in STAGES:
            v = r.get(s, "-")
            cells.append(v if v.startswith("FAIL") else f"{v.split()[0]:9}")
        lines.append(f"{r['file']:{width}}  " + "  ".join(cells))
    lines.append("")
    lines.append(f"files tried: {len(rows)}")
    for s in STAGES:
        passed = sum(1 for r in rows if r.get(s, "").startswith("ok"))
        skipped = sum(1 for r in rows if r.get(s, "").startswith("skip"))
        lines.append(f"  {s:8} ok {passed}" + (f", skipped {skipped}" if skipped else ""))
    kinds = Counter((f"{s}: {r[s].removeprefix('FAIL ')}" if s != "counts" else "counts differ")
                    + (" (the file's own code: W220 at convert)" if r.get("file_code") else "")
                    for r in rows for s in STAGES if r.get(s, "").startswith("FAIL"))
    all_ok = sum(1 for r in rows if all(r.get(s, "").startswith(("ok", "skip")) for s in STAGES))
    lines.append(f"  every stage: {all_ok} of {len(rows)}")
    if kinds:
        lines.append("failures by kind:")
        lines += [f"  {n:3}  {k}" for k, n in kinds.most_common()]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--cpp-compile", action="store_true",
                    help="compile the snippets of C++ models with g++ (hfsmc check)")
    ap.add_argument("--keep", type=Path, help="work in this folder and keep what was written")
    args = ap.parse_args()
    print(report(sweep(args.folder, args.cpp_compile, args.keep)))


if __name__ == "__main__":
    main()
