"""`hfsmc sim`: run the simulated multicopter, its MAVLink link and its camera.

The vehicle is reached as ArduPilot SITL is: it sends from its own UDP socket to
127.0.0.1:14550 (``udpout``) and reads the replies that come back to that
socket, so a component or MAVProxy listens with ``udpin:127.0.0.1:14550``.
It obeys its peer only (docs/worlds.md, "The MAVLink link"): with ``udpout`` the
address it sends to, with ``udpin`` the first address that writes to it (another
one may take over once that one has been silent for PEER_QUIET_S); datagrams
from any other address are dropped, counted, and said once per address.

The physics runs at a fixed step driven by the monotonic clock with absolute
deadlines; simulated time is steps * dt, so timestamps, telemetry instants and
sensor noise depend only on the seed and on the step at which commands arrive.

Faults for tests: ``--drop-link-after S --drop-link-for S`` and SIGUSR1 (toggle)
silence the link both ways; SIGUSR2 pauses and resumes the camera. SIGINT and
SIGTERM stop cleanly (truth written, sockets closed, exit 0).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib
import json
import math
import signal
import socket
import sys
import time
from collections.abc import Callable, Iterator
from types import FrameType
from typing import IO, Any

from hfsmc.fsutil import write_atomic
from hfsmc.sim import lockstep
from hfsmc.sim.autopilot import Autopilot
from hfsmc.sim.options import OutputError, open_outputs
from hfsmc.sim.options import fail as _fail
from hfsmc.sim.options import seconds as _seconds
from hfsmc.sim.options import speedup as _speedup
from hfsmc.sim.px4 import SOURCE_PORT, Px4
from hfsmc.sim.telemetry import latlon
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import WORLD_CLOCKS, World, WorldClock, WorldError, load_world

DEFAULT_MAVLINK = "udpout:127.0.0.1:14550"
MAX_DATAGRAMS = 500  # per step: a flood must not starve the physics
PEER_QUIET_S = 5.0  # udpin: a peer silent this long (while the link is up) may be replaced
STRANGERS_SAID = 16  # addresses whose ignored datagrams are said; later ones are only counted
TRUTH_LOG_S = 0.5  # s of simulated time between two lines of --truth-log
AUTOPILOTS: dict[str, type[Autopilot]] = {"ardupilot": Autopilot, "px4": Px4}
BOOT_TIMES = {"ardupilot": 3.0, "px4": 4.5}  # s: ArduPilot's short for tests; PX4's measured


def parse_url(url: str) -> tuple[str, str, int]:
    """``udpout:HOST:PORT`` or ``udpin:HOST:PORT`` (``udp:`` is udpin, as in mavutil)."""
    kind, _, rest = url.partition(":")
    kind = "udpin" if kind == "udp" else kind
    host, _, port = rest.rpartition(":")
    if kind not in ("udpin", "udpout") or not host or not port.isdigit() \
            or not 0 <= int(port) <= 65535 or (kind == "udpout" and int(port) == 0):
        raise ValueError(f"--mavlink {url!r}: expected udpout:HOST:PORT or udpin:HOST:PORT")
    return kind, host, int(port)


class Link:
    """The vehicle's UDP socket. Down, it sends nothing and drops what arrives. It takes
    datagrams from its peer only; ``ignored`` counts the others, ``log`` says whose."""

    def __init__(self, url: str, log: Callable[[str], None] | None = None,
                 source_port: int | None = None) -> None:
        self.kind, host, port = parse_url(url)
        self.log = log if log is not None else _stderr
        self.ignored = 0
        self._strangers: set[tuple[str, int]] = set()
        self._heard = 0.0  # when the peer was last heard (monotonic), or the link came up
        self._up = True
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.peer: tuple[str, int] | None = None
        try:
            if self.kind == "udpin":
                self.sock.bind((host, port))
            else:
                self.peer = (socket.gethostbyname(host), port)
                if source_port is not None:  # PX4 SITL sends from a known port (18570)
                    self.sock.bind(("127.0.0.1" if self.peer[0].startswith("127.") else "",
                                    source_port))
        except OSError:
            self.sock.close()
            raise
        self.sent = 0  # datagrams sent (the lockstep's count, docs/worlds.md)
        self.received = 0  # the peer's datagrams read, kept or dropped (a link down drops them)

    @property
    def up(self) -> bool:
        return self._up

    @up.setter
    def up(self, on: bool) -> None:
        if on and not self._up:  # the peer's silence while the link was down does not count
            self._heard = time.monotonic()
        self._up = on

    def describe(self) -> str:
        if self.kind == "udpout" and self.peer is not None:
            src = self.sock.getsockname()[1] if self.sock.getsockname()[1] else None
            return f"MAVLink to udp:{self.peer[0]}:{self.peer[1]}" + (
                f" from port {src}" if src else "")
        host, port = self.sock.getsockname()
        return f"MAVLink on udpin:{host}:{port} (obeys the first address that writes to it)"

    def send(self, data: bytes) -> None:
        if self.up and self.peer is not None:
            with contextlib.suppress(OSError):  # nobody listening yet, a full buffer: lost
                self.sock.sendto(data, self.peer)
                self.sent += 1

    def receive(self) -> list[bytes]:
        out: list[bytes] = []
        for _ in range(MAX_DATAGRAMS):
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                continue  # an ICMP error reported on the socket: try the next datagram
            mine = self._from_peer(addr) if self.up else addr == self.peer
            if mine:
                self.received += 1
            if self.up and mine:
                out.append(data)
        return out

    def _from_peer(self, addr: tuple[str, int]) -> bool:
        """Whether a datagram from ``addr`` is the peer's (udpin: the first one to write, or
        one that writes after the peer has been silent for PEER_QUIET_S)."""
        now = time.monotonic()
        if addr != self.peer and self.kind == "udpin" and \
                (self.peer is None or now - self._heard > PEER_QUIET_S):
            if self.peer is not None:
                self.log(f"MAVLink peer is now {addr[0]}:{addr[1]} ({self.peer[0]}:"
                         f"{self.peer[1]} silent for {PEER_QUIET_S:g} s)")
            self.peer = addr
        if addr == self.peer:
            self._heard = now
            return True
        self.ignored += 1
        if addr not in self._strangers and len(self._strangers) < STRANGERS_SAID:
            self._strangers.add(addr)
            peer = f"{self.peer[0]}:{self.peer[1]}" if self.peer else "none"
            self.log(f"ignoring MAVLink from {addr[0]}:{addr[1]}: the vehicle obeys its peer "
                     f"{peer} only")
        return False

    def close(self) -> None:
        self.sock.close()


class Simulator:
    """The loop: link → autopilot → physics → telemetry, one fixed step at a time."""

    def __init__(self, world: World, link: Link, *, boot_time: float = 3.0,
                 truth: str | None = None, drop_after: float | None = None,
                 drop_for: float = 5.0, params: dict[str, float] | None = None,
                 world_clock: str = "armed", truth_log: IO[str] | None = None,
                 autopilot: str = "ardupilot") -> None:
        self.world = world
        self.link = link
        self.truth_path = truth
        self.truth_log = truth_log
        self._logged_step = -1
        self.drop = None if drop_after is None else (drop_after, drop_after + drop_for)
        self.body = Body(world.vehicle, world.seed)
        link.log = self.log
        self.ap = AUTOPILOTS[autopilot](world, self.body, link.send, boot_time=boot_time,
                                        log=self.log)
        self.ap.set_params(params or {})
        self.clock = WorldClock(world_clock)
        self.pose = self.body.pose
        self.camera: Any = None
        self.stopping = False
        self._link_toggles = 0  # SIGUSR1 count (handled in the loop, not in the handler)
        self._camera_toggles = 0
        self._camera_paused = False
        self._link_forced_down = False
        self._in_window = False
        self._truth_failed = False

    def log(self, text: str) -> None:
        print(f"sim: [{self.body.t:7.2f} s] {text}", file=sys.stderr, flush=True)

    def run(self, duration: float | None = None) -> None:
        """Fly until stopped (a signal) or until ``duration`` simulated seconds."""
        dt = self.body.dt
        start = time.monotonic() - self.body.t  # real time goes on from where lockstep left
        while not self.stopping:
            self._faults()
            for data in self.link.receive():
                self.ap.receive(data)
            if self.advance(duration):
                break
            late = time.monotonic() - (start + self.body.steps * dt)
            if late < 0:
                time.sleep(-late)
            elif late > 0.5:  # stalled (suspended, overloaded): go on from now, no burst
                start += late

    def advance(self, duration: float | None = None) -> bool:
        """One physics step and what follows it (the world's clock, the pose, the truth each
        second, its log each half second); True when ``duration`` is reached."""
        self.ap.step()
        b = self.body
        if self.clock.update(b.t, b.armed, b.altitude):
            self.log(f"the world's clock starts (vehicle {self.clock.start})")
        self.pose = (self.clock.time(b.t), b.north, b.east, b.down, b.yaw)
        if self.truth_path and b.steps % round(1.0 / b.dt) == 0:
            self.write_truth()
        if self.truth_log is not None and b.steps % round(TRUTH_LOG_S / b.dt) == 0:
            self.log_truth()
        return duration is not None and b.t >= duration - 1e-9

    def _faults(self) -> None:
        forced = self._link_toggles % 2 == 1
        if forced != self._link_forced_down:
            self._link_forced_down = forced
            self.log(f"link {'dropped' if forced else 'restored'} (SIGUSR1)")
        t = self.body.t
        in_window = self.drop is not None and self.drop[0] <= t < self.drop[1]
        if in_window != self._in_window:
            self._in_window = in_window
            self.log(f"link {'dropped' if in_window else 'restored'} (--drop-link-after)")
        self.link.up = not (forced or in_window)
        paused = self._camera_toggles % 2 == 1
        if paused != self._camera_paused:
            self._camera_paused = paused
            if self.camera is not None:
                self.camera.pause(paused)
                self.log(f"camera {'paused' if paused else 'resumed'} (SIGUSR2)")
            else:
                self.log("SIGUSR2: no camera to pause")

    @contextlib.contextmanager
    def signals(self) -> Iterator[None]:
        """SIGINT/SIGTERM stop, SIGUSR1 toggles the link, SIGUSR2 the camera."""

        def stop(signum: int, frame: FrameType | None) -> None:
            self.stopping = True

        def usr1(signum: int, frame: FrameType | None) -> None:
            self._link_toggles += 1

        def usr2(signum: int, frame: FrameType | None) -> None:
            self._camera_toggles += 1

        handlers = {signal.SIGINT: stop, signal.SIGTERM: stop, signal.SIGUSR1: usr1,
                    signal.SIGUSR2: usr2}
        old = {s: signal.signal(s, h) for s, h in handlers.items()}
        try:
            yield
        finally:
            for s, h in old.items():
                signal.signal(s, h)

    def truth(self) -> dict[str, Any]:
        """The ground truth now (what really happened, without sensor noise)."""
        b, ap, w = self.body, self.ap, self.world
        t = b.t
        world_t = self.clock.time(t)
        lat, lon = latlon(w.home, b.north, b.east)
        home_lat, home_lon = latlon(w.home, 0.0, 0.0)

        def point(p: tuple[float, float] | None) -> dict[str, float] | None:
            return None if p is None else {"north": _r(p[0], 3), "east": _r(p[1], 3)}

        return {
            "time": _r(t, 3), "world": w.name, "seed": w.seed, "ready": ap.ready,
            "link": "up" if self.link.up else "down", "mode": ap.mode_name,
            "armed": b.armed, "landed": b.landed,
            "position": {"north": _r(b.north, 3), "east": _r(b.east, 3),
                         "down": _r(b.down, 3)},
            "altitude": _r(b.altitude, 3),
            "velocity": {"north": _r(b.vn, 3), "east": _r(b.ve, 3),
                         "down": _r(b.vd, 3)},
            "yaw_deg": _r(math.degrees(b.yaw), 2),
            "global": {"lat": lat / 1e7, "lon": lon / 1e7,
                       "alt": _r(w.home.alt + b.altitude, 3)},
            "battery": {"remaining_pct": _r(100 * b.battery_fraction, 2),
                        "voltage": _r(b.voltage, 3), "energy_wh": _r(b.energy_wh, 4)},
            "home": {"lat": home_lat / 1e7, "lon": home_lon / 1e7, "alt": w.home.alt,
                     "north": 0.0, "east": 0.0},
            "takeoff": point(ap.takeoff_point),
            "landing": point(ap.landing_point),
            "track": {"max_altitude": _r(b.max_alt, 3), "distance": _r(b.distance, 3),
                      "flight_time": _r(b.flight_time, 2), "takeoffs": ap.takeoffs,
                      "landings": ap.landings},
            "accident": None if w.accident is None else dataclasses.asdict(w.accident),
            "victims": [{"north": v.north, "east": v.east} for v in w.victims],
            "objects": [{"name": o.name, "color": list(o.color),
                         "north": _r(o.position(world_t)[0], 3),
                         "east": _r(o.position(world_t)[1], 3)}
                        for o in w.objects],
            **({"camera": {"frame": self.camera.count, "time": _r(self.camera.frame_us / 1e6, 3)}}
               if self.camera is not None and self.camera.stamped else {}),
        }

    def log_truth(self) -> None:
        """One line of the truth log (`--truth-log`), once per step."""
        if self.truth_log is None or self._logged_step == self.body.steps:
            return
        self._logged_step = self.body.steps
        try:
            self.truth_log.write(json.dumps(self.truth(), separators=(",", ":")) + "\n")
            self.truth_log.flush()
        except OSError as e:
            if not self._truth_failed:
                self._truth_failed = True
                self.log(f"cannot write the truth log: {e}")

    def write_truth(self) -> None:
        if not self.truth_path:
            return
        try:
            write_atomic(self.truth_path, json.dumps(self.truth(), indent=2) + "\n")
        except OSError as e:
            if not self._truth_failed:  # say it once; the flight goes on
                self._truth_failed = True
                self.log(f"cannot write the truth file: {e}")


def _stderr(text: str) -> None:
    print(f"sim: {text}", file=sys.stderr, flush=True)


def _r(x: float, digits: int) -> float:
    """Rounded, and never -0.0 (JSON readers should not see a negative zero)."""
    return round(x, digits) + 0.0




def _param(text: str) -> tuple[str, float]:
    name, eq, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not eq or not name or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER (LAND_SPEED=50), not {text!r}")
    return name.strip().upper(), number




def _port(text: str) -> int:
    v = int(text)
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"expected a TCP port (0..65535), not {text!r}")
    return v


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hfsmc sim",
        description="A simulated ArduPilot Copter (MAVLink over UDP) with a downward camera "
                    "(MJPEG over HTTP) over a world.")
    p.add_argument("--robot", choices=("diffdrive",),
                   help="a ground robot instead of the drone: `hfsmc sim --robot diffdrive "
                        "--help` (docs/worlds.md, Ground robots)")
    p.add_argument("--world", metavar="FILE", help="world file (YAML); default: an empty world")
    p.add_argument("--seed", type=int, metavar="N", help="override the world's seed (noise, textures)")
    p.add_argument("--mavlink", metavar="URL", default=DEFAULT_MAVLINK,
                   help=f"udpout:HOST:PORT or udpin:HOST:PORT (default {DEFAULT_MAVLINK})")
    p.add_argument("--autopilot", choices=sorted(AUTOPILOTS), default="ardupilot",
                   help="answer as ArduPilot Copter (the default) or as PX4 v1.16 "
                        "(docs/worlds.md)")
    p.add_argument("--source-port", type=_port, metavar="N",
                   help="with udpout, send from this UDP port (default: any for ardupilot, "
                        f"{SOURCE_PORT} for px4 as PX4 SITL; 0: any)")
    p.add_argument("--boot-time", type=_seconds, metavar="S",
                   help="seconds before GPS fix and EKF position (ardupilot) or the pre-flight "
                        "checks (px4), when arming is accepted (default 3 for ardupilot, short "
                        "for tests, ArduPilot SITL takes ~40; 4.5 for px4, as measured)")
    p.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="set an autopilot parameter at start, in ArduPilot's units (repeatable): "
                        "LAND_SPEED, LAND_SPEED_HIGH, LAND_ALT_LOW, WPNAV_SPEED_UP, "
                        "WPNAV_ACCEL_Z, MOT_SPOOL_TIME, TKOFF_SLEW_TIME... (docs/worlds.md)")
    p.add_argument("--truth", metavar="FILE",
                   help="write the ground truth (JSON) every second and at exit")
    p.add_argument("--truth-log", metavar="FILE",
                   help=f"append the ground truth as one JSON line every {TRUTH_LOG_S} "
                        "simulated seconds and at exit (a flight's whole track)")
    p.add_argument("--duration", type=_seconds, metavar="S",
                   help="exit after S simulated seconds (default: until SIGINT/SIGTERM)")
    p.add_argument("--drop-link-after", type=_seconds, metavar="S",
                   help="drop the MAVLink link S seconds after start")
    p.add_argument("--drop-link-for", type=_seconds, metavar="S",
                   help="for this long (default 5 s)")
    p.add_argument("--camera-port", type=_port, default=8554, metavar="N",
                   help="camera HTTP port on 127.0.0.1 (default 8554; 0: any free port)")
    p.add_argument("--no-camera", action="store_true", help="run without the camera")
    p.add_argument("--camera-only", action="store_true",
                   help="only render the camera for another vehicle (with --follow)")
    p.add_argument("--follow", metavar="URL",
                   help="MAVLink URL of the vehicle whose camera to render")
    p.add_argument("--lockstep", metavar="[HOST:]PORT",
                   help="be the time master of one component started with --clock sim:PORT: "
                        "wait for it on this TCP port (loopback unless a host is named), then "
                        "step only when it is done (as fast as both go; docs/worlds.md)")
    p.add_argument("--speedup", type=_speedup, metavar="N",
                   help="with --lockstep: hold simulated time to N times real time "
                        "(a person watching; default: as fast as it goes)")
    p.add_argument("--component-gone", choices=("stop", "realtime"), default="stop",
                   help="with --lockstep, when the component ends or dies: stop (the default) "
                        "or go on in real time")
    p.add_argument("--world-clock", choices=WORLD_CLOCKS, metavar="WHEN",
                   help="when the world's objects start moving: armed (when the vehicle first "
                        "arms, the default: a component may take a minute to build and start), "
                        "takeoff (when it first leaves the ground) or start (when the simulator "
                        "starts) (docs/worlds.md)")
    return p




def _camera_module() -> tuple[Any, str]:
    """hfsmc.sim.camera, or None and why not."""
    try:
        return importlib.import_module("hfsmc.sim.camera"), ""
    except ImportError as e:
        return None, str(e)


def _run_follow() -> Any:
    """The camera helper's ``run_follow`` (in hfsmc.sim.camera, or beside it in
    hfsmc.sim.follow), or why it cannot be had."""
    camera, why = _camera_module()
    if camera is not None and hasattr(camera, "run_follow"):
        return camera.run_follow
    try:
        return importlib.import_module("hfsmc.sim.follow").run_follow
    except (ImportError, AttributeError) as e:
        return why or str(e)


def main(argv: list[str]) -> int:
    """`hfsmc sim [ARGS...]`: 0 when stopped cleanly, 2 on a usage or world error."""
    if any(a == "--robot" or a.startswith("--robot=") for a in argv):
        from hfsmc.sim.ground.run import main as ground

        return ground(argv)
    args = parser().parse_args(argv)
    if args.drop_link_for is not None and args.drop_link_after is None:
        return _fail("--drop-link-for needs --drop-link-after")
    if args.speedup is not None and args.lockstep is None:
        return _fail("--speedup needs --lockstep (in real time the simulator runs at 1x)")
    if args.lockstep is not None and args.camera_only:
        return _fail("--lockstep and --camera-only: the camera follows another simulator's "
                     "time, not its own")
    if bool(args.camera_only) != bool(args.follow):
        return _fail("--camera-only and --follow URL go together")
    try:
        world = load_world(args.world)
    except WorldError as e:
        return _fail(str(e))
    if args.seed is not None:
        world = dataclasses.replace(world, seed=args.seed)
    if args.camera_only:
        follow = _run_follow()
        if isinstance(follow, str):
            return _fail(f"--camera-only: the camera is not available ({follow})")
        return int(follow(world, args.follow, args.camera_port,
                          world_clock=args.world_clock or "armed"))
    params = dict(args.param)
    known = AUTOPILOTS[args.autopilot].default_params(world)
    unknown = sorted(set(params) - set(known))
    if unknown:
        return _fail(f"--param {unknown[0]}: no such parameter "
                     f"({args.autopilot} knows: {', '.join(sorted(known))})")
    source = args.source_port if args.source_port is not None else \
        SOURCE_PORT if args.autopilot == "px4" else None
    try:
        link = Link(args.mavlink, source_port=source or None)
    except ValueError as e:
        return _fail(str(e))
    except OSError as e:
        port = f" from UDP port {source}" if source else ""
        return _fail(f"--mavlink {args.mavlink}: cannot send{port}: {e.strerror or e}"
                     + (" (another PX4 simulator? --source-port 0 sends from any port)"
                        if source else ""))
    try:
        server, truth_log = open_outputs(args, link.close)
    except OutputError as e:
        return _fail(str(e))
    boot = BOOT_TIMES[args.autopilot] if args.boot_time is None else args.boot_time
    sim = Simulator(world, link, boot_time=boot, truth=args.truth, autopilot=args.autopilot,
                    drop_after=args.drop_link_after,
                    drop_for=5.0 if args.drop_link_for is None else args.drop_link_for,
                    params=params, world_clock=args.world_clock or "armed", truth_log=truth_log)
    try:
        with sim.signals():
            where = _start_camera(sim, args, thread=server is None)
            if where is None:
                return 2
            more = f", {server.describe()}" if server is not None else ""
            print(f"sim: {link.describe()}, {where}{more}", file=sys.stderr, flush=True)
            try:
                if server is None or lockstep.fly(sim, server, args.duration,
                                                  args.speedup or math.inf,
                                                  args.component_gone):
                    if sim.camera is not None and server is not None:
                        sim.camera.start_thread()
                    sim.run(args.duration)
            finally:
                sim.write_truth()
                sim.log_truth()
                if link.ignored:
                    sim.log(f"ignored {link.ignored} MAVLink datagrams from other addresses "
                            "than the peer")
    finally:
        if sim.camera is not None:
            sim.camera.stop()
        if server is not None:
            server.close()
        if truth_log is not None:
            truth_log.close()
        link.close()
    return 0


def _start_camera(sim: Simulator, args: argparse.Namespace, thread: bool = True) -> str | None:
    """Start the camera; what to print about it, or None after an error."""
    if args.no_camera:
        return "no camera (--no-camera)"
    camera, why = _camera_module()
    if camera is None:
        return f"no camera (hfsmc.sim.camera is not available: {why})"
    feed = camera.CameraFeed(sim.world, pose=lambda: sim.pose, host="127.0.0.1",
                             port=args.camera_port)
    try:
        url = feed.start(thread=thread)
    except OSError as e:
        _fail(f"camera: cannot serve on 127.0.0.1:{args.camera_port}: {e}")
        return None
    sim.camera = feed
    return f"camera {url}"
