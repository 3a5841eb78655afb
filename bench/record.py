#!/usr/bin/env python3
"""Cost of ``--record`` and speed of ``hfsmc replay`` (docs/recording.md), figures in
bench/README.md.

follow_colors is flown in the simulator (``hfsmc sim``, the example's world: a 320x240
camera at 15 frames a second; the component at its 20 Hz) by its Python component and by
its C++ twin (examples/follow_colors_cpp), each flight stopped by ``--time-limit`` (it
lands through on_interrupt), with and without ``--record FILE``, the two kinds of flight
interleaved (round 1: without, with; round 2: with, without; ...). Each flight has a
simulator of its own on free ports.

* **CPU of the component**: user + system time from ``wait4`` over the component's life,
  per second of its life (% of a core); the difference between the medians with and
  without recording. Target: **<= 5 % of a core**. The same over the part of the flight
  with the camera in use (from the log's ``stage 1`` line to the time limit: the frames
  are recorded there), from ``/proc/PID/stat`` sampled every 0.1 s: the worst case,
  which a longer flight approaches.
* **Size**: MB (10^6 bytes) per minute of the recording, over the whole flight, and over
  the part with the camera in use (the frames' bytes over the span they were taken, plus
  the other channels' bytes over the whole flight: what a flight that keeps following
  would write). Target: **<= 30 MB a minute** (the camera part, the larger).
* **Replay speed**: ``hfsmc replay`` of one recording of each language, in its own
  language and in the other (``--model`` the twin), and of the example's recorded flight
  (examples/follow_colors/flight.mcap, 71 s at 160x120), its wall time against the flight's
  duration (x real time). The C++ component is built once before the flights, in the
  cache ``hfsmc replay --model`` uses, and that build is timed on its own; every replay
  then runs twice, the first (Python: generating the component; C++: CMake finding it up
  to date) and the second, with everything cached, which gives the speed. Target: **>= 10x
  real time** (a 140 s flight replayed in 14 s or less), judged on the example's flight
  only: a replay has a fixed cost of 2-4 s (start-up, reading the recording, checking the
  model), which the ~30 s flights of this bench do not amortise; and every replay
  identical.

Usage::

    python bench/record.py                      # about 6 minutes (+2 the first time: C++)
    python bench/record.py --only python --rounds 1 --time-limit 20
    python bench/record.py --json bench/results.json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from report import finish_targets, hfsmc_revision, loadavg, machine, table  # bench/report.py

ROOT = Path(__file__).resolve().parent.parent
# bench/mcap.py would hide the mcap package that hfsmc.recording and this bench read with.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))
from tests.support import free_port, interrupt  # noqa: E402

KEY = "record"
WORK = ROOT / "bench" / "_work" / "record"
CACHE = WORK / "cache"  # XDG_CACHE_HOME of the builds and replays (kept between runs)
MODEL = ROOT / "examples" / "follow_colors" / "follow_colors.yaml"
TWIN = ROOT / "examples" / "follow_colors_cpp" / "follow_colors_cpp.yaml"
WORLD = ROOT / "examples" / "follow_colors" / "world.yaml"
MCAP_MESSAGE_OVERHEAD = 31  # opcode, length, channel, sequence, log and publish times


@dataclass
class Flight:
    language: str
    round: int
    record: bool
    wall_s: float  # the component's life
    cpu_s: float  # its user + system time
    load: float  # 1-minute load average when it ended
    camera_cpu_pct: float | None  # % of a core from stage 1 (camera in use) to the time limit
    recording: Path | None = None
    size: dict[str, Any] = field(default_factory=dict)

    @property
    def cpu_pct(self) -> float:
        return 100 * self.cpu_s / self.wall_s


# -- building ---------------------------------------------------------------------------------
def build_python(tmp: Path) -> list[str]:
    subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(MODEL), "-o",
                    str(tmp / "py")], check=True, capture_output=True, timeout=300)
    return [sys.executable, str(tmp / "py" / "follow_colors.py")]


def build_cpp() -> tuple[list[str], dict[str, Any]]:
    """The twin compiled where ``hfsmc replay --model TWIN`` looks for it; the build's wall
    and CPU time (its compiler processes), and whether it started from nothing."""
    from hfsmc.component import cache_folder, write_component
    from hfsmc.cppcompile import compile_component
    from hfsmc.pipeline import compile_file

    folder = cache_folder(str(TWIN), "follow_colors_cpp-cpp")
    cold = not (folder / "build" / "CMakeCache.txt").is_file()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    result = compile_file(str(TWIN))
    if result.model is None:
        raise SystemExit(f"{TWIN} does not check")
    written = write_component(result.model, "cpp", folder)
    diags = compile_component(folder, result.model.file, progress=False)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if any(d.severity == "error" for d in diags):
        raise SystemExit("the C++ component did not build:\n" +
                         "\n".join(f"{d.span}: {d.message}" for d in diags))
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return [str(written.main)], {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "cold": cold,
                                 "units_rewritten": len(written.changed)}


# -- flying -----------------------------------------------------------------------------------
def fly(command: list[str], language: str, rnd: int, record: bool, time_limit: int,
        folder: Path) -> Flight:
    """One flight: a simulator on free ports, the component up to its time limit and landing."""
    folder.mkdir(parents=True)
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    (folder / "config.yaml").write_text(json.dumps({
        "parameters": {"report": str(folder / "report.json")},
        "interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
                       "camera": {"type": "camera",
                                  "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}))
    with open(folder / "sim.log", "wb") as log:
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--world", str(WORLD),
                                "--mavlink", f"udpout:127.0.0.1:{udp}", "--camera-port",
                                str(http)], stdout=log, stderr=subprocess.STDOUT,
                               stdin=subprocess.DEVNULL)
    recording = folder / "flight.mcap" if record else None
    args = ["--config", str(folder / "config.yaml"), "--time-limit", f"{time_limit}s"]
    if recording is not None:
        args += ["--record", str(recording)]
    try:
        time.sleep(2.0)  # the simulator's camera serving
        with open(folder / "component.log", "wb") as log:
            t0 = time.monotonic()
            comp = subprocess.Popen([*command, *args], stdout=log, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, cwd=folder)
            try:
                status, usage, samples, stage1 = _watch(comp.pid, time_limit + 120,
                                                        folder / "component.log")
            except TimeoutError:
                comp.kill()
                comp.wait()
                raise SystemExit(f"the {language} flight in {folder} did not end") from None
            wall = time.monotonic() - t0
            comp.returncode = os.waitstatus_to_exitcode(status)
    finally:
        interrupt(sim, signum=signal.SIGTERM)
    if comp.returncode != 124:
        tail = (folder / "component.log").read_text("utf-8", "replace")[-2000:]
        raise SystemExit(f"the {language} flight ended with status {comp.returncode}, not 124 "
                         f"(its time limit):\n{tail}")
    f = Flight(language, rnd, record, wall, usage.ru_utime + usage.ru_stime, loadavg()[0],
               _window_cpu(samples, stage1, time_limit), recording)
    if recording is not None:
        f.size = recording_size(recording)
    return f


STAGE1 = re.compile(r"^\[\s*([0-9.]+)\] \S+: stage 1: ", re.M)
TICK = os.sysconf("SC_CLK_TCK")


def _watch(pid: int, timeout: float, log: Path) -> tuple[
        int, resource.struct_rusage, list[tuple[float, float]], tuple[float, float] | None]:
    """Wait for the component, sampling its CPU time (``/proc/PID/stat``) every 0.1 s and
    noting when its log says ``stage 1`` (the camera in use from there on): its exit status,
    rusage, the samples (monotonic time, CPU s) and (monotonic time, component time) of the
    stage 1 line."""
    deadline = time.monotonic() + timeout
    samples: list[tuple[float, float]] = []
    stage1: tuple[float, float] | None = None
    stat = Path(f"/proc/{pid}/stat")
    while True:
        now = time.monotonic()
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            samples.append((now, (int(fields[11]) + int(fields[12])) / TICK))
        except (OSError, IndexError, ValueError):
            pass
        if stage1 is None and (m := STAGE1.search(log.read_text("utf-8", "replace"))):
            stage1 = (now, float(m.group(1)))
        got, status, usage = os.wait4(pid, os.WNOHANG)
        if got == pid:
            return status, usage, samples, stage1
        if now > deadline:
            raise TimeoutError
        time.sleep(0.1)


def _window_cpu(samples: list[tuple[float, float]], stage1: tuple[float, float] | None,
                time_limit: int) -> float | None:
    """% of a core from the stage 1 line to the time limit (the camera in use)."""
    if stage1 is None or not samples:
        return None
    start, t1 = stage1
    end = start + (time_limit - t1)
    inside = [s for s in samples if start <= s[0] <= end]
    if len(inside) < 2 or inside[-1][0] - inside[0][0] < 1:
        return None
    return 100 * (inside[-1][1] - inside[0][1]) / (inside[-1][0] - inside[0][0])


def recording_size(path: Path) -> dict[str, Any]:
    """The file's size, its frames' share, and MB a minute over the flight and over the
    part with the camera in use."""
    from mcap.reader import make_reader

    total = path.stat().st_size
    frame_bytes = frames = 0
    first = last = None
    log_times: list[int] = []
    fmt: set[str] = set()
    with open(path, "rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(log_time_order=False):
            log_times.append(message.log_time)
            if channel.topic.startswith("/hfsmc/frame/"):
                frames += 1
                frame_bytes += len(message.data) + MCAP_MESSAGE_OVERHEAD
                first = message.log_time if first is None else first
                last = message.log_time
                fmt.add(str(json.loads(message.data)["format"]))
    span_s = (max(log_times) - min(log_times)) / 1e9 if log_times else 0.0
    camera_s = (last - first) / 1e9 if first is not None and last is not None else 0.0
    mb = 1e6
    per_min = total / mb / (span_s / 60) if span_s else float("nan")
    camera_per_min = ((frame_bytes / mb / (camera_s / 60) if camera_s else 0.0) +
                      ((total - frame_bytes) / mb / (span_s / 60) if span_s else 0.0))
    return {"bytes": total, "duration_s": round(span_s, 2), "frames": frames,
            "frame_format": ",".join(sorted(fmt)) or "-",
            "frame_kb": round(frame_bytes / frames / 1000, 1) if frames else 0.0,
            "frames_share": round(frame_bytes / total, 3) if total else 0.0,
            "camera_s": round(camera_s, 1), "mb_per_min": round(per_min, 2),
            "camera_mb_per_min": round(camera_per_min, 2)}


# -- replaying --------------------------------------------------------------------------------
def replay(recording: Path, model: Path | None, label: str, duration_s: float) -> dict[str, Any]:
    """``hfsmc replay`` twice; the wall and CPU time of each, and what it said."""
    args = [sys.executable, "-m", "hfsmc", "replay", recording.name]
    if model is not None:
        args += ["--model", str(model)]
    env = {**os.environ, "XDG_CACHE_HOME": str(CACHE)}
    runs: list[dict[str, Any]] = []
    for _ in range(2):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.monotonic()
        r = subprocess.run(args, cwd=recording.parent, capture_output=True, text=True,
                           timeout=900, env=env, stdin=subprocess.DEVNULL)
        wall = time.monotonic() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        last = (r.stdout.strip().splitlines() or [""])[-1]
        runs.append({"wall_s": round(wall, 2),
                     "cpu_s": round((after.ru_utime + after.ru_stime) -
                                    (before.ru_utime + before.ru_stime), 2),
                     "status": r.returncode, "said": last or r.stderr.strip()[-300:]})
    warm = runs[-1]
    return {"replay": label, "flight_s": round(duration_s, 1), "runs": runs,
            "identical": all(x["status"] == 0 and ": identical" in x["said"] for x in runs),
            "x_real_time": round(duration_s / warm["wall_s"], 1)}


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}"


def _median(xs: list[float | None]) -> float | None:
    got = [x for x in xs if x is not None]
    return round(statistics.median(got), 2) if got else None


# -- main -------------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", choices=("python", "cpp"), help="one language only")
    ap.add_argument("--rounds", type=int, default=2, help="flights with and without, each")
    ap.add_argument("--time-limit", type=int, default=20, metavar="S",
                    help="the flights' --time-limit in seconds (then ~10 s of landing)")
    ap.add_argument("--json", type=Path, help=f'merge the figures into this file under "{KEY}"')
    ns = ap.parse_args(argv)
    languages = [ns.only] if ns.only else ["python", "cpp"]
    load_before = loadavg()
    figures: dict[str, Any] = {"machine": machine(), "hfsmc": hfsmc_revision(),
                               "time_limit_s": ns.time_limit, "rounds": ns.rounds}
    m = figures["machine"]
    rev = figures["hfsmc"]
    print(f"machine: {m['cpu']}, {m['cores']} cores, {m['memory_gib']} GiB, Python {m['python']}"
          f"; hfsmc {rev.get('commit')}{' (sources edited)' if rev.get('dirty') else ''}; "
          f"load average {load_before} (a shared machine: CPU times are the steadier figures)")
    WORK.mkdir(parents=True, exist_ok=True)
    os.environ["XDG_CACHE_HOME"] = str(CACHE)
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory(dir=WORK) as d:
        tmp = Path(d)
        commands: dict[str, list[str]] = {}
        if "python" in languages:
            commands["python"] = build_python(tmp)
        if "cpp" in languages:
            if shutil.which("cmake") is None:
                print("bench/record.py: cmake is not installed (`make deps`)", file=sys.stderr)
                return 1
            commands["cpp"], figures["cpp_build"] = build_cpp()
            b = figures["cpp_build"]
            print(f"C++ twin built in {b['wall_s']} s ({b['cpu_s']} s of compilers' CPU; "
                  f"{'from nothing' if b['cold'] else 'its build folder was there'}), "
                  "kept out of the replay times")
        flights: list[Flight] = []
        for rnd in range(ns.rounds):
            for lang in languages:
                for record in ((False, True) if rnd % 2 == 0 else (True, False)):
                    f = fly(commands[lang], lang, rnd + 1, record, ns.time_limit,
                            tmp / f"{lang}-{rnd + 1}-{'rec' if record else 'plain'}")
                    flights.append(f)
                    print(f"  {lang} round {rnd + 1} {'--record' if record else 'no record'}: "
                          f"{f.wall_s:.1f} s, {f.cpu_pct:.1f} % of a core (load {f.load})",
                          flush=True)
        rows = []
        for f in flights:
            s = f.size
            rows.append([f.language, str(f.round), "yes" if f.record else "no", f"{f.wall_s:.1f}",
                         f"{f.cpu_s:.2f}", f"{f.cpu_pct:.2f}", _pct(f.camera_cpu_pct), f"{f.load}",
                         f"{s['bytes'] / 1e6:.1f}" if s else "", str(s.get("frames", "")),
                         s.get("frame_format", ""), str(s.get("frame_kb", "")),
                         str(s.get("mb_per_min", "")), str(s.get("camera_mb_per_min", ""))])
        print(f"\nflights (follow_colors, 320x240 camera at 15 fps, component at 20 Hz, "
              f"--time-limit {ns.time_limit}s then landing)")
        for line in table(rows, ["language", "round", "record", "life s", "CPU s", "% core",
                                 "camera % core", "load", "MB", "frames", "format", "kB/frame", "MB/min",
                                 "camera MB/min"]):
            print(line)
        summary: dict[str, Any] = {}
        targets: list[dict[str, Any]] = []
        for lang in languages:
            plain = statistics.median(f.cpu_pct for f in flights
                                      if f.language == lang and not f.record)
            rec = [f for f in flights if f.language == lang and f.record]
            recorded = statistics.median(f.cpu_pct for f in rec)
            per_min = max(f.size["camera_mb_per_min"] for f in rec)
            cam_plain = _median([f.camera_cpu_pct for f in flights
                                 if f.language == lang and not f.record])
            cam_rec = _median([f.camera_cpu_pct for f in rec])
            summary[lang] = {"cpu_pct_without": round(plain, 2), "cpu_pct_with": round(recorded, 2),
                             "overhead_pct_of_a_core": round(recorded - plain, 2),
                             "camera_cpu_pct_without": cam_plain, "camera_cpu_pct_with": cam_rec,
                             "mb_per_min": max(f.size["mb_per_min"] for f in rec),
                             "camera_mb_per_min": per_min,
                             "frame_format": rec[0].size["frame_format"]}
            targets.append({"target": f"{lang}: recording's extra CPU <= 5 % of a core",
                            "value": f"{recorded - plain:+.2f} % ({plain:.2f} -> {recorded:.2f} %)",
                            "met": recorded - plain <= 5})
            if cam_plain is not None and cam_rec is not None:
                targets.append({"target": f"{lang}: the same, camera in use (stage 1 to the "
                                          "time limit)",
                                "value": f"{cam_rec - cam_plain:+.2f} % ({cam_plain:.2f} -> "
                                         f"{cam_rec:.2f} %)",
                                "met": cam_rec - cam_plain <= 5})
            targets.append({"target": f"{lang}: recording <= 30 MB a minute (camera in use)",
                            "value": f"{per_min:.1f} MB/min "
                                     f"({rec[0].size['frame_format']} frames)",
                            "met": per_min <= 30})
        figures["flights"] = [{"language": f.language, "round": f.round, "record": f.record,
                               "life_s": round(f.wall_s, 2), "cpu_s": round(f.cpu_s, 3),
                               "cpu_pct": round(f.cpu_pct, 2), "camera_cpu_pct":
                                   None if f.camera_cpu_pct is None else round(f.camera_cpu_pct, 2),
                               "load": f.load, **f.size}
                              for f in flights]
        figures["summary"] = summary

        # One recording of each language (the first made), in its language and the other.
        from hfsmc.recording import read_recording

        replays = []
        for lang in languages:
            f = next(x for x in flights if x.language == lang and x.record)
            assert f.recording is not None
            duration = read_recording(str(f.recording)).end_us / 1e6
            if lang == "python":
                replays.append(replay(f.recording, None, "python -> python", duration))
                if "cpp" in languages:
                    replays.append(replay(f.recording, TWIN, "python -> cpp", duration))
            else:
                replays.append(replay(f.recording, TWIN, "cpp -> cpp", duration))
                replays.append(replay(f.recording, MODEL, "cpp -> python", duration))
        # The example's recorded flight (scripts/record_example.sh: 160x120 at 5 frames a
        # second, a 60 s time limit): a longer flight, so the replay's fixed costs weigh less.
        example = tmp / "example" / "flight.mcap"
        example.parent.mkdir()
        shutil.copyfile(ROOT / "examples" / "follow_colors" / "flight.mcap", example)
        duration = read_recording(str(example)).end_us / 1e6
        replays.append(replay(example, None, "example: python -> python", duration))
        if "cpp" in languages:
            replays.append(replay(example, TWIN, "example: python -> cpp", duration))
        figures["replays"] = replays
        rows = [[r["replay"], f"{r['flight_s']}", f"{r['runs'][0]['wall_s']}",
                 f"{r['runs'][1]['wall_s']}", f"{r['runs'][1]['cpu_s']}", f"{r['x_real_time']}",
                 "identical" if r["identical"] else "NOT identical"] for r in replays]
        print("\nreplays (each twice: the second with everything cached gives the speed)")
        for line in table(rows, ["replay", "flight s", "1st s", "2nd s", "2nd CPU s",
                                 "x real time", "result"]):
            print(line)
        for r in replays:
            if not r["identical"]:
                print(f"  {r['replay']}: {r['runs'][-1]['said']}")
            if r["replay"].startswith("example"):  # the short flights: fixed costs dominate
                targets.append({"target": f"replay {r['replay']} >= 10x real time",
                                "value": f"{r['x_real_time']}x ({r['flight_s']} s flight in "
                                         f"{r['runs'][1]['wall_s']} s)",
                                "met": r["x_real_time"] >= 10})
            targets.append({"target": f"replay {r['replay']} identical",
                            "value": "identical" if r["identical"] else r["runs"][-1]["said"],
                            "met": r["identical"]})
    figures["bench_s"] = round(time.monotonic() - t_start, 1)
    print(f"\nthe bench took {figures['bench_s']} s")
    finish_targets(figures, targets, load_before, ns.json, KEY, print)
    return 0


if __name__ == "__main__":
    sys.exit(main())
