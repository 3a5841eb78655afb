"""The simulated multicopter's body: a point mass with a heading, the position and
velocity controllers an autopilot flies it with, ground contact, the battery, and
the noise of what it reports.

Coordinates are local NED metres from home (``down`` is negative in the air).
Everything advances by one fixed step (``dt``) at a time, so a flight depends
only on the seed and on the step at which each command arrives: the same seed
and the same commands give the same flight.
"""

from __future__ import annotations

import math
import random

from hfsmc.sim.world import Vehicle as VehicleConfig

GRAVITY = 9.80665
DT = 0.02  # the physics step: 50 Hz

KP_POS = 2.5  # 1/s: how hard the position controller pulls in the last metre
KP_POS_Z = 1.0  # 1/s: the same for height (ArduPilot's PSC_POSZ_P default)
BRAKE_SHARE = 0.5  # the share of max_accel planned for braking, the rest corrects
ARRIVED = 0.005  # m: closer than this, at low speed, the vehicle is on its target
YAW_SLEW = math.radians(60.0)  # rad/s: turning towards a heading (ATC_SLEW_YAW)
YAW_RATE_MAX = math.radians(180.0)  # rad/s: the fastest commanded turn
FACE_TRAVEL = 0.05  # share of max_speed above which "face the way you go" turns
CELLS = 4  # a 4S pack: 16.8 V full, 14.0 V empty
NOISE_POS = (0.02, 0.02, 0.03)  # m: the reported position's error (1 sigma), N E D
NOISE_TAU = 2.0  # s: how slowly that error wanders
NOISE_VEL = 0.02  # m/s: white noise on the reported velocity


def wrap_pi(a: float) -> float:
    """An angle in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def _limit(x: float, y: float, r: float) -> tuple[float, float]:
    """(x, y) shortened to length r when longer."""
    n = math.hypot(x, y)
    return (x, y) if n <= r or n == 0 else (x * r / n, y * r / n)


class Body:
    """The vehicle's physics and its low-level flight controllers.

    The autopilot chooses what to do (``hold``, ``goto``, ``fly_velocity``,
    ``land``, and a heading mode); ``step`` flies it for one step and returns the
    events of that step (``"liftoff"``, ``"touchdown"``).
    """

    def __init__(self, cfg: VehicleConfig, seed: int, dt: float = DT) -> None:
        self.cfg = cfg
        self.dt = dt
        self.steps = 0
        self.north = self.east = self.down = 0.0
        self.vn = self.ve = self.vd = 0.0
        self.an = self.ae = 0.0  # the last horizontal acceleration, for the attitude
        self.yaw = 0.0
        self.yaw_rate = 0.0
        self.armed = False
        self.landed = True
        self.energy_wh = cfg.battery_wh
        self.power_w = 0.0
        # Limits the autopilot's parameters may lower (WPNAV_SPEED and friends).
        self.speed_xy = cfg.max_speed
        # ArduPilot's defaults (docs/worlds.md, "The flight profile"), within the frame's.
        self.speed_up = min(2.5, cfg.max_climb)  # WPNAV_SPEED_UP
        self.speed_down = min(1.5, cfg.max_climb)  # WPNAV_SPEED_DN
        self.land_speed = min(0.5, cfg.max_climb)  # LAND_SPEED
        self.land_speed_high = self.speed_down  # LAND_SPEED_HIGH (0: WPNAV_SPEED_DN)
        self.land_alt_low = 10.0  # LAND_ALT_LOW: below this, descend at LAND_SPEED
        self.accel = cfg.max_accel
        self.accel_z = min(1.0, cfg.max_accel)  # WPNAV_ACCEL_Z
        # What the controllers are asked for.
        self.nav = "goto"  # goto | velocity | land
        self.goal = (0.0, 0.0, 0.0)
        self.vel_cmd = (0.0, 0.0, 0.0)
        self.brake_boost = 1.0
        self.heading = "hold"  # hold | rate | angle | travel
        self.heading_rate = 0.0
        self.heading_target = 0.0
        self.heading_dir = 0  # -1 counter-clockwise, 1 clockwise, 0 the shorter way
        # Track summary.
        self.max_alt = 0.0
        self.distance = 0.0
        self.flight_time = 0.0
        # Sensor noise, drawn the same number of times every step.
        self._rng = random.Random(seed)
        self._bias = [0.0, 0.0, 0.0]
        self._vnoise = [0.0, 0.0, 0.0]

    # -- what the autopilot asks for ---------------------------------------------

    @property
    def t(self) -> float:
        """Simulated seconds since start."""
        return self.steps * self.dt

    @property
    def altitude(self) -> float:
        return -self.down

    @property
    def pose(self) -> tuple[float, float, float, float, float]:
        """The true pose the camera renders: (t, north, east, down, yaw)."""
        return (self.t, self.north, self.east, self.down, self.yaw)

    def stopping_point(self, boost: float = 1.0) -> tuple[float, float, float]:
        """Where the vehicle would stop if it braked now: ArduPilot holds there."""
        a = BRAKE_SHARE * self.accel * boost
        az = BRAKE_SHARE * self.accel_z * boost
        sh = math.hypot(self.vn, self.ve) / (2 * a)
        return (self.north + self.vn * sh, self.east + self.ve * sh,
                min(0.0, self.down + self.vd * abs(self.vd) / (2 * az)))

    def hold(self, boost: float = 1.0) -> None:
        """Stop (braking ``boost`` times harder, for BRAKE) and hold that point."""
        self.goto(*self.stopping_point(boost))
        self.brake_boost = boost
        if self.heading in ("rate", "travel"):
            self.heading = "hold"

    def goto(self, north: float, east: float, down: float) -> None:
        """Fly in a straight line to a point and stay there."""
        self.nav = "goto"
        self.goal = (north, east, down)
        self.brake_boost = 1.0

    def fly_velocity(self, vn: float, ve: float, vd: float) -> None:
        """Track a velocity (NED, m/s), within the speed limits."""
        self.nav = "velocity"
        self.vel_cmd = (vn, ve, vd)

    def land(self) -> None:
        """Descend where the vehicle stops, slowing to the landing speed below LAND_ALT_LOW."""
        n, e, _ = self.stopping_point()
        self.nav = "land"
        self.goal = (n, e, 0.0)
        if self.heading in ("rate", "travel"):
            self.heading = "hold"

    def turn_rate(self, rate: float) -> None:
        self.heading = "rate"
        self.heading_rate = max(-YAW_RATE_MAX, min(YAW_RATE_MAX, rate))

    def turn_to(self, yaw: float, rate: float = 0.0, direction: int = 0) -> None:
        """Turn to a heading (rad) at ``rate`` rad/s (0: the default slew)."""
        self.heading = "angle"
        self.heading_target = wrap_pi(yaw)
        self.heading_rate = min(abs(rate), YAW_RATE_MAX) or YAW_SLEW
        self.heading_dir = direction

    def face_travel(self) -> None:
        """Turn to face the direction of travel (ArduPilot's WP_YAW_BEHAVIOR default)."""
        self.heading = "travel"

    def hold_heading(self) -> None:
        self.heading = "hold"

    def arrived(self, tolerance: float = 0.2) -> bool:
        """On the goal of ``goto`` (within ``tolerance`` m) and nearly still."""
        d = math.dist((self.north, self.east, self.down), self.goal)
        return self.nav == "goto" and d < tolerance and self.speed() < 0.3

    def speed(self) -> float:
        return math.sqrt(self.vn ** 2 + self.ve ** 2 + self.vd ** 2)

    # -- one step ------------------------------------------------------------------

    def step(self) -> list[str]:
        """Advance one step; the events of that step."""
        events: list[str] = []
        dt = self.dt
        was = (self.north, self.east, self.down)
        if not self.armed:
            self._unpowered(dt)
        elif self.landed:
            want = self._desired_velocity()
            if want[2] < -0.05:  # a climb was asked for: lift off
                self.landed = False
                events.append("liftoff")
                self._track(want, dt)
            else:
                self._on_ground()
        else:
            self._track(self._desired_velocity(), dt)
            self._turn(dt)
        if not self.landed and self.down >= 0.0 and self.vd >= 0.0:
            self.down = 0.0
            self._on_ground()
            self.landed = True
            events.append("touchdown")
        self._battery(dt)
        if not self.landed:
            self.flight_time += dt
            self.distance += math.dist(was, (self.north, self.east, self.down))
            self.max_alt = max(self.max_alt, -self.down)
        self._noise(dt)
        self.steps += 1
        return events

    def _desired_velocity(self) -> tuple[float, float, float]:
        if self.nav == "velocity":
            vn, ve = _limit(self.vel_cmd[0], self.vel_cmd[1], self.speed_xy)
            vd = max(-self.speed_up, min(self.speed_down, self.vel_cmd[2]))
            return (vn, ve, vd)
        if self.nav == "land":
            vn, ve, _ = self._towards((self.goal[0], self.goal[1], self.down))
            above = max(-self.down - self.land_alt_low, 0.0)
            fast = min(self.land_speed_high, math.sqrt(2 * BRAKE_SHARE * self.accel_z * above),
                       KP_POS_Z * above)
            return (vn, ve, max(self.land_speed, fast))
        return self._towards(self.goal)

    def _towards(self, goal: tuple[float, float, float]) -> tuple[float, float, float]:
        """The velocity that brings the vehicle to ``goal`` in a straight line."""
        en, ee, ed = goal[0] - self.north, goal[1] - self.east, goal[2] - self.down
        dist = math.sqrt(en * en + ee * ee + ed * ed)
        if dist < 1e-9:
            return (0.0, 0.0, 0.0)
        top = accel = math.inf  # the fastest speed (and braking) along the line within each limit
        h = math.hypot(en, ee)
        if h > 0:
            top = self.speed_xy * dist / h
            accel = self.accel * dist / h
        if ed < 0:
            top = min(top, self.speed_up * dist / -ed)
        elif ed > 0:
            top = min(top, self.speed_down * dist / ed)
        if ed != 0:
            accel = min(accel, self.accel_z * dist / abs(ed))
        a = BRAKE_SHARE * accel * self.brake_boost
        kp = (KP_POS * h + KP_POS_Z * abs(ed)) / (h + abs(ed))  # height is pulled more gently
        s = min(top, math.sqrt(2 * a * dist), kp * self.brake_boost * dist)
        return (en / dist * s, ee / dist * s, ed / dist * s)

    def _track(self, want: tuple[float, float, float], dt: float) -> None:
        """Accelerate towards the wanted velocity within max_accel, then move."""
        a = self.accel * self.brake_boost
        az = self.accel_z * self.brake_boost
        dn, de = _limit(want[0] - self.vn, want[1] - self.ve, a * dt)
        dd = max(-az * dt, min(az * dt, want[2] - self.vd))
        self.an, self.ae = dn / dt, de / dt
        self.vn += dn
        self.ve += de
        self.vd += dd
        self.north += self.vn * dt
        self.east += self.ve * dt
        self.down += self.vd * dt
        if self.nav == "goto" and self.speed() < 0.05 and \
                math.dist((self.north, self.east, self.down), self.goal) < ARRIVED:
            self.north, self.east, self.down = self.goal
            self.vn = self.ve = self.vd = 0.0
        if self.down > 0.0:  # the ground stops a descent
            self.down = 0.0

    def _turn(self, dt: float) -> None:
        before = self.yaw
        if self.heading == "rate":
            self.yaw = wrap_pi(self.yaw + self.heading_rate * dt)
        elif self.heading == "angle":
            self._slew(self.heading_target, self.heading_rate, self.heading_dir, dt)
        elif self.heading == "travel":
            want = self._desired_velocity()
            if math.hypot(want[0], want[1]) > FACE_TRAVEL * self.cfg.max_speed:
                self._slew(math.atan2(want[1], want[0]), YAW_SLEW, 0, dt)
        self.yaw_rate = wrap_pi(self.yaw - before) / dt

    def _slew(self, target: float, rate: float, direction: int, dt: float) -> None:
        err = wrap_pi(target - self.yaw)
        if direction > 0 and err < 0 and abs(err) > 1e-6:
            err += 2 * math.pi
        elif direction < 0 and err > 0 and abs(err) > 1e-6:
            err -= 2 * math.pi
        turn = max(-rate * dt, min(rate * dt, err))
        self.yaw = wrap_pi(self.yaw + turn)
        if abs(err) <= rate * dt:
            self.yaw = target
            if self.heading == "angle":
                self.heading_dir = 0

    def _unpowered(self, dt: float) -> None:
        """Motors off: on the ground it rests; in the air it falls."""
        self.yaw_rate = 0.0
        if self.landed:
            self._on_ground()
            return
        drag = max(0.0, 1.0 - 0.3 * dt)
        self.vn *= drag
        self.ve *= drag
        self.vd += GRAVITY * dt
        self.an = self.ae = 0.0
        self.north += self.vn * dt
        self.east += self.ve * dt
        self.down = min(0.0, self.down + self.vd * dt)

    def _on_ground(self) -> None:
        self.vn = self.ve = self.vd = 0.0
        self.an = self.ae = 0.0
        self.yaw_rate = 0.0

    def _battery(self, dt: float) -> None:
        if not self.armed:
            self.power_w = 0.0
        elif self.landed:
            self.power_w = 0.15 * self.cfg.hover_w  # motors at ground idle
        else:
            climb = max(0.0, -self.vd) / max(self.cfg.max_climb, 0.1)
            self.power_w = self.cfg.hover_w * (1.0 + 0.25 * climb)
        self.energy_wh = max(0.0, self.energy_wh - self.power_w * dt / 3600.0)

    @property
    def battery_fraction(self) -> float:
        return self.energy_wh / self.cfg.battery_wh if self.cfg.battery_wh > 0 else 0.0

    @property
    def voltage(self) -> float:
        load = self.power_w / self.cfg.hover_w if self.cfg.hover_w > 0 else 0.0
        return CELLS * (3.5 + 0.7 * self.battery_fraction) - 0.4 * load

    @property
    def current(self) -> float:
        return self.power_w / self.voltage if self.voltage > 0 else 0.0

    # -- what the sensors report ---------------------------------------------------

    def _noise(self, dt: float) -> None:
        """One draw per axis per step, whatever happens, so a seed fixes the noise."""
        keep = math.exp(-dt / NOISE_TAU)
        spread = math.sqrt(1.0 - keep * keep)
        for i in range(3):
            self._bias[i] = keep * self._bias[i] + NOISE_POS[i] * spread * self._rng.gauss(0, 1)
            self._vnoise[i] = NOISE_VEL * self._rng.gauss(0, 1)

    def reported_position(self) -> tuple[float, float, float]:
        """Position as the EKF reports it: the truth plus a slowly wandering error."""
        return (self.north + self._bias[0], self.east + self._bias[1],
                self.down + self._bias[2])

    def reported_velocity(self) -> tuple[float, float, float]:
        if self.landed and not self.armed:
            return (0.0, 0.0, 0.0)
        return (self.vn + self._vnoise[0], self.ve + self._vnoise[1],
                self.vd + self._vnoise[2])

    def attitude(self) -> tuple[float, float]:
        """Roll and pitch (rad) that give the last horizontal acceleration."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        forward = self.an * c + self.ae * s
        right = -self.an * s + self.ae * c
        return (math.atan2(right, GRAVITY), -math.atan2(forward, GRAVITY))
