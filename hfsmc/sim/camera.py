"""The downward camera's picture of the world, drawn with OpenCV (docs/worlds.md).

A pinhole camera looks straight down from the vehicle (a gimbal keeps it level,
so roll and pitch do not tilt the view); the top of the image is the vehicle's
heading and its right the vehicle's right. Everything is precomputed from the
world's seed once, so that a frame costs two ``warpAffine`` calls, one multiply
and a few drawing calls:

- a *base map* of the whole ground at ``_BASE_PPM`` pixels per metre: the
  ground colour with slow, large patches of brighter and darker grass;
- a *detail tile*, a periodic grass-like noise (``_TILE`` pixels square,
  ``_TILE_PPM`` pixels per metre, so a 16 m period) and its mipmaps, which
  multiplies the brightness of the base map and of the road;
- the road, the victims and the moving objects drawn on top in image
  coordinates, anti-aliased with sub-pixel precision.

Brightness noise multiplies the three channels alike, so the hue and the
saturation of the ground stay those of its colour: colour filters in HSV see
grass as grass at any texture strength.
"""

from __future__ import annotations

import functools
import itertools
import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from hfsmc.sim.mjpeg import MjpegServer
from hfsmc.sim.world import RGB, Point, World

log = logging.getLogger("hfsmc.sim.camera")
Image = npt.NDArray[np.uint8]

MIN_ALTITUDE = 0.2  # metres: on the ground, the camera sees what it sees from this high
OUTSIDE = (28, 28, 28)  # BGR beyond the edge of the ground
HAIR = (40, 50, 70)  # BGR: a victim's head, dark enough for no colour filter to take it

_TILE = 1024  # detail tile side, pixels (a power of two: its mipmaps halve exactly)
_TILE_PPM = 64.0  # detail tile pixels per metre
_BASE_PPM = 2.0  # base map pixels per metre
_BASE_MAX = 4096  # base map side at most, pixels (a larger ground gets fewer pixels per metre)
_SHIFT = 4  # fractional bits of drawing coordinates
_ONE = 1 << _SHIFT
_UNIT = 128  # detail value that leaves a pixel's brightness as it is


def _u8(a: npt.NDArray[Any]) -> Image:
    """An OpenCV result as the 8-bit image it is (no copy)."""
    return np.asarray(a, dtype=np.uint8)


def bgr(c: RGB) -> tuple[int, int, int]:
    """A world colour (RGB) as OpenCV wants it."""
    return (c[2], c[1], c[0])


def _periodic_noise(rng: np.random.Generator, n: int, beta: float) -> npt.NDArray[np.float32]:
    """n by n noise with a 1/f^beta spectrum, zero mean and unit deviation, periodic in both axes
    (it is shaped in the Fourier domain), so that tiles of it join without a seam."""
    white = rng.standard_normal((n, n))
    f = np.fft.fftfreq(n)
    k = np.hypot(f[:, None], f[None, :])
    k[0, 0] = 1.0
    spectrum = np.fft.fft2(white) / k**beta
    spectrum[0, 0] = 0.0
    out = np.fft.ifft2(spectrum).real
    out /= out.std() or 1.0
    return out.astype(np.float32)


def _blades(rng: np.random.Generator, n: int, count: int) -> npt.NDArray[np.float32]:
    """n by n periodic image of ``count`` short light and dark strokes: blades of grass seen
    from above. A stroke near an edge is drawn again one period over, so tiles join."""
    out = np.zeros((n, n), dtype=np.float32)
    centre = rng.uniform(0, n, (count, 2))
    angle = rng.uniform(0, math.pi, count)
    half = rng.uniform(1.5, 5.0, count)
    value = rng.choice([-1.0, 1.0], count) * rng.uniform(0.4, 1.0, count)
    d = np.stack([np.cos(angle), np.sin(angle)], axis=1) * half[:, None]
    a = np.round((centre - d) * _ONE).astype(np.int64)
    b = np.round((centre + d) * _ONE).astype(np.int64)
    period = n * _ONE

    def shifts(c: float) -> tuple[int, ...]:
        return (0, period) if c < 6 else (0, -period) if c > n - 6 else (0,)

    for i in range(count):
        for ox in shifts(centre[i, 0]):
            for oy in shifts(centre[i, 1]):
                cv2.line(out, (int(a[i, 0]) + ox, int(a[i, 1]) + oy),
                         (int(b[i, 0]) + ox, int(b[i, 1]) + oy), float(value[i]), 1,
                         cv2.LINE_AA, _SHIFT)
    return out


@functools.lru_cache(maxsize=4)
def _detail_levels(seed: int, texture: float) -> tuple[tuple[float, Image], ...]:
    """The grass detail tile and its mipmaps: (pixels per metre, tile), finest first. Cached:
    renderers of one world share them (they only read them)."""
    rng = np.random.default_rng([seed, 1])
    grain = _periodic_noise(rng, _TILE, 0.2)  # soil and blades below a pixel
    tufts = _periodic_noise(rng, _TILE, 1.2)  # tufts a few decimetres across
    blades = _blades(rng, _TILE, 30_000)
    noise = np.clip(0.45 * grain + 0.7 * tufts + 1.5 * blades, -2.5, 2.5)
    tile = np.clip(_UNIT * (1.0 + 0.35 * texture * noise), 0, 255).astype(np.uint8)
    levels = [(_TILE_PPM, tile)]
    while tile.shape[0] > 16:
        # INTER_AREA halves by averaging 2 by 2 blocks: each level stays exactly periodic.
        tile = _u8(cv2.resize(tile, (tile.shape[1] // 2, tile.shape[0] // 2),
                              interpolation=cv2.INTER_AREA))
        levels.append((levels[-1][0] / 2, tile))
    for _, t in levels:
        t.flags.writeable = False  # shared by every renderer of the seed
    return tuple(levels)


def _base_map(world: World) -> tuple[float, Image]:
    """The whole ground, one colour with large light and dark patches: (pixels per metre, map)."""
    g = world.ground
    ppm = min(_BASE_PPM, _BASE_MAX / max(g.size, 1e-6))
    n = max(2, math.ceil(g.size * ppm))
    rng = np.random.default_rng([world.seed, 2])
    size = 1 << max(1, (n - 1).bit_length())
    patches = _periodic_noise(rng, size, 2.2)[:n, :n]
    light = np.clip(1.0 + 0.25 * g.texture * patches, 0.2, 2.0)
    colour = np.array(bgr(g.color), dtype=np.float32)
    base = np.clip(light[:, :, None] * colour, 0, 255).astype(np.uint8)
    return n / g.size if g.size > 0 else ppm, base


def _clip_segment(a: Point, b: Point, lo: Point, hi: Point) -> tuple[Point, Point] | None:
    """The part of segment ab inside the box lo..hi (Liang-Barsky), or None."""
    t0, t1 = 0.0, 1.0
    d = (b[0] - a[0], b[1] - a[1])
    for axis in (0, 1):
        for p, q in ((-d[axis], a[axis] - lo[axis]), (d[axis], hi[axis] - a[axis])):
            if p == 0:
                if q < 0:
                    return None
                continue
            r = q / p
            if p < 0:
                t0 = max(t0, r)
            else:
                t1 = min(t1, r)
            if t0 > t1:
                return None
    return ((a[0] + t0 * d[0], a[1] + t0 * d[1]), (a[0] + t1 * d[0], a[1] + t1 * d[1]))


class _View:
    """One pose's projection between the ground (north, east metres) and the image (pixels)."""

    def __init__(self, world: World, north: float, east: float, down: float, yaw: float) -> None:
        cam = world.camera
        self.w, self.h = cam.width, cam.height
        self.cx, self.cy = (cam.width - 1) / 2, (cam.height - 1) / 2
        focal = (cam.width / 2) / math.tan(math.radians(cam.hfov_deg) / 2)
        self.scale = focal / max(-down, MIN_ALTITUDE)  # pixels per metre on the ground
        self.north, self.east = north, east
        self.cos, self.sin = math.cos(yaw), math.sin(yaw)
        self.yaw = yaw
        # Half the diagonal of the footprint: nothing farther can show.
        self.reach = math.hypot(self.cx + 1, self.cy + 1) / self.scale

    def image_to_ground(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Rows of the affine map (u, v, 1) → north and → east."""
        s, c, sn = self.scale, self.cos, self.sin
        n = (-sn / s, -c / s, self.north + (c * self.cy + sn * self.cx) / s)
        e = (c / s, -sn / s, self.east + (sn * self.cy - c * self.cx) / s)
        return n, e

    def to_image(self, north: float, east: float) -> tuple[float, float]:
        dn, de = north - self.north, east - self.east
        forward = dn * self.cos + de * self.sin
        right = -dn * self.sin + de * self.cos
        return (self.cx + self.scale * right, self.cy - self.scale * forward)

    def fixed(self, north: float, east: float) -> tuple[int, int]:
        """A ground point in OpenCV's fixed-point drawing coordinates."""
        u, v = self.to_image(north, east)
        return (round(u * _ONE), round(v * _ONE))

    def near(self, north: float, east: float, radius: float) -> bool:
        return math.hypot(north - self.north, east - self.east) <= self.reach + radius

    def warp(self, src: Image, ppm: float, origin: Point, period: int | None,
             border: int) -> Image:
        """src (north up, ``ppm`` pixels per metre, the ground point ``origin`` at its pixel
        (0, 0)) as this view sees it; a periodic src wraps round."""
        n, e = self.image_to_ground()
        # Ground → source pixel: x = (east - origin east)·ppm, y = (origin north - north)·ppm.
        row_x = [ppm * e[0], ppm * e[1], ppm * (e[2] - origin[1])]
        row_y = [-ppm * n[0], -ppm * n[1], ppm * (origin[0] - n[2])]
        if period:
            # warpAffine works in 16-bit fixed point: keep the offsets within one period.
            row_x[2] %= period
            row_y[2] %= period
        m = np.array([row_x, row_y], dtype=np.float64)
        return _u8(cv2.warpAffine(src, m, (self.w, self.h),
                                  flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                  borderMode=border, borderValue=OUTSIDE))


class Renderer:
    """Draws the downward camera's view of ``world``; same world, pose and time → same bytes."""

    def __init__(self, world: World) -> None:
        self.world = world
        self._levels = _detail_levels(world.seed, world.ground.texture)
        self._base_ppm, self._base = _base_map(world)
        half = world.ground.size / 2
        self._half = half
        rng = np.random.default_rng([world.seed, 3])
        # Each victim lies in its own direction (radians from north).
        self._victim_heading = [float(a) for a in rng.uniform(0, 2 * math.pi, len(world.victims))]
        self._road_points = list(world.road.points)

    def render(self, t: float, north: float, east: float, down: float, yaw: float) -> Image:
        """The view at time ``t`` (s) from (north, east, down) metres NED, heading ``yaw`` rad."""
        view = _View(self.world, north, east, down, yaw)
        half = self._half
        px = 0.5 / self._base_ppm  # pixel (0, 0)'s centre is half a pixel in from the corner
        img = view.warp(self._base, self._base_ppm, (half - px, px - half), None,
                        cv2.BORDER_REPLICATE)
        self._draw_road(img, view)
        ppm, tile = self._detail(view.scale)
        detail = view.warp(tile, ppm, (0.0, 0.0), tile.shape[0], cv2.BORDER_WRAP)
        img = _u8(cv2.multiply(img, cv2.cvtColor(detail, cv2.COLOR_GRAY2BGR), scale=1 / _UNIT))
        self._mask_outside(img, view)
        self._draw_victims(img, view)
        self._draw_objects(img, view, t)
        return img

    def _detail(self, scale: float) -> tuple[float, Image]:
        # The coarsest level still at least as fine as the screen: sharp without shimmer.
        chosen = self._levels[0]
        for level in self._levels:
            if level[0] < scale:
                break
            chosen = level
        return chosen

    def _window(self, view: _View, margin: float) -> tuple[Point, Point]:
        r = view.reach + margin
        return (view.north - r, view.east - r), (view.north + r, view.east + r)

    def _draw_road(self, img: Image, view: _View) -> None:
        road = self.world.road
        pts = self._road_points
        if len(pts) < 2 or road.width <= 0:
            if len(pts) == 1 and view.near(pts[0][0], pts[0][1], road.width / 2):
                cv2.circle(img, view.fixed(*pts[0]), round(road.width / 2 * view.scale * _ONE),
                           bgr(road.color), -1, cv2.LINE_AA, _SHIFT)
            return
        # Clipped to a box round the footprint, so coordinates stay small at any altitude;
        # the cut ends' round caps fall outside the picture.
        lo, hi = self._window(view, road.width)
        thickness = max(1, round(road.width * view.scale))
        colour = bgr(road.color)
        for a, b in itertools.pairwise(pts):
            seg = _clip_segment(a, b, lo, hi)
            if seg is not None:
                cv2.line(img, view.fixed(*seg[0]), view.fixed(*seg[1]), colour, thickness,
                         cv2.LINE_AA, _SHIFT)

    def _mask_outside(self, img: Image, view: _View) -> None:
        half = self._half
        lo, hi = self._window(view, 1.0)
        if lo[0] >= -half and lo[1] >= -half and hi[0] <= half and hi[1] <= half:
            return  # the footprint is all ground
        n0, e0 = max(lo[0], -half), max(lo[1], -half)
        n1, e1 = min(hi[0], half), min(hi[1], half)
        mask = np.zeros(img.shape[:2], dtype=np.uint8)
        if n0 < n1 and e0 < e1:
            corners = np.array([view.fixed(n0, e0), view.fixed(n0, e1), view.fixed(n1, e1),
                                view.fixed(n1, e0)], dtype=np.int32)
            cv2.fillConvexPoly(mask, corners, 255, cv2.LINE_8, _SHIFT)
        img[mask == 0] = OUTSIDE

    def _draw_victims(self, img: Image, view: _View) -> None:
        for victim, heading in zip(self.world.victims, self._victim_heading, strict=True):
            r = victim.radius
            if not view.near(victim.north, victim.east, r):
                continue
            # A figure lying on the ground: a body along its heading, a dark head at one end.
            angle = math.degrees(heading - view.yaw) - 90.0
            axes = (round(r * view.scale * _ONE), round(0.45 * r * view.scale * _ONE))
            cv2.ellipse(img, view.fixed(victim.north, victim.east), axes, angle, 0, 360,
                        bgr(victim.color), -1, cv2.LINE_AA, _SHIFT)
            hn = victim.north + 0.8 * r * math.cos(heading)
            he = victim.east + 0.8 * r * math.sin(heading)
            cv2.circle(img, view.fixed(hn, he), round(0.3 * r * view.scale * _ONE), HAIR, -1,
                       cv2.LINE_AA, _SHIFT)

    def _draw_objects(self, img: Image, view: _View, t: float) -> None:
        for obj in self.world.objects:
            n, e = obj.position(t)
            if view.near(n, e, obj.radius):
                cv2.circle(img, view.fixed(n, e), round(obj.radius * view.scale * _ONE),
                           bgr(obj.color), -1, cv2.LINE_AA, _SHIFT)


def footprint(world: World, altitude: float) -> tuple[float, float]:
    """The ground seen from ``altitude`` metres up: (width, height) in metres."""
    cam = world.camera
    half_w = math.tan(math.radians(cam.hfov_deg) / 2)
    h = max(altitude, MIN_ALTITUDE)
    return (2 * h * half_w, 2 * h * half_w * cam.height / cam.width)


Pose = tuple[float, float, float, float, float]  # t (s), north, east, down (m), yaw (rad)


class CameraFeed:
    """The simulated downward camera: renders ``pose()`` at the camera's rate in a thread of
    its own and serves the frames as MJPEG on ``host`` (``port`` 0: any free port).

    ``pose`` returns (seconds since the simulation started, north, east, down, yaw) and is
    called from the camera's thread.
    """

    def __init__(self, world: World, pose: Callable[[], Pose], host: str = "127.0.0.1",
                 port: int = 8554, quality: int = 85) -> None:
        self.world = world
        self._pose = pose
        self._host, self._port = host, port
        self._quality = quality
        self._renderer: Renderer | None = None
        self._server: MjpegServer | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._frame: Image | None = None
        self._pose_failed = False
        self.count = 0  # frames rendered (their numbers: 1, 2, ...)
        self.frame_us = 0  # the simulated time the latest one was rendered for (lockstep)
        self._stamped = False  # frames carry their number and time (lockstep)

    def start(self, thread: bool = True) -> str:
        """Serve (the first frame is ready before this returns); the stream's URL. OSError
        when the port is taken. Without ``thread`` nothing renders on its own: the simulator
        in lockstep calls ``shoot_at`` (and ``start_thread`` if it goes on in real time)."""
        if self._server is not None:
            return self.url
        self._renderer = Renderer(self.world)
        server = MjpegServer(self._host, self._port)
        server.start()
        self._server = server
        self._stamped = not thread
        self._shoot()
        if thread:
            self.start_thread()
        return self.url

    def start_thread(self) -> None:
        """Render at the camera's rate in real time, in a thread of its own."""
        self._stamped = False
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="hfsmc-camera", daemon=True)
        self._thread.start()

    def shoot_at(self, t_us: int) -> None:
        """Render the pose now as the frame of simulated time ``t_us`` (lockstep): its part
        says its number and time (X-Frame, X-Time-Us)."""
        self.frame_us = t_us
        if self._server is not None and not self._server.paused:
            self._shoot()

    @property
    def url(self) -> str:
        """http://HOST:PORT/bottom.mjpg (once started)."""
        if self._server is None:
            raise RuntimeError("the camera is not started")
        return self._server.url()

    @property
    def port(self) -> int:
        if self._server is None:
            raise RuntimeError("the camera is not started")
        return self._server.port

    @property
    def stamped(self) -> bool:
        """Frames carry their number and simulated time (the simulator in lockstep)."""
        return self._stamped

    @property
    def paused(self) -> bool:
        return self._server is not None and self._server.paused

    def pause(self, on: bool) -> None:
        """Drop the camera (streams cut, requests refused with 503) or bring it back."""
        if self._server is not None:
            self._server.pause(on)

    def frame(self) -> Image | None:
        """The last frame rendered (BGR), or None before the first."""
        return self._frame

    def stop(self) -> None:
        """Stop rendering and serving; every client is cut. Returns within a second."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(0.5)
            self._thread = None
        if self._server is not None:
            self._server.stop()
            self._server = None

    def __enter__(self) -> CameraFeed:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _shoot(self) -> None:
        assert self._renderer is not None and self._server is not None
        try:
            pose = self._pose()
        except Exception:
            if not self._pose_failed:  # once: the pose source may fail at every frame
                log.exception("camera: the vehicle's pose is not available")
                self._pose_failed = True
            return
        frame = self._renderer.render(*pose)
        ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, self._quality])
        if ok:
            self._frame = frame
            self.count += 1
            headers = {"X-Frame": str(self.count), "X-Time-Us": str(self.frame_us)} \
                if self._stamped else None
            self._server.publish(jpeg.tobytes(), headers)

    def _run(self) -> None:
        period = 1.0 / max(self.world.camera.fps, 0.1)
        due = time.monotonic() + period
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            if self._server is None:
                return
            if not self._server.paused:
                self._shoot()
            due += period
            now = time.monotonic()
            if due < now - period:  # fell behind (a stalled machine): skip, do not rush
                due = now + period
