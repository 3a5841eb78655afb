"""What every benchmark here shares: the machine's load, text tables, results.json."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any


def loadavg() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def table(rows: list[list[str]], header: list[str]) -> Iterator[str]:
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    fmt = "  ".join(f"{{:{'<' if i == 0 else '>'}{w}}}" for i, w in enumerate(widths))
    yield fmt.format(*header)
    yield "  ".join("-" * w for w in widths)
    for r in rows:
        yield fmt.format(*r)


def merge_json(out: Path, key: str, figures: dict[str, Any]) -> None:
    """Set ``out[key]``, keeping the other keys of an existing JSON object."""
    data: dict[str, Any] = {}
    if out.exists():
        try:
            loaded = json.loads(out.read_text(encoding="utf-8"))
            if isinstance(loaded, dict):
                data = loaded
        except json.JSONDecodeError:
            print(f"warning: {out} is not JSON; overwriting it", file=sys.stderr)
    data[key] = figures
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(out.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    tmp.replace(out)


def machine() -> dict[str, Any]:
    """CPU model, cores, memory and Python of this machine, for the figures' record."""
    cpu = platform.processor() or "unknown"
    mem_gib = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                mem_gib = round(int(line.split()[1]) / 1024 / 1024, 1)
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": mem_gib,
            "python": platform.python_version(),
            "implementation": platform.python_implementation(),
            "platform": platform.platform()}


def hfsmc_revision() -> dict[str, Any]:
    """The hfsmc version and, in a git checkout, the commit measured (dirty: sources edited)."""
    from importlib.metadata import PackageNotFoundError, version

    out: dict[str, Any] = {"commit": None, "dirty": None}
    try:
        out["version"] = version("hfsmc")
    except PackageNotFoundError:
        out["version"] = None
    repo = Path(__file__).resolve().parent.parent
    try:
        out["commit"] = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"],
                                       capture_output=True, text=True, check=True).stdout.strip()
        status = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--",
                                 "hfsmc", "templates"],
                                capture_output=True, text=True, check=True).stdout
        out["dirty"] = bool(status.strip())
    except (OSError, subprocess.CalledProcessError):
        pass
    return out


def verdict(ok: bool) -> str:
    return "met" if ok else "MISSED"


def finish_targets(figures: dict[str, Any], targets: list[dict[str, Any]],
                   load_before: list[float], json_out: Path | None, key: str,
                   log: Callable[[str], None]) -> None:
    """Record the targets and the load in ``figures``, print the verdicts, merge the
    figures into ``json_out`` under ``key`` when given, and say whether all were met."""
    load_after = loadavg()
    ok = all(t["met"] for t in targets)
    figures.update({"targets": targets, "targets_met": ok,
                    "load_average": {"before": load_before, "after": load_after}})
    log("\n== targets ==")
    for t in targets:
        log(f"  {verdict(t['met']):6}  {t['target']}: {t['value']}")
    if json_out:
        merge_json(json_out, key, figures)
        log(f"\nwrote {json_out} (key \"{key}\")")
    log(f"\ntargets {'met' if ok else 'NOT all met'} (load average before {load_before}, "
        f"after {load_after})")
