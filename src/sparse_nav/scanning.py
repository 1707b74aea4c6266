"""Scan motions of seed 000 as robot-independent steps, and their Tello and cmd_vel forms (ROS-free).

The initial scan turns a full circle in place, but never by rotation alone: every iteration goes a
bit back (wider view), to the right while looking right and back, to the left while looking left and
back, forward to where it started, then turns clockwise. The sideways moves give monocular SLAM the
baseline it needs to initialise and to keep triangulating while the view turns.
"""
import dataclasses
import math

# The ground robot's scan speeds. 1.3 rad/s keeps under the turn rate at which monocular tracking
# fails (the simulator's slam_max_turn_rate_rad_s, 1.75) and the robot's 1.5. On random:1-50
# (bench/bench_ground_scan.py, turn 90 deg) 0.3 m/s and 1.3 rad/s took the initial scan from 101 to
# 77 sim-s with the exit found in 37 worlds instead of 35 and 40 tracking losses instead of 46;
# in one_room (seeds 0-9, 30 deg turns) 0.5 rad/s had taken 431 sim-s, 1 rad/s 290.
GROUND_SPEED_M_S = 0.3
GROUND_TURN_RATE_RAD_S = 1.3
# The ground robot's initial scan turns 90 deg per iteration (the drone's, 30): a third of the sim
# time (101 s instead of 290 s, at 1 rad/s), which losses every 30 s leave the mission short of,
# for the exit found as often (bench_ground_scan.py: seeds 0-9 of one_room and 0-1 of
# random:1-10, 19 of 30 hits at 60 deg, 20 at 45 deg in 196 s, 20 at 30 deg; seed 0 of
# random:1-24, 16 of 24 at 60 deg in 148 s, 17 at 90 deg; one_room seeds 0-9, 10 of 10 at 90 deg).
GROUND_INITIAL_SCAN_TURN_DEG = 90.0


@dataclasses.dataclass(frozen=True)
class Step:
    """One motion in the robot frame: translation (forward_m, left_m) then a turn (ccw_deg).

    A ``reverse`` step undoes the step before it (whose negated values it carries): it turns
    first and translates after, so that both together bring the robot back where it was.
    """

    forward_m: float = 0.0
    left_m: float = 0.0
    ccw_deg: float = 0.0
    reverse: bool = False

    def undo(self):
        """The reverse step of this one."""
        return Step(-self.forward_m, -self.left_m, -self.ccw_deg, reverse=not self.reverse)


@dataclasses.dataclass
class InitialScanConfig:
    """Sizes of the seed 000 initial scan; defaults written once here."""

    back_m: float = 0.3        # a: go back for a wider view
    side_m: float = 0.3        # b, c: sideways move
    look_deg: float = 20.0     # b, c: look right/left while moving sideways
    turn_deg: float = 30.0     # e: clockwise turn per iteration
    full_turn_deg: float = 360.0

    def validate(self):
        if not 0 < self.turn_deg <= 180:
            raise ValueError(f"turn_deg must be in (0, 180], got {self.turn_deg}")
        for name in ("back_m", "side_m", "look_deg", "full_turn_deg"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")


def sway(config=None):
    """Steps a-d of one initial-scan iteration: back, right and back, left and back, forward.

    It ends where it began and gives monocular SLAM baseline without a net turn; on its own it is
    the conductor's relocalising motion after a loss.
    """
    cfg = config or InitialScanConfig()
    cfg.validate()
    right = Step(left_m=-cfg.side_m, ccw_deg=-cfg.look_deg)
    left = Step(left_m=cfg.side_m, ccw_deg=cfg.look_deg)
    return [
        Step(forward_m=-cfg.back_m),     # a: a bit back
        right, right.undo(),             # b: right and look right (cw); ccw and go left
        left, left.undo(),               # c: left and look left (ccw); cw and go right
        Step(forward_m=cfg.back_m),      # d: forward to where the iteration started
    ]


@dataclasses.dataclass
class RelocaliseConfig:
    """Sizes of the motion that starts a new SLAM map after a loss; defaults written once here."""

    baseline_m: float = 0.6    # ground robot: straight drive out and back (m)
    min_baseline_m: float = 0.2  # drive at least this far, even where the map shows less room
    standoff_m: float = 0.4    # keep this far from the wall ahead on the map (m)
    turn_deg: float = 60.0     # turn after each try, so the next sees other features

    def validate(self):
        if not 0 < self.min_baseline_m <= self.baseline_m:
            raise ValueError("need 0 < min_baseline_m <= baseline_m")
        if self.standoff_m < 0:
            raise ValueError("standoff_m must be >= 0")


def relocalise(robot, free_distance=None, config=None, sway_config=None):
    """One try of the motion that lets monocular SLAM start a new map after a loss, then a turn.

    A new map needs a baseline of about 8 % of the depth of the features the camera sees,
    with those features in view all along. The drone gets it from the sway, whose moves are
    sideways. The ground robot cannot move sideways, and its sway turns 90 deg to face each side
    (the initialiser's reference frame is lost with the view), so that its straight legs are
    0.3 m: too short beyond 4 m of depth. It drives straight instead, out and back along its
    heading, into whichever side has more room (free_distance(bearing_deg) -> free metres, as in
    random_scan; None: forward).
    """
    cfg = config or RelocaliseConfig()
    cfg.validate()
    turn = Step(ccw_deg=cfg.turn_deg)
    if robot == "drone":
        return sway(sway_config) + [turn]
    ahead = free_distance(0.0) if free_distance else math.inf
    behind = free_distance(180.0) if free_distance else 0.0
    sign = 1.0 if ahead >= behind else -1.0
    room = max(ahead, behind) - cfg.standoff_m
    distance = round(min(cfg.baseline_m, max(cfg.min_baseline_m, room)), 2)
    return [Step(forward_m=sign * distance), Step(forward_m=-sign * distance), turn]


def initial_scan(config=None):
    """The seed 000 initial scan as a list of Steps (a, b, c, d, e per iteration until a full turn)."""
    cfg = config or InitialScanConfig()
    cfg.validate()
    steps = []
    turned = 0.0
    while turned < cfg.full_turn_deg - 1e-9:
        turn = min(cfg.turn_deg, cfg.full_turn_deg - turned)
        steps += sway(cfg) + [Step(ccw_deg=-turn)]   # e: look a bit to the right
        turned += turn
    return steps


@dataclasses.dataclass
class WallScanConfig:
    """Sizes of the seed 000 wall scan and its random variant; defaults written once here."""

    standoff_m: float = 1.2     # stop this far before a wall: closer, too few features are in view
    min_move_m: float = 0.2     # shorter approaches are skipped (the Tello's smallest move)
    max_move_m: float = 3.0
    circle_turn_deg: float = 60.0
    circle_sway_m: float = 0.2  # forward, then back, with every turn: parallax while turning

    def validate(self):
        if not 0 < self.circle_turn_deg <= 180:
            raise ValueError(f"circle_turn_deg must be in (0, 180], got {self.circle_turn_deg}")
        if not 0 < self.min_move_m <= self.max_move_m:
            raise ValueError("need 0 < min_move_m <= max_move_m")
        for name in ("standoff_m", "circle_sway_m"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")


def circular_scan(config=None):
    """Seed 000 step 2b: a full circle of turns, each with a short sway forward and back."""
    cfg = config or WallScanConfig()
    cfg.validate()
    steps, turned = [], 0.0
    while turned < 360.0 - 1e-9:
        turn = min(cfg.circle_turn_deg, 360.0 - turned)
        if cfg.circle_sway_m:
            steps += [Step(forward_m=cfg.circle_sway_m), Step(forward_m=-cfg.circle_sway_m)]
        steps.append(Step(ccw_deg=-turn))
        turned += turn
    return steps


def _approach(bearing_deg, free_m, cfg):
    """Turn to a bearing, go up to the wall, scan a circle there, come back and turn back."""
    distance = min(free_m - cfg.standoff_m, cfg.max_move_m)
    if distance < cfg.min_move_m:
        return []
    turn = Step(ccw_deg=bearing_deg) if abs(bearing_deg) >= 1.0 else None
    go = Step(forward_m=distance)
    steps = ([turn] if turn else []) + [go] + circular_scan(cfg) + [go.undo()]
    return steps + ([turn.undo()] if turn else [])


def wall_scan(free_distances, config=None):
    """Seed 000 step 2: for each wall, go to it and scan a circle; back to the start after each.

    free_distances: (bearing_deg counter-clockwise from the current heading, free distance m to
    the wall in that direction), e.g. measured on the occupancy grid. Walls too close are skipped.
    """
    cfg = config or WallScanConfig()
    cfg.validate()
    steps = []
    for bearing_deg, free_m in free_distances:
        if math.isfinite(bearing_deg) and math.isfinite(free_m):
            steps += _approach(math.remainder(bearing_deg, 360.0), free_m, cfg)
    return steps


def random_scan(rng, free_distance, config=None):
    """One round of seed 000's randomised variant: a random move, then a circular scan.

    rng: a numpy Generator (seeded by the caller); free_distance(bearing_deg) -> free metres from
    the current position along that bearing, so the move never aims into a near wall (without
    room for a move the robot only scans). The robot stays where it went: the next round scans
    from there.
    """
    cfg = config or WallScanConfig()
    cfg.validate()
    bearing = float(rng.uniform(-180.0, 180.0))
    room = min(free_distance(bearing) - cfg.standoff_m, cfg.max_move_m)
    steps = []
    if room >= cfg.min_move_m:
        distance = round(float(rng.uniform(cfg.min_move_m, room)), 2)
        steps = [Step(ccw_deg=round(bearing)), Step(forward_m=distance)]
    return steps + circular_scan(cfg)


def pose_after(pose, steps):
    """Where Steps take a robot from pose (x_m, y_m, yaw_rad): each translates in the robot
    frame, then turns (a reverse step turns first)."""
    x, y, yaw = pose
    for step in steps:
        if step.reverse:
            yaw += math.radians(step.ccw_deg)
        x += step.forward_m * math.cos(yaw) - step.left_m * math.sin(yaw)
        y += step.forward_m * math.sin(yaw) + step.left_m * math.cos(yaw)
        if not step.reverse:
            yaw += math.radians(step.ccw_deg)
    return x, y, math.remainder(yaw, 2 * math.pi)


def steps_to_pose(start, target, min_move_m=0.02, min_turn_deg=1.0):
    """Steps that take a unicycle from pose start to pose target, both (x_m, y_m, yaw_rad) in
    one frame that holds still (wheel odometry): turn to the line between them, drive it, turn to
    the target's heading. A target behind the robot is backed into: a turn on the spot of more
    than 90 deg sweeps the camera over what SLAM may not have mapped."""
    (x, y, yaw), (tx, ty, tyaw) = start, target
    distance = math.hypot(tx - x, ty - y)
    steps, heading = [], yaw
    if distance >= min_move_m:
        face = math.remainder(math.atan2(ty - y, tx - x) - yaw, 2 * math.pi)
        sign = 1.0
        if abs(face) > math.pi / 2:
            face, sign = math.remainder(face + math.pi, 2 * math.pi), -1.0
        if abs(math.degrees(face)) >= min_turn_deg:
            steps.append(Step(ccw_deg=math.degrees(face)))
        steps.append(Step(forward_m=sign * distance))
        heading = yaw + face
    turn = math.degrees(math.remainder(tyaw - heading, 2 * math.pi))
    if abs(turn) >= min_turn_deg:
        steps.append(Step(ccw_deg=turn))
    return steps


def _tello_move(value_cm, positive, negative):
    return f"{positive if value_cm > 0 else negative} {abs(value_cm)}"


def to_tello_commands(steps, min_move_cm=20, max_move_cm=500):
    """Tello SDK commands for Steps; moves are rounded to whole cm within the Tello's limits."""
    commands = []
    for step in steps:
        moves = []
        for value_m, pos, neg in ((step.forward_m, "forward", "back"),
                                  (step.left_m, "left", "right")):
            cm = int(round(value_m * 100))
            if cm == 0:
                continue
            if not min_move_cm <= abs(cm) <= max_move_cm:
                raise ValueError(f"move of {cm} cm is outside the Tello's {min_move_cm}-"
                                 f"{max_move_cm} cm")
            moves.append(_tello_move(cm, pos, neg))
        deg = int(round(step.ccw_deg))
        turns = [f"{'ccw' if deg > 0 else 'cw'} {abs(deg)}"] if deg else []
        commands += turns + moves if step.reverse else moves + turns
    return commands


def to_velocity_segments(steps, speed_m_s=GROUND_SPEED_M_S, turn_rate_rad_s=GROUND_TURN_RATE_RAD_S,
                         side_face_deg=90.0):
    """(linear_m_s, angular_rad_s, duration_s) segments for a unicycle executing Steps.

    A unicycle cannot move sideways: a sideways step turns on the spot to face the side by
    ``side_face_deg``, drives the step's length, and turns on to the step's heading; its reverse
    step retraces that exactly. The camera so moves sideways as far as the drone's does, which is
    the baseline monocular SLAM triangulates far points with: an arc of the step's length moved
    it ~5 cm sideways for 0.3 m and 20 deg, and the points seen through a door then came out as
    streaks along the line of sight (bench/bench_ground_scan.py, one_room, seeds 0-9: the exit
    ranked first after 1 of 10 initial scans with arcs, 7 of 10 with this; median points mapped
    beyond the exit's wall 87 -> 159; the scan took 431 s of sim time instead of 163 s at 0.5 rad/s).
    """
    if not 0.0 < side_face_deg <= 90.0:
        raise ValueError(f"side_face_deg must be in (0, 90], got {side_face_deg}")
    segments = []

    def turn(angle):
        if angle:
            segments.append((0.0, math.copysign(turn_rate_rad_s, angle),
                             abs(angle) / turn_rate_rad_s))

    for step in steps:
        if step.forward_m:
            segments.append((math.copysign(speed_m_s, step.forward_m), 0.0,
                             abs(step.forward_m) / speed_m_s))
        if step.left_m:
            face = math.copysign(math.radians(side_face_deg), step.left_m)
            rest = math.radians(step.ccw_deg) - face
            drive = (-speed_m_s if step.reverse else speed_m_s, 0.0, abs(step.left_m) / speed_m_s)
            # A reverse step carries the negated values: turning by rest, backing and turning by
            # face retraces the step it undoes.
            first, last = (rest, face) if step.reverse else (face, rest)
            turn(first)
            segments.append(drive)
            turn(last)
        elif step.ccw_deg:
            angle = math.radians(step.ccw_deg)
            duration = abs(angle) / turn_rate_rad_s
            # A little forward motion during a turn keeps parallax for monocular tracking.
            segments.append((0.05, angle / duration, duration))
    return segments
