#!/usr/bin/env python3
"""ROS 2 components on loopback: latency, CPU, the snapshot, ``--record`` (issue 32).

In one run, beside a bare cyclonedds-python writer/reader pair (bench/ros2_peers.py, no
hfsmc: the floor), all on loopback (``CYCLONEDDS_URI``: 127.0.0.1, no multicast) in a
ROS 2 domain no test holds meanwhile:

1. **latency**, publish to snapshot, p50/p99: a sender component (bench/models/
   ros2_ping*.yaml) publishes CLOCK_MONOTONIC in a std_msgs/msg/Int64 at 100 Hz; a
   receiver (ros2_pong*.yaml, period 1 ms) notes, for each new sample its snapshot holds,
   the delay to its snippet (right after the snapshot; includes the wait for the next
   1 ms instant) and to the sample's arrival in the interface (its age subtracted: the
   middleware's part, comparable to the bare pair's), Python -> Python and C++ -> C++;
2. **CPU** of a bump-and-go component (examples/bump_and_go, and its C++ twin
   bench/models/bump_and_go.cpp.yaml) fed by a steady feeder process (a 360-ray
   LaserScan at 10 Hz, Odometry at 50 Hz, its cmd_vel read back: 20 Hz), its user +
   system time from /proc/PID/stat over a fixed window after a warm-up;
3. **the snapshot** of an interface with 10 subscriptions, each holding a message
   (ros2_snap10*.yaml): the mean of many calls of what the engine calls when an instant
   begins, timed inside the component;
4. **``--record``**: the bump-and-go runs of 2 with and without ``--record``, interleaved.

Targets (issue 32): C++ CPU <= 2 % of a core, Python <= 8 %; snapshot C++ <= 5 us (Python
reported against the same); ``--record`` <= 5 % of a core more (the reading of
bench/record.py; the overhead relative to the component's own CPU is reported beside it).

Usage::

    python bench/ros2.py                 # about 5 minutes (+ the C++ builds the first time)
    python bench/ros2.py --quick         # short windows, one round: about 1.5 minutes
    python bench/ros2.py --json bench/results.json
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from component import busy_percent, cpu_counters  # bench/component.py, beside this script
from cpp import build_cpp, build_python
from report import finish_targets, hfsmc_revision, loadavg, machine, table, verdict

HERE = Path(__file__).resolve().parent
MODELS = HERE / "models"
EXAMPLES = HERE.parent / "examples"
WORK = HERE / "_work" / "ros2"
PEERS = HERE / "ros2_peers.py"
KEY = "ros2"
LOOPBACK = ("<CycloneDDS><Domain Id=\"any\"><General><Interfaces>"
            "<NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
            "<AllowMulticast>false</AllowMulticast></General>"
            "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
            "<MaxAutoParticipantIndex>19</MaxAutoParticipantIndex>"
            "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>")
DOMAINS = range(10, 102)  # as the tests (tests/ros2_support.py), with the same lock files
TARGET_CPU = {"C++": 2.0, "Python": 8.0}  # % of a core
TARGET_SNAPSHOT_US = 5.0
TARGET_RECORD = 5.0  # % of a core more with --record (as bench/record.py; relative shown too)
WARMUP_SAMPLES = 20  # latency samples dropped at the start (discovery, first handshakes)
BUMP_SPEC = {"publish": {"scan": {"topic": "scan", "type": "sensor_msgs/msg/LaserScan",
                                  "qos": "sensor_data", "rate": 10},
                         "odom": {"topic": "odom", "type": "nav_msgs/msg/Odometry",
                                  "qos": "default", "rate": 50}},
             "subscribe": {"cmd_vel": {"topic": "cmd_vel", "type": "geometry_msgs/msg/Twist",
                                       "qos": "default"}}}
SNAP10_TOPICS = {"scan": ("scan", "sensor_msgs/msg/LaserScan", "sensor_data"),
                 "odom": ("odom", "nav_msgs/msg/Odometry", "default"),
                 "imu": ("imu", "sensor_msgs/msg/Imu", "sensor_data"),
                 "bumper": ("bumper", "std_msgs/msg/Bool", "default"),
                 "battery": ("battery", "sensor_msgs/msg/BatteryState", "default"),
                 "joints": ("joint_states", "sensor_msgs/msg/JointState", "default"),
                 "pose": ("pose", "geometry_msgs/msg/PoseStamped", "default"),
                 "goal": ("goal", "geometry_msgs/msg/PoseStamped", "default"),
                 "sonar": ("sonar", "sensor_msgs/msg/Range", "default"),
                 "temperature": ("temperature", "sensor_msgs/msg/Temperature", "default")}
SNAP10_SPEC = {"publish": {k: {"topic": t, "type": ty, "qos": q, "rate": 10}
                           for k, (t, ty, q) in SNAP10_TOPICS.items()}}


@dataclass(frozen=True)
class Mode:
    latency_s: float  # how long the sender sends
    warmup_s: float  # the component runs this long before its CPU is read
    window_s: float  # the CPU window
    rounds: int  # of each bump-and-go run, with and without --record
    snap_rounds: int


FULL = Mode(latency_s=15.0, warmup_s=4.0, window_s=20.0, rounds=2, snap_rounds=40)
QUICK = Mode(latency_s=4.0, warmup_s=2.0, window_s=4.0, rounds=1, snap_rounds=5)


@contextlib.contextmanager
def ros2_domain() -> Iterator[int]:
    """A ROS 2 domain id no test or other bench holds meanwhile (a lock file per id, the
    scheme of tests/ros2_support.py, so neither disturbs the other's figures)."""
    folder = os.path.join(tempfile.gettempdir(), "hfsmc-ros2-domains")
    os.makedirs(folder, exist_ok=True)
    for dom in reversed(DOMAINS):  # from the top: the tests start low
        fd = os.open(os.path.join(folder, f"{dom}.lock"), os.O_CREAT | os.O_RDWR, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        try:
            yield dom
        finally:
            os.close(fd)
        return
    raise SystemExit("every ROS 2 domain id is taken")


class Procs:
    """Processes started for one measurement; every one is stopped when it ends."""

    def __init__(self, env: dict[str, str]) -> None:
        self.env = env
        self.procs: list[tuple[str, subprocess.Popen[str]]] = []

    def start(self, what: str, cmd: list[str]) -> subprocess.Popen[str]:
        p = subprocess.Popen(cmd, env=self.env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        self.procs.append((what, p))
        return p

    def wait_all(self, timeout: float) -> dict[str, tuple[int, str, str]]:
        """Wait for every process; {what: (status, stdout, stderr)}. One that does not end
        in ``timeout`` s is killed and the run stops with its stderr."""
        end = time.monotonic() + timeout
        out: dict[str, tuple[int, str, str]] = {}
        for what, p in self.procs:
            try:
                so, se = p.communicate(timeout=max(0.1, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                so, se = p.communicate()
                raise SystemExit(f"{what}: did not end in time\n{se[-2000:]}") from None
            out[what] = (p.returncode, so, se)
        return out

    def __enter__(self) -> Procs:
        return self

    def __exit__(self, *_: object) -> None:
        for _what, p in self.procs:
            if p.poll() is None:
                p.kill()
                p.communicate()


def must_succeed(results: dict[str, tuple[int, str, str]]) -> None:
    for what, (status, _so, se) in results.items():
        if status != 0:
            raise SystemExit(f"{what}: exit status {status}\n{se[-3000:]}")


def percentiles(ns: list[int]) -> dict[str, float]:
    """p50, p99 and max of delays in ns, in microseconds."""
    if not ns:
        raise SystemExit("no latency sample")
    s = sorted(ns)
    q = statistics.quantiles(s, n=100, method="inclusive") if len(s) > 1 else [s[0]] * 99
    return {"p50_us": round(q[49] / 1e3, 1), "p99_us": round(q[98] / 1e3, 1),
            "max_us": round(s[-1] / 1e3, 1), "samples": len(s)}


def proc_cpu_s(pid: int) -> float:
    """Time process ``pid`` has run on a CPU so far, all its threads, in seconds: the sum
    of its threads' /proc/PID/task/TID/schedstat (ns, where /proc/PID/stat counts 10 ms
    ticks: too coarse for a component that uses 0.5 % of a core). A thread that ended
    meanwhile is no longer counted: the components keep theirs for their whole life."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError, ValueError, IndexError):
            total += int((task / "schedstat").read_text(encoding="ascii").split()[0])
    return total / 1e9


# -- the builds ------------------------------------------------------------------------
@dataclass
class Programs:
    py: dict[str, Path]  # model -> the Python component's script
    cpp: dict[str, Path]  # model -> the C++ component's executable


def build_all(langs: tuple[str, ...], log: Callable[[str], None]) -> Programs:
    WORK.mkdir(parents=True, exist_ok=True)
    py: dict[str, Path] = {}
    cpp: dict[str, Path] = {}
    t0 = time.monotonic()
    for name in ("ros2_ping", "ros2_pong", "ros2_snap10"):
        py[name] = build_python(MODELS / f"{name}.yaml", WORK / f"py_{name}")
        if "C++" in langs:
            cpp[name] = build_cpp(MODELS / f"{name}.cpp.yaml", WORK / f"cpp_{name}").exe
    py["bump_and_go"] = build_python(EXAMPLES / "bump_and_go" / "bump_and_go.yaml",
                                     WORK / "py_bump_and_go")
    if "C++" in langs:
        cpp["bump_and_go"] = build_cpp(MODELS / "bump_and_go.cpp.yaml",
                                       WORK / "cpp_bump_and_go").exe
    log(f"built {len(py)} Python and {len(cpp)} C++ components in "
        f"{time.monotonic() - t0:.0f} s")
    return Programs(py, cpp)


def command(progs: Programs, lang: str, model: str) -> list[str]:
    return [str(progs.cpp[model])] if lang == "C++" else [sys.executable, str(progs.py[model])]


def peer(mode: str, *args: str) -> list[str]:
    return [sys.executable, str(PEERS), mode, *args]


# -- 1. latency ------------------------------------------------------------------------
def latency(progs: Programs, env: dict[str, str], mode: Mode, langs: tuple[str, ...],
            log: Callable[[str], None]) -> dict[str, Any]:
    secs = mode.latency_s
    out: dict[str, Any] = {}
    for label in ("bare cyclonedds", *(f"{lang} -> {lang}" for lang in langs)):
        f = WORK / "latency.txt"
        f.unlink(missing_ok=True)
        before = cpu_counters()
        with Procs(env) as ps:
            if label == "bare cyclonedds":
                ps.start("bare-sub", peer("bare-sub", "--seconds", f"{secs + 3:g}", "--out", str(f)))
                ps.start("bare-pub", peer("bare-pub", "--seconds", f"{secs:g}"))
            else:
                lang = label.split(" ")[0]
                ps.start(f"{lang} receiver", [*command(progs, lang, "ros2_pong"), "--until",
                                              f"{secs + 3:g}s", "--param", f"out={f}"])
                ps.start(f"{lang} sender", [*command(progs, lang, "ros2_ping"), "--until",
                                            f"{secs:g}s"])
            must_succeed(ps.wait_all(secs + 60))
        rows = [line.split() for line in f.read_text(encoding="ascii").splitlines()]
        rows = rows[WARMUP_SAMPLES:]
        fig: dict[str, Any] = {"machine_busy_percent": busy_percent(before, cpu_counters())}
        if label == "bare cyclonedds":
            fig["arrival"] = percentiles([int(r[0]) for r in rows])
        else:
            fig["snapshot"] = percentiles([int(r[0]) for r in rows])
            fig["arrival"] = percentiles([int(r[1]) for r in rows])
        out[label] = fig
        log(f"  {label}: {json.dumps(fig)}")
    return out


# -- 2 and 4. CPU of bump-and-go, with and without --record ----------------------------
def bump_run(progs: Programs, env: dict[str, str], mode: Mode, lang: str,
             record: bool) -> dict[str, Any]:
    life = mode.warmup_s + mode.window_s
    rec = WORK / f"bump_{'cpp' if lang == 'C++' else 'py'}.mcap"
    rec.unlink(missing_ok=True)
    with Procs(env) as ps:
        feeder = ps.start("feeder", peer("feed", "--folder", str(progs.py["bump_and_go"].parent),
                                         "--spec", json.dumps(BUMP_SPEC),
                                         "--seconds", f"{life + 2:g}"))
        del feeder
        comp = ps.start(f"{lang} bump_and_go",
                        [*command(progs, lang, "bump_and_go"), "--until", f"{life + 1:g}s",
                         *(["--record", str(rec)] if record else [])])
        time.sleep(mode.warmup_s)
        c0, t0, m0 = proc_cpu_s(comp.pid), time.monotonic(), cpu_counters()
        time.sleep(mode.window_s)
        c1, t1, m1 = proc_cpu_s(comp.pid), time.monotonic(), cpu_counters()
        results = ps.wait_all(life + 60)
    must_succeed(results)
    fed = json.loads(results["feeder"][1].strip().splitlines()[-1])
    return {"cpu_percent": round(100 * (c1 - c0) / (t1 - t0), 3),
            "cmd_vel_received": fed["received"].get("cmd_vel"), "sent": fed["sent"],
            "recording_bytes": rec.stat().st_size if record and rec.exists() else None,
            "machine_busy_percent": busy_percent(m0, m1)}


def bump_cpu(progs: Programs, env: dict[str, str], mode: Mode, langs: tuple[str, ...],
             log: Callable[[str], None]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for lang in langs:
        runs: dict[str, list[dict[str, Any]]] = {"plain": [], "record": []}
        for r in range(mode.rounds):
            order = (False, True) if r % 2 == 0 else (True, False)
            for record in order:
                f = bump_run(progs, env, mode, lang, record)
                runs["record" if record else "plain"].append(f)
                log(f"  {lang}{' --record' if record else ''}: {json.dumps(f)}")
        plain = statistics.median(f["cpu_percent"] for f in runs["plain"])
        with_rec = statistics.median(f["cpu_percent"] for f in runs["record"])
        out[lang] = {"runs": runs, "cpu_percent": round(plain, 3),
                     "cpu_percent_record": round(with_rec, 3),
                     "record_more_points": round(with_rec - plain, 3),
                     "record_overhead_percent": round(100 * (with_rec - plain) / plain, 1)
                     if plain else None}
    return out


# -- 3. the snapshot of 10 subscriptions ----------------------------------------------
def snapshot_cost(progs: Programs, env: dict[str, str], mode: Mode, langs: tuple[str, ...],
                  log: Callable[[str], None]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for lang in langs:
        f = WORK / "snap10.txt"
        f.unlink(missing_ok=True)
        with Procs(env) as ps:
            comp = ps.start(f"{lang} snap10", [*command(progs, lang, "ros2_snap10"), "--until",
                                               "40s", "--param", f"out={f}", "--param",
                                               f"rounds={mode.snap_rounds}"])
            ps.start("feeder", peer("feed", "--folder", str(progs.py["ros2_snap10"].parent),
                                    "--spec", json.dumps(SNAP10_SPEC), "--seconds", "40"))
            while comp.poll() is None and not (f.exists() and f.stat().st_size):
                time.sleep(0.2)
            comp.wait(timeout=60)
            for _what, p in ps.procs:  # the feeder is done once the component has its figures
                if p.poll() is None:
                    p.terminate()
            results = ps.wait_all(30)
        status, _so, se = results[f"{lang} snap10"]
        if status != 0 or not f.exists():
            raise SystemExit(f"{lang} snap10: exit status {status}\n{se[-3000:]}")
        means = [float(x) for x in f.read_text(encoding="ascii").split()]
        if not means:
            raise SystemExit(f"{lang} snap10: no figure ({se.strip()[-500:]})")
        out[lang] = {"median_ns": round(statistics.median(means), 1),
                     "min_ns": round(min(means), 1), "rounds": len(means)}
        log(f"  {lang}: {json.dumps(out[lang])}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="ROS 2 components on loopback: latency against a "
                                 "bare Cyclone DDS pair, CPU of bump-and-go, the snapshot of 10 "
                                 "subscriptions, the cost of --record.")
    ap.add_argument("--quick", action="store_true", help="short windows, one round")
    ap.add_argument("--only", choices=("python", "cpp"),
                    help="the components of one language only (beside the bare pair)")
    ap.add_argument("--json", type=Path, metavar="OUT",
                    help=f'merge the figures into OUT under the key "{KEY}"')
    ns = ap.parse_args(argv)
    mode = QUICK if ns.quick else FULL
    langs = {"python": ("Python",), "cpp": ("C++",)}.get(ns.only or "", ("Python", "C++"))

    def log(s: str = "") -> None:
        print(s, flush=True)

    info, revision = machine(), hfsmc_revision()
    load_before = loadavg()
    log(f"machine: {info['cpu']}, {info['cores']} cores, {info['memory_gib']} GiB; Python "
        f"{info['python']}; hfsmc {revision['version']} at {revision['commit']}"
        f"{' (modified)' if revision['dirty'] else ''}; load average {load_before}")
    progs = build_all(langs, log)
    with ros2_domain() as dom:
        env = {**os.environ, "CYCLONEDDS_URI": LOOPBACK, "ROS_DOMAIN_ID": str(dom)}
        log(f"\n== 1. publish -> snapshot latency, 100 Hz for {mode.latency_s:g} s (domain {dom}) ==")
        lat = latency(progs, env, mode, langs, log)
        log(f"\n== 2+4. bump-and-go CPU over {mode.window_s:g} s after {mode.warmup_s:g} s, "
            f"with and without --record, {mode.rounds} round(s) ==")
        cpu = bump_cpu(progs, env, mode, langs, log)
        log("\n== 3. snapshot of 10 subscriptions ==")
        snap = snapshot_cost(progs, env, mode, langs, log)

    log("\nlatency, microseconds (p50 / p99 / max)")
    rows = []
    for label, f in lat.items():
        a, s = f["arrival"], f.get("snapshot")
        rows.append([label, f"{a['p50_us']:g} / {a['p99_us']:g} / {a['max_us']:g}",
                     f"{s['p50_us']:g} / {s['p99_us']:g} / {s['max_us']:g}" if s else "-",
                     str(a["samples"])])
    for line in table(rows, ["pair", "publish -> arrival", "publish -> snapshot (1 ms)",
                             "samples"]):
        log(line)
    log("\nbump-and-go (360-ray scan 10 Hz, odometry 50 Hz, cmd_vel 20 Hz), % of a core")
    rows = [[lang, f"{f['cpu_percent']:g}", f"{f['cpu_percent_record']:g}",
             f"{f['record_more_points']:+g}", f"{f['record_overhead_percent']:+g} %"]
            for lang, f in cpu.items()]
    for line in table(rows, ["component", "CPU", "with --record", "more", "overhead"]):
        log(line)

    targets: list[dict[str, Any]] = []
    for lang, limit in TARGET_CPU.items():
        if lang not in langs:
            continue
        v = cpu[lang]["cpu_percent"]
        targets.append({"target": f"{lang} bump-and-go CPU <= {limit:g} % of a core",
                        "value": v, "met": v <= limit})
    for lang in langs:
        v = round(snap[lang]["median_ns"] / 1e3, 3)
        targets.append({"target": f"{lang} snapshot of 10 subscriptions <= "
                                  f"{TARGET_SNAPSHOT_US:g} us", "value": v,
                        "met": v <= TARGET_SNAPSHOT_US})
    for lang in langs:
        v = cpu[lang]["record_more_points"]
        targets.append({"target": f"{lang} --record costs <= {TARGET_RECORD:g} % of a core more "
                                  f"(relative: {cpu[lang]['record_overhead_percent']:+g} % of the "
                                  "component's own CPU)", "value": v, "met": v <= TARGET_RECORD})
    for t in targets:
        log(f"  {verdict(t['met'])}: {t['target']}: {t['value']}")
    figures: dict[str, Any] = {
        "description": "ROS 2 components on loopback (Cyclone DDS): publish -> snapshot "
                       "latency against a bare cyclonedds-python pair, bump-and-go CPU fed "
                       "by a steady feeder, the snapshot of 10 subscriptions, --record",
        "quick": ns.quick, "machine": info, "hfsmc": revision, "latency": lat,
        "bump_and_go": cpu, "snapshot_10": snap}
    finish_targets(figures, targets, load_before, ns.json, KEY, log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
