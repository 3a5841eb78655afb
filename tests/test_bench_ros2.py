"""bench/ros2.py runs (issue 32's ROS 2 figures): its short mode, Python components and
the bare Cyclone DDS pair, on loopback; every figure is there and comes from real traffic.
No time is asserted: only that each measurement measured something."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_ros2_bench_quick_python(tmp_path: Path) -> None:
    out = tmp_path / "results.json"
    p = subprocess.run([sys.executable, str(ROOT / "bench" / "ros2.py"), "--quick", "--only",
                        "python", "--json", str(out)], capture_output=True, text=True,
                       timeout=300, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-3000:] + p.stdout[-3000:]
    fig = json.loads(out.read_text())["ros2"]
    lat = fig["latency"]
    assert set(lat) == {"bare cyclonedds", "Python -> Python"}
    assert lat["bare cyclonedds"]["arrival"]["samples"] > 100  # 4 s at 100 Hz, 20 dropped
    py = lat["Python -> Python"]
    assert py["snapshot"]["samples"] > 100
    # a sample is in a snapshot only after it arrived
    assert py["snapshot"]["p50_us"] >= py["arrival"]["p50_us"]
    bump = fig["bump_and_go"]["Python"]
    for run in [*bump["runs"]["plain"], *bump["runs"]["record"]]:
        assert run["cpu_percent"] > 0
        assert run["cmd_vel_received"] > 20  # the component drove (20 Hz) all along
        assert 0 < run["sent"]["scan"] < run["sent"]["odom"]  # 10 Hz and 50 Hz
    assert bump["runs"]["record"][0]["recording_bytes"] > 10_000
    snap = fig["snapshot_10"]["Python"]
    assert snap["rounds"] == 5 and snap["median_ns"] > 0
    assert {t["target"].split(" ")[0] for t in fig["targets"]} == {"Python"}
    assert "load_average" in fig


def test_ros2_rpc_bench_quick(tmp_path: Path) -> None:
    """bench/ros2_rpc.py (issue 30): a Python and a C++ component's call -> response and
    send_goal -> accepted against the runtime's test servers, beside the bare Cyclone DDS
    request/reply pair; every figure from real exchanges."""
    out = tmp_path / "results.json"
    p = subprocess.run([sys.executable, str(ROOT / "bench" / "ros2_rpc.py"), "--quick",
                        "--json", str(out)], capture_output=True, text=True, timeout=900,
                       cwd=ROOT)
    assert p.returncode == 0, p.stderr[-3000:] + p.stdout[-3000:]
    fig = json.loads(out.read_text())["ros2_rpc"]
    n = fig["exchanges"] - fig["warmup_dropped"]
    for kind in ("call", "goal"):
        lat = fig["latency"][kind]
        assert set(lat) == {"bare cyclonedds", "Python", "C++"}
        for label in ("bare cyclonedds", "Python", "C++"):
            assert lat[label]["samples"] == n
            assert 0 < lat[label]["p50_us"] <= lat[label]["p99_us"] <= lat[label]["max_us"]
        assert "next_instant_percent" not in lat["bare cyclonedds"]
        for lang in ("Python", "C++"):
            assert 0 <= lat[lang]["next_instant_percent"] <= 100
            ratio = fig["ratio_to_floor"][kind][lang]
            assert ratio["p50"] == round(lat[lang]["p50_us"] / lat["bare cyclonedds"]["p50_us"], 2)
    assert fig["targets"] == [] and "load_average" in fig
    assert "send_goal -> accepted" in p.stdout
