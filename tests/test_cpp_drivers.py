"""The C++ drivers of the mavlink and camera interfaces (templates/cpp/hfsmc), on
loopback against the simulator, and the MAVLink C headers mavgen makes for them.

tests/cpp/drivers_main.cpp is built once per session with g++ (-Wall -Wextra
-Werror, AddressSanitizer and UBSan), with the drivers' sources (templates/cpp/
hfsmc_mavlink.cpp, hfsmc_camera.cpp, hfsmc_record.cpp), against the headers of
hfsmc.emit.mavgen.mavlink_headers(), Eigen and OpenCV; each test runs one of
its scenarios beside a fresh `hfsmc sim`. A missing tool fails the tests."""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import os
import queue
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any, ClassVar

import numpy as np
import pytest
from pymavlink import mavutil

from hfsmc.emit.cpp import INTERFACE_SOURCES
from hfsmc.emit.mavgen import mavlink_headers
from tests.conftest import ROOT
from tests.support import close_pipes, free_port, simulator

MAV = mavutil.mavlink
# 180 s a test, and the first one also waits for the session's build of drivers_main (600 s at
# most: one g++ with the sanitizers took over 180 s on a loaded 2-core machine).
pytestmark = pytest.mark.timeout(180 + 600)

FLAGS = ["-std=c++17", "-Wall", "-Wextra", "-Werror", "-I/usr/include/eigen3"]
SANITIZE = ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined",
            "-fno-omit-frame-pointer"]
SAN_ENV = {"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0",
           "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1"}


def mavutil_version() -> str:
    return importlib.metadata.version("pymavlink")


def tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        pytest.fail(f"{name} is needed to test the C++ drivers (Debian: g++, pkg-config, "
                    "libopencv-dev, libeigen3-dev)")
    return path


def opencv_flags() -> list[str]:
    r = subprocess.run([tool("pkg-config"), "--cflags", "--libs", "opencv4"],
                       capture_output=True, text=True, timeout=30)
    if r.returncode != 0:
        pytest.fail(f"pkg-config finds no opencv4 (libopencv-dev): {r.stderr}")
    return r.stdout.split()


def library_sources(*kinds: str) -> list[str]:
    """The runtime's sources a program using the drivers of ``kinds`` compiles with (a
    component builds them into its libraries): JSON, --record and --playback, then the
    drivers."""
    names = ["hfsmc_json.cpp", "hfsmc_record.cpp", *(n for k in kinds for n in INTERFACE_SOURCES[k])]
    return [str(ROOT / "templates/cpp" / n) for n in names]


def write_include(root: Path) -> Path:
    """A component's include/ folder: mavgen's headers and templates/cpp."""
    for key, data in mavlink_headers().items():
        path = root / key
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    include = root / "include"
    shutil.copytree(ROOT / "templates/cpp/hfsmc", include / "hfsmc")
    if not (Path("/usr/include/eigen3/Eigen/Core")).is_file():
        pytest.fail("Eigen is needed (Debian: libeigen3-dev)")
    return include


@pytest.fixture(scope="session")
def include(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_include(tmp_path_factory.mktemp("cpp"))


@pytest.fixture(scope="session")
def drivers(include: Path) -> Path:
    """tests/cpp/drivers_main.cpp, built with the sanitizers."""
    exe = include.parent / "drivers_main"
    r = subprocess.run([tool("g++"), *FLAGS, *SANITIZE, f"-I{include}",
                        str(ROOT / "tests/cpp/drivers_main.cpp"),
                        *library_sources("mavlink", "camera"), "-o", str(exe),
                        *opencv_flags()], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""  # not even a note
    return exe


class Scenario:
    """drivers_main SCENARIO ARG running: stdout read line by line (bounded
    waits), stderr in a file, sanitizers on."""

    def __init__(self, exe: Path, scenario: str, arg: str, tmp: Path) -> None:
        self.err_path = tmp / f"{scenario}.err"
        with self.err_path.open("w") as err:
            self.proc = subprocess.Popen([str(exe), scenario, arg], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=err, text=True,
                                         env={**os.environ, **SAN_ENV})
        self.out: list[str] = []
        self.lines: queue.Queue[str | None] = queue.Queue()
        assert self.proc.stdout is not None
        self._reader = threading.Thread(target=self._read, args=(self.proc.stdout,), daemon=True)
        self._reader.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self.lines.put(line.rstrip("\n"))
        self.lines.put(None)

    def expect(self, prompt: str, timeout: float) -> None:
        """Wait for a line; fail with what was said if it does not come."""
        end = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, end - time.monotonic()))
            except queue.Empty:
                pytest.fail(f"no `{prompt}` in {timeout} s: {self.out}")
            if line is None:
                pytest.fail(f"ended before `{prompt}`: {self.out}\n{self.stderr()}")
            self.out.append(line)
            if line == prompt:
                return

    def go(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write("go\n")
        self.proc.stdin.flush()

    def finish(self, timeout: float) -> int:
        try:
            rc = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            rc = -9
        self._reader.join(timeout=5)
        while (line := self.lines.get_nowait() if not self.lines.empty() else None) is not None:
            self.out.append(line)
        return rc

    def stderr(self) -> str:
        return self.err_path.read_text()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        close_pipes(self.proc, self._reader)


@contextlib.contextmanager
def scenario(exe: Path, name: str, arg: str, tmp: Path) -> Iterator[Scenario]:
    s = Scenario(exe, name, arg, tmp)
    try:
        yield s
    finally:
        s.close()


def passed(s: Scenario, timeout: float) -> str:
    """Wait for the scenario's end; its stderr, after checking it passed cleanly."""
    rc = s.finish(timeout)
    err = s.stderr()
    assert rc == 0, "\n".join(s.out) + "\n" + err
    assert not any(line.startswith("FAIL") for line in s.out)
    assert "Sanitizer" not in err and "runtime error" not in err, err
    return err


# -- the MAVLink C headers ----------------------------------------------------------------
def _digest(headers: dict[str, bytes]) -> str:
    h = hashlib.sha256()
    for key in sorted(headers):
        h.update(key.encode() + b"\0" + headers[key] + b"\0")
    return h.hexdigest()


DIGEST = """\
import hashlib
from hfsmc.emit.cpp import INTERFACE_SOURCES
from hfsmc.emit.mavgen import mavlink_headers
headers = mavlink_headers()
h = hashlib.sha256()
for key in sorted(headers):
    h.update(key.encode() + b"\\0" + headers[key] + b"\\0")
print(h.hexdigest())
"""


def test_mavlink_headers_are_the_dialect_and_its_includes_only() -> None:
    headers = mavlink_headers()
    assert all(key.startswith("include/mavlink/") for key in headers)
    assert "include/mavlink/ardupilotmega/mavlink.h" in headers
    assert "include/mavlink/common/mavlink_msg_command_long.h" in headers
    assert "include/mavlink/minimal/mavlink_msg_heartbeat.h" in headers
    assert not any(key.endswith("testsuite.h") for key in headers)  # not reached by an include
    for key, data in headers.items():  # every quoted include is there: the set is closed
        folder = Path(key).parent
        for name in re.findall(rb'#\s*include\s+"([^"]+)"', data):
            if name != b"string.h":  # the C library's, quoted by mavgen
                assert os.path.normpath(folder / name.decode()) in headers, (key, name)
    stamps = re.findall(rb'#define MAVLINK_BUILD_DATE "([^"]*)"',
                        headers["include/mavlink/ardupilotmega/version.h"])
    assert stamps == [b"pymavlink " + mavutil_version().encode()]
    assert not any(re.search(rb'MAVLINK_BUILD_DATE "[A-Z][a-z]{2} [A-Z][a-z]{2} \d\d \d{4}"', d)
                   for d in headers.values())


def test_mavlink_headers_are_the_same_bytes_in_every_process() -> None:
    first = mavlink_headers()
    first["include/mavlink/ardupilotmega/mavlink.h"] = b"changed"  # a copy: the cache keeps its own
    assert mavlink_headers()["include/mavlink/ardupilotmega/mavlink.h"] != b"changed"
    here = _digest(mavlink_headers())
    digests = set()
    for seed in ("1", "2"):  # hash randomisation differs between the two
        r = subprocess.run([sys.executable, "-c", DIGEST], cwd=ROOT, capture_output=True,
                           text=True, timeout=120, env={**os.environ, "PYTHONHASHSEED": seed})
        assert r.returncode == 0, r.stderr
        assert r.stderr == "" and r.stdout.count("\n") == 1  # mavgen's chatter kept quiet
        digests.add(r.stdout.strip())
    assert digests == {here}


def test_headers_compile_clean_with_I_and_isystem(include: Path, tmp_path: Path) -> None:
    main = tmp_path / "both.cpp"
    main.write_text('#include "hfsmc/mavlink.hpp"\n#include "hfsmc/camera.hpp"\n'
                    "int main() { return 0; }\n")
    cflags = [f for f in opencv_flags() if f.startswith("-I")]
    for how in ("-I", "-isystem"):
        for unit in (str(main), *library_sources("mavlink", "camera")):
            r = subprocess.run([tool("g++"), *FLAGS, "-Wpedantic", how, str(include), *cflags,
                                "-fsyntax-only", unit], capture_output=True, text=True,
                               timeout=120)
            assert r.returncode == 0 and r.stderr == "", (how, unit, r.stderr)


def test_the_driver_base_records_typed_fields_as_the_python_base(include: Path,
                                                                 tmp_path: Path) -> None:
    """hfsmc/driver.hpp's typed fields (Numbers, Wholes, Texts: the mavlink driver's
    vectors, mission and acks) give the JSON and the schema the Python base gives the same
    SNAPSHOT; stop_warning() is what warning_at_stop() says; the base is a Synced."""
    import importlib
    import json

    exe = tmp_path / "typed_fields"
    r = subprocess.run([tool("g++"), *FLAGS, f"-I{include}", str(ROOT / "tests/cpp/typed_fields_main.cpp"),
                        *library_sources(), "-o", str(exe)], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    out = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True).stdout
    lines = dict(line.split(" ", 1) for line in out.splitlines())
    assert json.loads(lines["fields"]) == {"at": [1.5, "nan", -2.0], "span": [3, 7],
                                           "acks": {"grip": "accepted", "home": "pending"},
                                           "busy": True}
    assert lines["fields"] == ('{"at":[1.5,"nan",-2.0],"span":[3,7],'
                               '"acks":{"grip":"accepted","home":"pending"},"busy":true}')
    base = importlib.import_module("hfsmc.templates.python.hfsmc_driver")

    class Arm(base.Driver):  # type: ignore[misc, name-defined]
        KIND = "arm"
        SNAPSHOT: ClassVar[dict[str, Any]] = {"at": (1.5, float("nan"), -2.0), "span": (3, 7),
                                              "acks": {}, "busy": True}

    assert lines["schema"] == json.dumps(Arm.snapshot_schema())
    assert lines["warning"] == "still gripping"
    assert lines["lockstep"] == "0"


# -- the drivers ----------------------------------------------------------------------------
def test_offline_answers_at_once_and_threads_leave_signals_alone(drivers: Path,
                                                                 tmp_path: Path) -> None:
    with scenario(drivers, "offline", str(free_port(socket.SOCK_DGRAM)), tmp_path) as s:
        err = passed(s, 30)
    assert any(line.startswith("ok: close is prompt") for line in s.out)
    said = err.splitlines()  # the grabber's line comes when it comes
    assert [line for line in said if line.startswith("drone:")] == [
        "drone: option rate: `fast` is not a positive number, 20 used",
        "drone: unknown option `colour` ignored (options: rate, ack_timeout, source_system, autopilot)",
        "drone: arm: not sent, no vehicle yet (no heartbeat)"]
    assert [line for line in said if not line.startswith("drone:")] == [
        "camera: option size: `big` is not WxH (320x240): frames kept as they come",
        "camera: stream not available at 63: reconnecting"]


def test_a_taken_port_is_said_and_exits_1(drivers: Path, tmp_path: Path) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", 0))
        port = held.getsockname()[1]
        with scenario(drivers, "taken", str(port), tmp_path) as s:
            rc = s.finish(20)
    assert rc == 1 and s.out == []
    assert s.stderr().startswith(f"drone: cannot open udpin:127.0.0.1:{port}: Address already in use")


def test_flight_in_the_simulator(drivers: Path, tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    with simulator(tmp_path, port, "--no-camera"), \
            scenario(drivers, "flight", str(port), tmp_path) as s:
        err = passed(s, 90)
    texts = [line for line in err.splitlines() if line.startswith("drone: ArduPilot: ")]
    assert texts[:1] == ["drone: ArduPilot: Arm: Mode STABILIZE not armable"], err  # STATUSTEXT
    said = [line for line in err.splitlines() if line not in texts]
    assert said[0] == f"drone: vehicle 1/1 on udpin:127.0.0.1:{port}, mode STABILIZE", said
    assert said[1] in ("drone: arm FAILED", "drone: arm DENIED"), said
    assert said[2:] == ["drone: set_mode GUIDED accepted", "drone: arm accepted",
                        "drone: takeoff accepted", "drone: land accepted"]
    sim_log = (tmp_path / "sim.log").read_text()
    assert "take-off to 3.0 m" in sim_log and "disarmed (landed)" in sim_log


def test_link_loss_is_seen_and_the_link_comes_back(drivers: Path, tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    with simulator(tmp_path, port, "--no-camera", "--drop-link-after", "3",
                   "--drop-link-for", "4"), \
            scenario(drivers, "linkloss", str(port), tmp_path) as s:
        err = passed(s, 60)
    assert [line for line in err.splitlines() if "vehicle 1/1" not in line] == [
        "drone: link lost: no heartbeat for 2 s", "drone: link back"]


def test_px4_in_the_simulator(drivers: Path, tmp_path: Path) -> None:
    """The C++ driver on `hfsmc sim --autopilot px4`, as the Python one in tests/test_px4.py."""
    port = free_port(socket.SOCK_DGRAM)
    with simulator(tmp_path, port, "--no-camera", "--autopilot", "px4", "--source-port", "0",
                   "--boot-time", "4") as sim, \
            scenario(drivers, "px4", str(port), tmp_path) as s:
        s.expect("drop the link", 60)
        sim.send_signal(signal.SIGUSR1)  # the link drops: no setpoint reaches PX4
        time.sleep(3.0)
        sim.send_signal(signal.SIGUSR1)
        s.go()
        err = passed(s, 60)
    said = err.splitlines()
    assert said[0] == f"drone: PX4 vehicle 1/1 on udpin:127.0.0.1:{port}, mode HOLD", said
    for line in ("drone: arm TEMPORARILY_REJECTED",
                 "drone: PX4: Arming denied: Resolve system health failures first",  # two chunks
                 "drone: PX4: GUIDED on the ground is Hold; targets switch to OFFBOARD in flight",
                 "drone: set_mode GUIDED accepted", "drone: takeoff accepted",
                 "drone: set_mode PRECLAND accepted",
                 "drone: set_mode PRECLAND DENIED (second answer)",
                 "drone: PX4: keeping a setpoint stream at 10 Hz (OFFBOARD needs one)",
                 "drone: PX4: setpoints streaming: switching to OFFBOARD",
                 "drone: set_mode GUIDED (OFFBOARD) accepted",
                 "drone: PX4 left OFFBOARD for POSCTL (a failsafe or a pilot): the driver stops "
                 "its stream; set_mode(\"GUIDED\") takes the vehicle back",
                 "drone: land accepted"):
        assert line in said, (line, said)
    assert said.count("drone: set_mode GUIDED (OFFBOARD) accepted") == 1, said  # never fought


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mission_api_in_the_simulator(drivers: Path, tmp_path: Path, autopilot: str) -> None:
    """The C++ mission API on both autopilots, as the Python one in tests/test_mission_api.py."""
    from hfsmc.sim.telemetry import latlon
    from hfsmc.sim.world import World
    lat, lon = (x / 1e7 for x in latlon(World().home, 12.0, 9.0))
    port = free_port(socket.SOCK_DGRAM)
    extra = ("--autopilot", "px4", "--source-port", "0") if autopilot == "px4" else ()
    with simulator(tmp_path, port, "--no-camera", "--boot-time", "4", *extra), \
            scenario(drivers, f"mission:{lat!r},{lon!r}", str(port), tmp_path) as s:
        err = passed(s, 200)
    name = "RTL_RETURN_ALT set to 12" if autopilot == "px4" else "RTL_ALT set to 1200"
    assert f"drone: rtl: {name}" in err.splitlines(), err


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mission_upload_in_the_simulator(drivers: Path, tmp_path: Path, autopilot: str) -> None:
    """The C++ mission upload, AUTO and progress on both autopilots, as the Python one in
    tests/test_mission_upload.py."""
    port = free_port(socket.SOCK_DGRAM)
    extra = ("--autopilot", "px4", "--source-port", "0") if autopilot == "px4" else ()
    with simulator(tmp_path, port, "--no-camera", "--boot-time", "2", *extra), \
            scenario(drivers, "upload", str(port), tmp_path) as s:
        err = passed(s, 240)
    said = err.splitlines()
    assert "drone: upload_mission NO_SPACE" in said, err
    assert any(line.startswith("drone: upload_mission accepted") for line in said), err


def test_garbage_datagrams_do_not_break_the_reader(drivers: Path, tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    rng = np.random.default_rng(7)
    good = MAV.MAVLink_heartbeat_message(2, 3, 0, 0, 0, 3).pack(MAV.MAVLink(None, 1, 1))
    bad_crc = good[:-1] + bytes([good[-1] ^ 0xFF])
    junk = [b"", b"\xfe", b"\xfd\x00\x00", b"\xfd\xff" + bytes(8), good[:5], bad_crc,
            b"hello\n" * 100, bytes(60000),
            *(rng.integers(0, 256, n, dtype=np.uint8).tobytes()
              for n in (1, 7, 17, 280, 1500, 9000))]
    with simulator(tmp_path, port, "--no-camera"), \
            scenario(drivers, "garbage", str(port), tmp_path) as s:
        s.expect("send junk", 30)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for _ in range(20):
                for datagram in junk:
                    sock.sendto(datagram, ("127.0.0.1", port))
        s.go()
        err = passed(s, 30)
    ours = [ln for ln in err.splitlines()[1:] if not ln.startswith("drone: ArduPilot: ")]
    assert ours in (["drone: arm FAILED"], ["drone: arm DENIED"]), err  # the autopilot's texts aside


def test_camera_frames_and_recovery_after_a_drop(drivers: Path, tmp_path: Path) -> None:
    port, camera_port = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    url = f"http://127.0.0.1:{camera_port}/bottom.mjpg"
    with simulator(tmp_path, port, "--camera-port", str(camera_port)) as sim, \
            scenario(drivers, "camera", url, tmp_path) as s:
        s.expect("pause the camera", 40)
        sim.send_signal(signal.SIGUSR2)
        s.go()
        s.expect("resume the camera", 20)
        sim.send_signal(signal.SIGUSR2)
        s.go()
        err = passed(s, 30)
    assert [line for line in err.splitlines() if line.startswith(("camera:", "small:"))] == [
        f"camera: stream lost at {url}: reconnecting", f"camera: stream back at {url}"], err
    sim_log = (tmp_path / "sim.log").read_text()
    assert "camera paused (SIGUSR2)" in sim_log and "camera resumed (SIGUSR2)" in sim_log
