#!/usr/bin/env python3
"""Vision step of the follow_colors mission: cost per frame of the model's own `blob()`.

The follow_colors component is built with ``hfsmc build`` and imported; its
``camera`` interface is replaced by frames the simulator's renderer draws over
the mission's world along the flight (320x240, the world's camera), so the
figure is the cost of the code the mission really runs on every tick (HSV
conversion, colour masks, moments), measured as process CPU time, per colour
and per frame. A 20 Hz mission has 50 ms per tick; the simulator's own
rendering cost per frame is reported beside it, and that of monitor_area's
world (a road and victims, the costlier picture) along a descending, turning
flight, against its target of 5 ms per frame (the camera's 15 Hz leaves 67 ms).

Usage::

    python bench/vision.py [--frames N] [--json bench/results.json]
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from report import hfsmc_revision, loadavg, machine, merge_json, table  # bench/report.py

from hfsmc.sim.camera import Renderer
from hfsmc.sim.world import load_world

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
WORK = HERE / "_work" / "vision"
KEY = "vision"
TICK_BUDGET_MS = 50.0  # the mission's period
RENDER_TARGET_MS = 5.0  # the simulator's frame, median (it renders at 15 Hz beside physics)


class StillCamera:
    """Stands in for the camera interface: the frame the test hands it, always fresh."""

    def __init__(self) -> None:
        self.image: Any = None

    def frame(self) -> Any:
        return self.image

    def age(self) -> float:
        return 0.0


def load_component() -> Any:
    out = WORK / "follow_colors"
    subprocess.run([sys.executable, "-m", "hfsmc", "build", str(ROOT / "examples/follow_colors/"
                    "follow_colors.yaml"), "-o", str(out)], check=True, capture_output=True)
    spec = importlib.util.spec_from_file_location("follow_colors_bench", out / "follow_colors.py")
    assert spec is not None and spec.loader is not None
    sys.path.insert(0, str(out))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def poses(world: Any, n: int) -> list[tuple[float, float, float, float, float]]:
    """Along the objects' paths, 4 m up, at the times they move: what the drone sees."""
    out = []
    end = max((o.start + 30.0 for o in world.objects), default=60.0)
    for i in range(n):
        t = end * i / max(n - 1, 1)
        near = min(world.objects, key=lambda o: abs(o.start - t)) if world.objects else None
        north, east = near.position(t) if near is not None else (0.0, 0.0)
        out.append((t, north + 1.0, east - 0.5, -4.0, 0.0))
    return out


def monitor_area_render_ms(frames: int) -> list[float]:
    """Process CPU time (ms) of each frame of monitor_area's world: over the road towards the
    accident, descending and turning (the poses tests/test_sim_camera.py renders)."""
    renderer = Renderer(load_world(ROOT / "examples/monitor_area/world.yaml"))
    costs = []
    for i in range(frames):
        c0 = time.process_time()
        renderer.render(i / 15, 40 + i * 0.3, i * 0.2, -6 - i * 0.05, i * 0.05)
        costs.append((time.process_time() - c0) * 1000)
    return costs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=400, help="frames rendered and filtered")
    ap.add_argument("--json", type=Path, help=f'merge the figures into this file under "{KEY}"')
    ns = ap.parse_args(argv)
    load_before = loadavg()
    world = load_world(ROOT / "examples/follow_colors/world.yaml")
    renderer = Renderer(world)
    component = load_component()
    camera = StillCamera()
    component.camera = camera
    component.altitude = 4.0
    frames, render_ms = [], []
    for pose in poses(world, ns.frames):
        c0 = time.process_time()
        frames.append(renderer.render(*pose))
        render_ms.append((time.process_time() - c0) * 1000)
    rows, figures = [], {}
    for color in ("green", "blue", "red"):
        costs, seen = [], 0
        for image in frames:
            camera.image = image
            c0 = time.process_time()
            found = component.blob(color)
            costs.append((time.process_time() - c0) * 1000)
            seen += bool(found)
        med, p99 = statistics.median(costs), sorted(costs)[int(0.99 * (len(costs) - 1))]
        figures[color] = {"median_ms": round(med, 3), "p99_ms": round(p99, 3), "seen": seen}
        rows.append([color, f"{med:.3f}", f"{p99:.3f}", f"{seen}/{len(frames)}",
                     f"{100 * med / TICK_BUDGET_MS:.1f} %"])
    h, w = frames[0].shape[:2]
    rmed = statistics.median(render_ms)
    print(f"vision step of follow_colors on {len(frames)} frames of {w}x{h} "
          "(process CPU time, ms per call of the model's blob())")
    for line in table(rows, ["colour", "median", "p99", "frames with the colour",
                             "of a 50 ms tick"]):
        print("  " + line)
    print(f"  simulator rendering: median {rmed:.3f} ms per frame")
    area = monitor_area_render_ms(60)
    amed = statistics.median(area)
    verdict = "met" if amed <= RENDER_TARGET_MS else "MISSED"
    print(f"  simulator rendering of monitor_area (road, victims): median {amed:.3f} ms per "
          f"frame over {len(area)} frames; target <= {RENDER_TARGET_MS:g} ms: {verdict}")
    result = {"frames": len(frames), "size": [w, h], "blob": figures,
              "render_median_ms": round(rmed, 3),
              "monitor_area_render": {"frames": len(area), "median_ms": round(amed, 3),
                                      "target_ms": RENDER_TARGET_MS,
                                      "met": amed <= RENDER_TARGET_MS},
              "machine": machine(),
              "hfsmc": hfsmc_revision(), "load": {"before": load_before, "after": loadavg()}}
    if ns.json:
        merge_json(ns.json, KEY, result)
        print(f"wrote {ns.json} (key {KEY!r})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
