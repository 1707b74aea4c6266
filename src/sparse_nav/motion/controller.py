"""The reactive layer (ROS-free): path following, go-to-wall and the staleness guard.

For a ground robot each control step gives a velocity (v, w); for a DJI Tello it gives the next
discrete SDK command (seed 001: signed angle rounded to whole degrees, then a forward move),
within the Tello's limits. Whenever the pose, the map alignment or the path is older than its
timeout, or SLAM tracking is lost, the step says stop: zero velocity, no further drone command.
"""
import collections
import dataclasses
import math

import numpy as np

from sparse_nav.exit_finder.geometry import segment_distances
from sparse_nav.motion.primitive import PathFollower

IDLE, FOLLOWING, REACHED, STOPPED_STALE, STOPPED_LOST, WALL_SEEKING, WALL_REACHED, FAILED = range(8)
STATE_NAMES = {IDLE: "IDLE", FOLLOWING: "FOLLOWING", REACHED: "REACHED",
               STOPPED_STALE: "STOPPED_STALE", STOPPED_LOST: "STOPPED_LOST",
               WALL_SEEKING: "WALL_SEEKING", WALL_REACHED: "WALL_REACHED", FAILED: "FAILED"}

# DJI Tello SDK limits, as the simulator (sim/robots.py TelloDrone.parse) enforces them.
TELLO_MIN_MOVE_CM, TELLO_MAX_MOVE_CM = 20, 500
TELLO_MIN_TURN_DEG, TELLO_MAX_TURN_DEG = 1, 360


@dataclasses.dataclass
class MotionConfig:
    """Every parameter of the motion layer; defaults are written here once."""

    robot: str = "ground"              # "ground" (cmd_vel) or "drone" (Tello commands)
    lookahead_m: float = 0.5           # look-ahead distance along the path
    goal_tolerance_m: float = 0.15     # the end of the path is reached within this (ground)
    max_linear_m_s: float = 0.3
    min_linear_m_s: float = 0.05       # forward creep while turning: monocular SLAM needs parallax
    max_angular_rad_s: float = 0.8
    angular_gain: float = 1.5          # rad/s of turn rate per rad of heading error
    turn_in_place_deg: float = 60.0    # above this heading error only the creep goes forward
    slow_down_m: float = 0.5           # the speed ramps down within this distance of the end
    drone_goal_tolerance_m: float = 0.3    # >= the Tello's 20 cm smallest move
    drone_max_step_cm: int = 100       # longest forward move per command; the pose is read again
    drone_min_turn_deg: int = 8        # smaller heading errors are left uncorrected
    pose_timeout_s: float = 0.25       # TF odom -> base_link, 20 Hz: twice its period + slack
    map_timeout_s: float = 0.25        # TF map -> odom (slam_bridge, 20 Hz)
    path_timeout_s: float = 0.5        # navigator/path, 5 Hz: twice its period + slack
    tracked_timeout_s: float = 0.5     # tracked points older than this count as none seen
    wall_min_tracked_points: int = 40  # go-to-wall: fewer tracked points is a miss
    wall_max_fails: int = 3            # consecutive misses that mean the wall is reached (seed 000)
    wall_speed_m_s: float = 0.15       # ground robot's approach speed
    wall_step_cm: int = 30             # drone's approach step
    wall_back_off_m: float = 0.3       # backs off this far once at the wall
    wall_max_distance_m: float = 6.0   # gives up when no wall was met within this
    stall_fraction: float = 0.3        # ground: advancing less than this share of the commanded
    #                                    distance (wheel odometry) is a stall: pushing on something
    stall_timeout_s: float = 3.0       # following: less than stall_fraction of the commanded
    #                                    distance over this window means blocked: stop
    route_tolerance_m: float = 0.1     # a blocked robot waits for a path whose route (after its
    #                                    first point, the robot) leaves the old one by more
    bump_max_tries: int = 4            # blocked while following: tries shifted sideways at one
    #                                    spot before it stops (FAILED); sides alternate, first away
    #                                    from the side the robot strayed to or the path bends
    #                                    toward, and the shift grows by bump_shift_m every two
    bump_back_off_m: float = 0.3       # each try starts by backing off this far, room to turn;
    #                                    blocked farther than this from the last spot is a new one
    bump_shift_m: float = 0.15         # it then aims this far beside the path ...
    bump_radius_m: float = 1.5         # ... while the look-ahead point is within this of the spot
    #                                    (a recess and its door: both jambs are passed shifted)
    bump_speed_m_s: float = 0.15       # ground robot's backing-off speed

    def validate(self):
        if self.robot not in ("ground", "drone"):
            raise ValueError(f"robot must be 'ground' or 'drone', got {self.robot!r}")
        for name in ("lookahead_m", "goal_tolerance_m", "max_linear_m_s", "max_angular_rad_s",
                     "angular_gain", "slow_down_m", "pose_timeout_s", "map_timeout_s",
                     "path_timeout_s", "tracked_timeout_s", "wall_speed_m_s",
                     "wall_max_distance_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.min_linear_m_s <= self.max_linear_m_s:
            raise ValueError("min_linear_m_s must be in [0, max_linear_m_s]")
        if not 0 < self.turn_in_place_deg <= 180:
            raise ValueError("turn_in_place_deg must be in (0, 180]")
        if not TELLO_MIN_MOVE_CM <= self.drone_max_step_cm <= TELLO_MAX_MOVE_CM:
            raise ValueError(f"drone_max_step_cm must be within the Tello's "
                             f"{TELLO_MIN_MOVE_CM}-{TELLO_MAX_MOVE_CM} cm")
        if not TELLO_MIN_MOVE_CM <= self.wall_step_cm <= TELLO_MAX_MOVE_CM:
            raise ValueError(f"wall_step_cm must be within {TELLO_MIN_MOVE_CM}-"
                             f"{TELLO_MAX_MOVE_CM} cm")
        if not TELLO_MIN_TURN_DEG <= self.drone_min_turn_deg <= 180:
            raise ValueError("drone_min_turn_deg must be in [1, 180]")
        # Closer than the smallest move the Tello can make, the end counts as reached.
        if self.drone_goal_tolerance_m < TELLO_MIN_MOVE_CM / 100.0:
            raise ValueError("drone_goal_tolerance_m must be >= 0.2 (the Tello's smallest move)")
        if self.robot == "drone" and self.lookahead_m < TELLO_MIN_MOVE_CM / 100.0:
            raise ValueError("lookahead_m must be >= 0.2 for the drone")
        if self.wall_min_tracked_points < 0 or self.wall_max_fails < 1:
            raise ValueError("wall_min_tracked_points must be >= 0, wall_max_fails >= 1")
        if self.wall_back_off_m < 0:
            raise ValueError("wall_back_off_m must be >= 0")
        if not 0 <= self.stall_fraction < 1:
            raise ValueError("stall_fraction must be in [0, 1)")
        if not self.stall_timeout_s > 0:
            raise ValueError("stall_timeout_s must be > 0")
        if not (math.isfinite(self.route_tolerance_m) and self.route_tolerance_m >= 0):
            raise ValueError("route_tolerance_m must be finite and >= 0")
        if self.bump_max_tries < 0:
            raise ValueError("bump_max_tries must be >= 0")
        for name in ("bump_back_off_m", "bump_shift_m"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {getattr(self, name)}")
        for name in ("bump_radius_m", "bump_speed_m_s"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ValueError(f"{name} must be finite and > 0, got {getattr(self, name)}")


class StalenessGuard:
    """Latest times of named inputs, and which of them are older than their timeouts."""

    def __init__(self, timeouts_s):
        self.timeouts_s = dict(timeouts_s)
        self.stamps = {name: None for name in self.timeouts_s}

    def mark(self, name, stamp_s):
        self.stamps[name] = stamp_s

    def forget(self, name):
        self.stamps[name] = None

    def stale(self, now_s):
        """[(name, age_s or None)] of the inputs never seen or older than their timeout."""
        out = []
        for name, timeout in self.timeouts_s.items():
            stamp = self.stamps[name]
            if stamp is None:
                out.append((name, None))
            elif now_s - stamp > timeout:
                out.append((name, now_s - stamp))
        return out


def tello_command(heading_error_rad, distance_m, min_turn_deg, max_step_cm):
    """Seed 001's discrete conversion: a turn of the rounded signed angle if it is at least
    ``min_turn_deg``, else a forward move of the distance rounded to cm, at most ``max_step_cm``,
    at least the Tello's 20 cm. Always within the Tello SDK's limits."""
    deg = int(round(math.degrees(heading_error_rad)))
    if abs(deg) >= max(min_turn_deg, TELLO_MIN_TURN_DEG):
        deg = max(-180, min(180, deg))
        return f"ccw {deg}" if deg > 0 else f"cw {-deg}"
    cm = int(round(distance_m * 100.0))
    cm = max(TELLO_MIN_MOVE_CM, min(cm, max_step_cm, TELLO_MAX_MOVE_CM))
    return f"forward {cm}"


class WallSeeker:
    """Seed 000's go-to-wall: forward until ORB-SLAM stops seeing key points, with a fail counter.

    A miss is a step with fewer than ``wall_min_tracked_points`` tracked points (or none recent),
    or, where odometry measures the advance, a step that advanced less than
    ``stall_fraction`` of what was commanded (the robot pushes against the wall while its
    camera, too close to focus on it, may still track points elsewhere). ``wall_max_fails``
    consecutive misses mean the wall is reached, and a single good step resets the counter, so
    momentary misses do not stop the approach early. A blocked move (a drone's "error: obstacle")
    is the wall at once. Then the robot backs off ``wall_back_off_m``.
    """

    SEEKING, BACKING, DONE = "seeking", "backing", "done"

    def __init__(self, cfg):
        self.cfg = cfg
        self.phase = self.DONE
        self.fails = 0
        self.travelled_m = 0.0
        self.backed_m = 0.0
        self.success = False
        self.reason = ""
        self._stalled = False

    def start(self):
        self.phase, self.fails, self.travelled_m, self.backed_m = self.SEEKING, 0, 0.0, 0.0
        self.success, self.reason, self._stalled = False, "", False

    def observe(self, n_tracked):
        """Count one approach step's view (None: no recent tracked points)."""
        if self.phase != self.SEEKING:
            return
        lost = n_tracked is None or n_tracked < self.cfg.wall_min_tracked_points
        why = "features lost" if lost else "stalled"
        if lost or self._stalled:
            self.fails += 1
        else:
            self.fails = 0
        self._stalled = False
        if self.fails >= self.cfg.wall_max_fails:
            self._at_wall(f"{why}, {self.fails} misses in a row")
        elif self.travelled_m >= self.cfg.wall_max_distance_m:
            self.phase, self.success = self.DONE, False
            self.reason = f"no wall within {self.cfg.wall_max_distance_m:.1f} m"

    def blocked(self):
        """The last forward move hit something."""
        if self.phase == self.SEEKING:
            self._at_wall("blocked")

    def moved(self, commanded_m, measured_m=None):
        """Distance commanded since the last call (m, signed: negative backwards) and, when
        odometry measures it, the distance actually advanced along the heading (m)."""
        if self.phase == self.SEEKING:
            advanced = commanded_m if measured_m is None else measured_m
            self.travelled_m += max(advanced, 0.0)
            if measured_m is not None and commanded_m > 1e-6:
                self._stalled = measured_m < self.cfg.stall_fraction * commanded_m
        elif self.phase == self.BACKING:
            # Dead reckoning: backing off must end even if something behind holds the robot.
            self.backed_m += max(-commanded_m, 0.0)
            if self.backed_m >= self.cfg.wall_back_off_m - 1e-9:
                self.phase, self.success = self.DONE, True

    def _at_wall(self, why):
        self.reason = f"wall reached after {self.travelled_m:.2f} m ({why})"
        self.phase = self.BACKING
        if self.cfg.wall_back_off_m <= 0:
            self.phase, self.success = self.DONE, True


@dataclasses.dataclass
class Decision:
    """What the robot does this control step."""

    state: int
    reason: str
    linear_m_s: float = 0.0
    angular_rad_s: float = 0.0
    command: str = None              # the next Tello command (drone), or None
    moving: bool = False             # False: zero velocity / no further command
    distance_to_goal_m: float = float("nan")
    heading_error_deg: float = float("nan")


class MotionController:
    """One object owning the follower, the wall seeker and the guard for one robot."""

    def __init__(self, config=None):
        self.cfg = config or MotionConfig()
        self.cfg.validate()
        self.follower = PathFollower(self.cfg.lookahead_m, self.goal_tolerance_m)
        self.wall = WallSeeker(self.cfg)
        self.guard = StalenessGuard({"pose": self.cfg.pose_timeout_s,
                                     "map": self.cfg.map_timeout_s,
                                     "path": self.cfg.path_timeout_s})
        self.pose = None
        self.lost = False
        self.lost_reason = ""
        self.map_index = None
        self.map_switch_s = -math.inf
        self.mode = "path"
        self.tracked = None              # (count, stamp_s)
        self.idle_reason = "no path yet"
        self.blocked = ""                # why the path cannot be followed further, or ""
        self._progress = collections.deque()   # (stamp_s, commanded_m, measured_m)
        self._last_linear = 0.0
        self._bump = None                # (xy where blocked, side +1 left / -1 right, why)
        self._bump_tries = 0
        self._backing_left_m = 0.0

    @property
    def goal_tolerance_m(self):
        return self.cfg.drone_goal_tolerance_m if self.cfg.robot == "drone" \
            else self.cfg.goal_tolerance_m

    def set_pose(self, x, y, yaw, pose_stamp_s, map_stamp_s):
        """Robot pose in the map frame (m, rad) with the stamps of odom->base and map->odom."""
        values = (x, y, yaw, pose_stamp_s, map_stamp_s)
        if not all(math.isfinite(v) for v in values):
            raise ValueError("pose has non-finite values")
        self.pose = (x, y, yaw)
        self.guard.mark("pose", pose_stamp_s)
        self.guard.mark("map", map_stamp_s)

    def set_path(self, points, stamp_s, now_s):
        """A new path (N, 2) m in the map frame, planned at ``stamp_s``, received at ``now_s``.

        An empty path stops the robot (the navigator has none). A path planned before the last
        SLAM map switch is in the old map's coordinates and is refused. Raises ValueError for a
        malformed path; the previous path is then kept.
        """
        if len(points) == 0:
            self.follower.clear()
            self.guard.forget("path")
            self.idle_reason = "empty path (the navigator has none)"
            return
        if stamp_s < self.map_switch_s:
            raise ValueError(f"path planned at {stamp_s:.2f} s, before the SLAM map switch at "
                             f"{self.map_switch_s:.2f} s")
        before = self.follower.points
        tolerance = self.cfg.route_tolerance_m
        if self.follower.set_path(points) and not _same_route(before, self.follower.points,
                                                               tolerance):
            if self.blocked:
                self._end_bump()     # a new route after the tries: it gets tries of its own
            self._unblock()
        self.guard.mark("path", now_s)
        self.mode = "path"

    def set_slam_state(self, lost, map_index, stamp_s, reason=""):
        """SLAM health; a change of map index invalidates the path (old map coordinates)."""
        self.lost, self.lost_reason = lost, reason
        if lost:
            return
        if self.map_index is not None and map_index != self.map_index:
            self.map_switch_s = stamp_s
            self._end_bump()
            self.follower.clear()
            self.guard.forget("path")
            self.idle_reason = f"SLAM map switched to {map_index}: waiting for a new path"
        self.map_index = map_index

    def path_blocked(self, reason):
        """Following a path, the robot met an obstacle the map does not show (a drone's "error:
        obstacle"): see _blocked_by."""
        if self.mode == "path" and self.follower.points is not None:
            self._blocked_by(reason)

    def follow_moved(self, commanded_m, measured_m, now_s):
        """Ground robot following a path: forward distance commanded since the last step and the
        distance the wheel odometry advanced (m). Less than stall_fraction of the commanded
        distance over the last stall_timeout_s means blocked (see _blocked_by)."""
        if self._backing_left_m > 0:
            # Dead reckoning, as go-to-wall's backing off: it must end even if held from behind.
            self._backing_left_m -= max(-commanded_m, 0.0)
            self._progress.clear()
            return
        if self.mode != "path" or self.follower.points is None or measured_m is None:
            self._progress.clear()
            return
        if self._last_linear <= self.cfg.min_linear_m_s + 1e-9:
            # Turning with the creep may push on a wall until the robot faces away: not a stall.
            commanded_m = measured_m = 0.0
        self._progress.append((now_s, max(commanded_m, 0.0), measured_m))
        while self._progress and now_s - self._progress[0][0] > self.cfg.stall_timeout_s:
            self._progress.popleft()
        span = now_s - self._progress[0][0]
        commanded = sum(c for _, c, _ in self._progress)
        measured = sum(m for _, _, m in self._progress)
        if span >= 0.9 * self.cfg.stall_timeout_s and commanded > 0.02 \
                and measured < self.cfg.stall_fraction * commanded:
            self._blocked_by(f"advanced {measured:.2f} m of {commanded:.2f} m commanded in "
                             f"{span:.1f} s")

    def _blocked_by(self, why):
        """Something the map does not show stopped the robot on its path, most often a door jamb
        that a path through a narrow, thickly mapped door passes too closely. While tries are
        left at that spot the robot backs off and aims beside the path past it, away from the
        side it strayed to first (a robot cutting a corner meets the jamb on the inside), the
        other side next, the shift growing (see MotionConfig); then it stops (FAILED) until a
        path with another route arrives."""
        self._progress.clear()
        if self._backing_left_m > 0 or self.blocked or self.pose is None:
            return
        xy = np.array(self.pose[:2])
        if self._bump is None:
            side = -self.follower.side_of(xy) or 1     # neither side stands out: left first
        elif np.linalg.norm(xy - self._bump[0]) > self.cfg.bump_back_off_m + 1e-9:
            # Past the last spot: the side that got it there goes first at the new one.
            side, self._bump_tries = self._bump[1], 0
        else:
            side = -self._bump[1]
        if self._bump_tries >= self.cfg.bump_max_tries:
            tried = f" ({self._bump_tries} shifted tries failed)" if self._bump_tries else ""
            self.blocked = f"blocked: {why}{tried}; waiting for a different path"
            return
        self._bump_tries += 1
        self._bump = (xy, side, why)
        self._backing_left_m = self.cfg.bump_back_off_m
        self.follower.shift(xy, self.cfg.bump_radius_m, side * self._bump_shift_now())

    def _bump_shift_now(self):
        """bump_shift_m for the first two tries at a spot (one each side), twice it for the
        next two, and so on."""
        return self.cfg.bump_shift_m * (1 + (self._bump_tries - 1) // 2)

    def _end_bump(self):
        self._bump, self._bump_tries, self._backing_left_m = None, 0, 0.0
        self.follower.shift(None, 0.0, 0.0)

    def _unblock(self):
        self.blocked = ""
        self._progress.clear()

    def set_tracked(self, n_points, stamp_s):
        self.tracked = (int(n_points), stamp_s)

    def start_wall(self):
        """Begin go-to-wall in the current heading (the path, if any, is dropped)."""
        self._unblock()
        self._end_bump()
        self.follower.clear()
        self.guard.forget("path")
        self.mode = "wall"
        self.wall.start()

    def stop(self, reason="stopped on request"):
        self._unblock()
        self._end_bump()
        self.follower.clear()
        self.guard.forget("path")
        self.mode = "path"
        self.wall.phase = WallSeeker.DONE
        self.idle_reason = reason

    def wall_moved(self, commanded_m, measured_m=None):
        """Go-to-wall progress since the last step: commanded and measured distance (m)."""
        self.wall.moved(commanded_m, measured_m)

    def wall_blocked(self):
        self.wall.blocked()

    def step(self, now_s):
        """The Decision for this control step at time ``now_s`` (s)."""
        if self.mode == "wall":
            return self._wall_step(now_s)
        if self.follower.points is None:
            return Decision(IDLE, self.idle_reason)
        if self.lost:
            return Decision(STOPPED_LOST, f"SLAM lost: {self.lost_reason}".rstrip(": "))
        if self.blocked:
            return Decision(FAILED, self.blocked)
        stale = self.guard.stale(now_s)
        if stale:
            return Decision(STOPPED_STALE, "stale input: " + ", ".join(
                f"{name} never received" if age is None else f"{name} {age:.2f} s old"
                for name, age in stale))
        if self._bump is not None:
            recovering = self._bump_step()
            if recovering is not None:
                return recovering
        target = self.follower.target(*self.pose)
        heading_deg = math.degrees(target.heading_error)
        if target.reached:
            return Decision(REACHED, f"within {target.to_end_m:.2f} m of the path's end",
                            distance_to_goal_m=target.to_end_m, heading_error_deg=heading_deg)
        decision = Decision(FOLLOWING, "following the path", moving=True,
                            distance_to_goal_m=target.remaining_m,
                            heading_error_deg=heading_deg)
        if self.cfg.robot == "drone":
            distance = target.to_end_m if target.is_end else target.distance
            decision.command = tello_command(target.heading_error, distance,
                                             self.cfg.drone_min_turn_deg,
                                             self.cfg.drone_max_step_cm)
            return decision
        decision.linear_m_s, decision.angular_rad_s = self._velocity(target)
        self._last_linear = decision.linear_m_s
        return decision

    def _bump_step(self):
        """The backing-off Decision of a try, or None to follow the (shifted) path. The try ends
        once the robot is bump_radius_m away from where it was blocked (through, or elsewhere)."""
        xy, side, why = self._bump
        if self._backing_left_m <= 0:
            if math.dist(self.pose[:2], xy) > self.cfg.bump_radius_m:
                self._end_bump()
            return None
        toward = "left" if side > 0 else "right"
        decision = Decision(FOLLOWING, f"blocked ({why}): backing off, then "
                            f"{self._bump_shift_now():.2f} m to the {toward} of the path (try "
                            f"{self._bump_tries} of {self.cfg.bump_max_tries})", moving=True)
        if self.cfg.robot == "drone":
            decision.command = "back %d" % max(TELLO_MIN_MOVE_CM, min(
                TELLO_MAX_MOVE_CM, int(round(self._backing_left_m * 100))))
            self._backing_left_m = 0.0       # one Tello command carries the whole move
        else:
            decision.linear_m_s = -self.cfg.bump_speed_m_s
            self._last_linear = decision.linear_m_s
        return decision

    def _velocity(self, target):
        cfg = self.cfg
        err = target.heading_error
        w = max(-cfg.max_angular_rad_s, min(cfg.max_angular_rad_s, cfg.angular_gain * err))
        if abs(err) > math.radians(cfg.turn_in_place_deg):
            return cfg.min_linear_m_s, w
        v = cfg.max_linear_m_s * math.cos(err)
        v = min(v, cfg.max_linear_m_s * target.to_end_m / cfg.slow_down_m)
        return max(cfg.min_linear_m_s, v), w

    def _wall_step(self, now_s):
        cfg, wall = self.cfg, self.wall
        if wall.phase == WallSeeker.SEEKING:
            n = None
            if self.tracked is not None and now_s - self.tracked[1] <= cfg.tracked_timeout_s:
                n = self.tracked[0]
            wall.observe(n)
        if wall.phase == WallSeeker.SEEKING:
            decision = Decision(WALL_SEEKING, f"approaching the wall ({wall.fails} misses, "
                                f"{wall.travelled_m:.2f} m)", moving=True)
            if cfg.robot == "drone":
                decision.command = f"forward {cfg.wall_step_cm}"
            else:
                decision.linear_m_s = cfg.wall_speed_m_s
            return decision
        if wall.phase == WallSeeker.BACKING:
            decision = Decision(WALL_SEEKING, wall.reason + ", backing off", moving=True)
            if cfg.robot == "drone":
                remaining = cfg.wall_back_off_m - wall.backed_m
                decision.command = "back %d" % max(TELLO_MIN_MOVE_CM, min(
                    TELLO_MAX_MOVE_CM, int(round(remaining * 100))))
            else:
                decision.linear_m_s = -cfg.wall_speed_m_s
            return decision
        # The outcome stays until a new path, go-to-wall or stop, so nobody misses it.
        return Decision(WALL_REACHED if wall.success else FAILED, wall.reason)


def _same_route(old, new, tolerance_m):
    """True when every point of ``new`` after its first lies within tolerance_m of the polyline
    ``old`` and both end together. The navigator starts each path at the robot, so a blocked
    robot's republished path differs in its first point (pose jitter) but follows the same route."""
    if old is None or new is None or len(new) < 2:
        return False
    if np.hypot(*(new[-1] - old[-1])) > tolerance_m:
        return False
    pts = new[1:]
    if len(old) < 2:
        return bool(np.all(np.hypot(*(pts - old[0]).T) <= tolerance_m))
    return bool(np.all(segment_distances(pts, old[:-1], old[1:]).min(axis=1) <= tolerance_m))
