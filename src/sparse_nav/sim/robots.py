"""Simulated robots: a unicycle ground robot on cmd_vel and a DJI Tello driven by SDK text commands.

Poses are in the world frame: (x, y) metres, z metres above the floor, yaw radians about +z
(0 = +x, counter-clockwise positive). Obstacles are vertical 2D segments (m) with a height (m).
"""
import collections
import dataclasses
import math
import types

import numpy as np

from sparse_nav.sim.world import segment_distances


class DroneCommandError(ValueError):
    """A Tello command that is unknown or outside the Tello's limits; the message says which."""


def _wrap(angle):
    """Angle wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class _Obstacles:
    """Collision queries against walls (full height) and box footprints (up to their height).

    Motion is continuous in small steps, so a disc can only enter a box through its edges:
    testing the distance to wall and box-edge segments is enough.
    """

    def __init__(self, world):
        segs, heights = world.obstacle_segments()
        self.segs = segs
        self.heights = np.where(np.arange(len(segs)) < len(world.walls), np.inf, heights)

    def blocked(self, x, y, radius, z=0.0):
        """True if a disc of ``radius`` (m) at (x, y) and height z (m) touches an obstacle.

        Boxes only block below their top (a drone may fly over a low box).
        """
        if len(self.segs) == 0:
            return False
        d = segment_distances(np.array([x, y]), self.segs)
        return bool(np.any((d < radius) & (self.heights > z)))


class GroundRobot:
    """Unicycle robot (disc of ``ground_radius_m``) driven by linear/angular velocity commands.

    Collisions: a motion that would bring the disc into a wall or box is cut at contact (found by
    bisection) and counted once per contact episode; turning in place is always possible.
    Wheel odometry integrates the actual motion with a per-run scale and heading bias plus noise.
    """

    def __init__(self, world, config, rng):
        self.cfg = config
        self.x, self.y, self.yaw = (float(v) for v in world.start)
        self._obstacles = _Obstacles(world)
        self._rng = rng
        self._v = 0.0
        self._w = 0.0
        self.collisions = 0
        self._in_contact = False
        # Odometry error model, drawn once per run (wheel radius/track width calibration).
        self._odo_scale = 1.0 + rng.normal(0.0, config.ground_odom_scale_error)
        self._odo_turn_scale = 1.0 + rng.normal(0.0, config.ground_odom_scale_error)
        self._odo_curvature = rng.normal(0.0, config.ground_odom_curvature_rad_per_m)
        self.odom = [0.0, 0.0, 0.0]

    def set_cmd_vel(self, linear_m_s, angular_rad_s):
        """Set the velocity command (m/s, rad/s), clamped to the robot's limits."""
        v, w = float(linear_m_s), float(angular_rad_s)
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"cmd_vel must be finite, got ({linear_m_s}, {angular_rad_s})")
        lim_v, lim_w = self.cfg.ground_max_linear_m_s, self.cfg.ground_max_angular_rad_s
        self._v = min(max(v, -lim_v), lim_v)
        self._w = min(max(w, -lim_w), lim_w)

    @property
    def cmd_vel(self):
        """The clamped velocity command (m/s, rad/s)."""
        return self._v, self._w

    def pose(self):
        """(x, y, z, yaw) of the base in the world (m, rad); z is 0 on the floor."""
        return self.x, self.y, 0.0, self.yaw

    def step(self, dt):
        """Advance by dt seconds."""
        yaw_mid = self.yaw + 0.5 * self._w * dt
        dx, dy = self._v * dt * math.cos(yaw_mid), self._v * dt * math.sin(yaw_mid)
        frac = 1.0
        if dx or dy:
            radius = self.cfg.ground_radius_m
            if self._obstacles.blocked(self.x + dx, self.y + dy, radius):
                lo, hi = 0.0, 1.0
                for _ in range(12):  # bisection to contact, to ~0.03% of the step
                    mid = 0.5 * (lo + hi)
                    if self._obstacles.blocked(self.x + mid * dx, self.y + mid * dy, radius):
                        hi = mid
                    else:
                        lo = mid
                frac = lo
                if not self._in_contact:
                    self.collisions += 1
                self._in_contact = True
            else:
                self._in_contact = False
        self.x += frac * dx
        self.y += frac * dy
        dyaw = self._w * dt
        self.yaw = _wrap(self.yaw + dyaw)
        self._integrate_odometry(frac * self._v * dt, dyaw)

    def _integrate_odometry(self, ds, dyaw):
        cfg = self.cfg
        ds_o = ds * self._odo_scale
        dyaw_o = dyaw * self._odo_turn_scale + abs(ds) * self._odo_curvature
        if ds or dyaw:
            ds_o += self._rng.normal(0.0, cfg.ground_odom_noise_m_per_sqrt_m * math.sqrt(abs(ds)))
            dyaw_o += self._rng.normal(0.0, cfg.ground_odom_noise_rad_per_sqrt_rad
                                       * math.sqrt(abs(dyaw)))
        x, y, th = self.odom
        mid = th + 0.5 * dyaw_o
        self.odom = [x + ds_o * math.cos(mid), y + ds_o * math.sin(mid), _wrap(th + dyaw_o)]


# Tello SDK 1.3 commands this emulator accepts.
_TELLO_MOVES = types.MappingProxyType({   # name -> (up, forward, left) unit direction
    "forward": (0.0, 1.0, 0.0), "back": (0.0, -1.0, 0.0), "left": (0.0, 0.0, 1.0),
    "right": (0.0, 0.0, -1.0), "up": (1.0, 0.0, 0.0), "down": (-1.0, 0.0, 0.0)})
_TELLO_TURNS = types.MappingProxyType({"cw": -1.0, "ccw": 1.0})   # name -> sign of yaw change
_TELLO_PLAIN = ("command", "takeoff", "land", "stop", "emergency")


@dataclasses.dataclass
class _DroneTask:
    """A command being executed: its text and its motion target."""

    text: str
    kind: str
    target: tuple = ()          # (x, y, z) for moves; yaw for turns; z for takeoff/land
    rate: float = 0.0           # m/s or rad/s


class TelloDrone:
    """A DJI Tello on its SDK: discrete text commands, queued and executed over simulation time.

    Starts landed. ``takeoff`` climbs to ``drone_flight_height_m``; moves of 20-500 cm and turns of
    1-360 deg run at ``drone_speed_m_s`` / ``drone_turn_rate_deg_s`` with seeded execution errors;
    a collision stops a move early with "error: obstacle"; 15 s without a command while hovering
    makes it land by itself. Completed commands are answered "ok" or "error: ...".
    """

    def __init__(self, world, config, rng):
        self.cfg = config
        self.x, self.y, self.yaw = (float(v) for v in world.start)
        self.z = 0.0
        self.flying = False
        self._ceiling = world.ceiling_height_m
        self._obstacles = _Obstacles(world)
        self._rng = rng
        self._speed = config.drone_speed_m_s
        self._queue = collections.deque()
        self._task = None
        self._responses = []
        self._last_activity_s = 0.0
        self.collisions = 0

    def pose(self):
        """(x, y, z, yaw) of the drone body in the world (m, rad)."""
        return self.x, self.y, self.z, _wrap(self.yaw)

    @staticmethod
    def parse(text):
        """Validate a Tello SDK command; returns (name, value or None).

        Raises:
          DroneCommandError: unknown command, missing/extra/non-integer argument, or a value
            outside the Tello's limits (moves 20-500 cm, turns 1-360 deg, speed 10-100 cm/s).
        """
        if not isinstance(text, str):
            raise DroneCommandError(f"command must be text, got {type(text).__name__}")
        parts = text.strip().lower().split()
        if not parts:
            raise DroneCommandError("empty command")
        name, args = parts[0], parts[1:]
        known = list(_TELLO_PLAIN) + [f"{m} N" for m in _TELLO_MOVES] + \
            [f"{t} N" for t in _TELLO_TURNS] + ["speed N"]
        if name in _TELLO_PLAIN:
            if args:
                raise DroneCommandError(f"'{text.strip()}': '{name}' takes no argument")
            return name, None
        if name in _TELLO_MOVES:
            limits, unit, what = (20, 500), "cm", "distance"
        elif name in _TELLO_TURNS:
            limits, unit, what = (1, 360), "deg", "angle"
        elif name == "speed":
            limits, unit, what = (10, 100), "cm/s", "speed"
        else:
            raise DroneCommandError(f"'{text.strip()}': unknown command '{name}'; known: "
                                    f"{', '.join(known)}")
        if len(args) != 1:
            raise DroneCommandError(f"'{text.strip()}': '{name}' needs one integer {what} in "
                                    f"{unit} ({limits[0]}-{limits[1]})")
        try:
            value = int(args[0])
        except ValueError:
            raise DroneCommandError(f"'{text.strip()}': {what} must be an integer "
                                    f"{limits[0]}-{limits[1]} {unit}, got '{args[0]}'") from None
        if not limits[0] <= value <= limits[1]:
            raise DroneCommandError(f"'{text.strip()}': {what} must be {limits[0]}-{limits[1]} "
                                    f"{unit}, got {value}")
        return name, value

    def command(self, text, now_s):
        """Queue a validated command received at time now_s (s). Raises DroneCommandError."""
        name, value = self.parse(text)
        self._last_activity_s = now_s
        canonical = text.strip()
        if name == "stop":
            # Hover now: the running motion and anything queued are cancelled.
            if self._task is not None and self._task.kind in ("move", "turn"):
                self._responses.append((self._task.text, "error: stopped"))
                self._task = None
            while self._queue:
                self._responses.append((self._queue.popleft()[0], "error: stopped"))
            self._responses.append((canonical, "ok"))
            return
        if name == "emergency":
            # Motors off: the drone drops to the floor; nothing running or queued completes.
            if self._task is not None and self._task.text != "auto-land":
                self._responses.append((self._task.text, "error: emergency"))
            self._task = None
            while self._queue:
                self._responses.append((self._queue.popleft()[0], "error: emergency"))
            self.z = 0.0
            self.flying = False
            self._responses.append((canonical, "ok"))
            return
        self._queue.append((canonical, name, value))

    def pop_responses(self):
        """(command, response) pairs completed since the last call."""
        out, self._responses = self._responses, []
        return out

    def step(self, dt, now_s):
        """Advance by dt seconds ending at time now_s (s)."""
        remaining = dt
        while remaining > 1e-12:
            if self._task is None and not self._start_next(now_s):
                break
            remaining = self._advance(remaining, now_s)
        if (self.flying and self._task is None and not self._queue
                and now_s - self._last_activity_s >= self.cfg.drone_auto_land_s):
            self._task = _DroneTask("auto-land", "land", target=0.0,
                                    rate=self.cfg.drone_vertical_speed_m_s)

    def _start_next(self, now_s):
        """Begin the next queued command; commands that finish at once are answered here."""
        cfg = self.cfg
        while self._queue:
            text, name, value = self._queue.popleft()
            if name == "command":
                self._answer(text, "ok", now_s)
                continue
            if name == "speed":
                self._speed = value / 100.0
                self._answer(text, "ok", now_s)
                continue
            if name == "takeoff":
                if self.flying:
                    self._answer(text, "error: already flying", now_s)
                    continue
                self.flying = True
                self._task = _DroneTask(text, "takeoff", target=cfg.drone_flight_height_m,
                                        rate=cfg.drone_vertical_speed_m_s)
                return True
            if not self.flying:
                self._answer(text, "error: not flying", now_s)
                continue
            if name == "land":
                self._task = _DroneTask(text, "land", target=0.0,
                                        rate=cfg.drone_vertical_speed_m_s)
                return True
            if name in _TELLO_TURNS:
                angle = math.radians(value + self._rng.normal(0.0, cfg.drone_turn_error_deg))
                self._task = _DroneTask(text, "turn", target=self.yaw + _TELLO_TURNS[name] * angle,
                                        rate=math.radians(cfg.drone_turn_rate_deg_s))
                return True
            dz, fwd, left = _TELLO_MOVES[name]
            dist = value / 100.0 * (1.0 + self._rng.normal(0.0, cfg.drone_move_error_fraction))
            err = math.radians(self._rng.normal(0.0, cfg.drone_move_error_deg))
            if dz:
                # Vertical moves drift a little sideways instead of in heading.
                heading = self.yaw + self._rng.uniform(-math.pi, math.pi)
                side = abs(dist) * math.sin(err)
                target = (self.x + side * math.cos(heading), self.y + side * math.sin(heading),
                          self.z + dz * dist * math.cos(err))
            else:
                heading = self.yaw + math.atan2(left, fwd) + err
                target = (self.x + dist * math.cos(heading), self.y + dist * math.sin(heading),
                          self.z)
            self._task = _DroneTask(text, "move", target=target, rate=self._speed)
            return True
        return False

    def _answer(self, text, response, now_s):
        self._responses.append((text, response))
        self._last_activity_s = now_s

    def _advance(self, dt, now_s):
        """Run the current task for up to dt seconds; returns the unused time (s)."""
        task = self._task
        cfg = self.cfg
        if task.kind in ("takeoff", "land"):
            dz = task.target - self.z
            step = task.rate * dt
            if abs(dz) <= step:
                used = abs(dz) / task.rate
                self.z = task.target
                self._task = None
                if task.kind == "land":
                    self.flying = False
                if task.text != "auto-land":
                    self._answer(task.text, "ok", now_s)
                else:
                    self._last_activity_s = now_s
                return dt - used
            self.z += math.copysign(step, dz)
            return 0.0
        if task.kind == "turn":
            dyaw = task.target - self.yaw
            step = task.rate * dt
            if abs(dyaw) <= step:
                self.yaw = _wrap(task.target)
                self._task = None
                self._answer(task.text, "ok", now_s)
                return dt - abs(dyaw) / task.rate
            self.yaw += math.copysign(step, dyaw)  # unwrapped until the turn ends
            return 0.0
        # Straight move toward the target at the set speed, stopping at obstacles.
        delta = np.array(task.target) - np.array([self.x, self.y, self.z])
        dist = float(np.linalg.norm(delta))
        step = task.rate * dt
        frac = 1.0 if dist <= step else step / dist
        nx, ny, nz = np.array([self.x, self.y, self.z]) + frac * delta
        if (self._obstacles.blocked(nx, ny, cfg.drone_radius_m, nz)
                or nz > self._ceiling - cfg.drone_ceiling_margin_m
                or nz < cfg.drone_min_height_m):
            self.collisions += 1
            self._task = None
            self._answer(task.text, "error: obstacle", now_s)
            return 0.0
        self.x, self.y, self.z = float(nx), float(ny), float(nz)
        if frac >= 1.0:
            self._task = None
            self._answer(task.text, "ok", now_s)
            return dt - dist / task.rate
        return 0.0
