"""The simulator core: a world, a robot, its camera and an ORB-SLAM3 monocular emulator, stepped on
simulation time. ROS-free; the ``sim`` node publishes its outputs.

Frames: world (m, z up, REP-103); base (x forward, y left, z up) at the robot's footprint centre
(ground robot) or body centre (drone); camera optical (x right, y down, z forward).
"""
import dataclasses
import math

import numpy as np

from sparse_nav.sim.camera import Camera
from sparse_nav.sim.robots import GroundRobot, TelloDrone
from sparse_nav.sim.slam import MonocularSlam

# Rotation from the optical frame to the base frame: optical z (forward) = base x, optical x
# (right) = -base y, optical y (down) = -base z.
_R_BASE_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclasses.dataclass
class SimConfig:
    """Every simulator parameter, with its default written once here (units in the names)."""

    robot: str = "ground"                      # "ground" (cmd_vel) or "drone" (Tello commands)
    seed: int = 0                              # seeds every random draw of a run
    physics_dt_s: float = 0.01                 # robot integration step

    # Camera (DJI Tello: 82.6 deg diagonal FOV, 960x720; here horizontal and vertical).
    camera_hfov_deg: float = 82.0
    camera_vfov_deg: float = 52.0
    camera_min_range_m: float = 0.3
    camera_max_range_m: float = 8.0
    camera_rate_hz: float = 15.0
    camera_width_px: int = 960                 # image width: focal length from the hfov
    camera_detection_prob: float = 0.9         # a visible feature is detected in a frame
    ground_camera_height_m: float = 0.5        # above the floor
    ground_camera_forward_m: float = 0.1       # ahead of the turning axis, at the robot's front
    drone_camera_forward_m: float = 0.05       # Tello: camera at the nose, near the yaw axis

    # ORB-SLAM3 monocular emulation.
    slam_init_min_parallax: float = 0.08       # baseline / median shared-feature depth
    slam_init_min_shared: int = 50             # features shared with the reference frame
    slam_min_tracked: int = 25                 # fewer tracked map points: tracking lost
    slam_pose_min_tracked: int = 10            # fewer: not even the pose is found (see below)
    slam_reloc_min_tracked: int = 40           # map points needed to relocalise
    slam_new_point_min_parallax_deg: float = 1.0   # triangulation angle for a new map point
    slam_depth_noise_px: float = 1.5           # keypoint noise at pyramid level 0 (px); depth sigma
    #                                            = depth^2 * this / (focal_px * baseline)
    slam_min_relative_depth_noise: float = 0.07  # floor of that sigma / depth
    slam_max_relative_depth_noise: float = 0.3  # cap of that sigma / depth
    slam_refine_parallax_factor: float = 1.5   # re-estimate a point once its views span this
    #                                            many times its triangulation angle (local BA)
    slam_lateral_noise_rad: float = 0.002      # sigma across the ray = this * depth (m)
    slam_outlier_fraction: float = 0.025       # share of new points that are spurious
    slam_outlier_far_fraction: float = 0.3     # of those, share placed far behind the surface
    slam_scale_range_m_per_unit: tuple = (0.2, 5.0)   # log-uniform metres per SLAM unit
    slam_scale_drift_per_sqrt_m: float = 0.01  # random-walk sigma of log scale per sqrt(metre)
    slam_max_turn_rate_rad_s: float = 1.75     # faster turns blur the image: tracking lost
    slam_recently_lost_s: float = 3.0          # RECENTLY_LOST before LOST (ORB-SLAM3 monocular:
    #                                            3 s of image time, Tracking.cc)
    slam_young_map_s: float = 3.0              # a map younger than this is LOST outright when
    #                                            the pose is not found (fewer than
    #                                            slam_pose_min_tracked, or a fast turn), no
    #                                            RECENTLY_LOST (ORB-SLAM3: 10 keyframes or fewer)
    slam_lost_frames_before_new_map: int = 1   # LOST frames before the atlas starts a new map
    slam_merge_min_shared: int = 40            # old-map points seen to merge back into it
    slam_merge_min_map_age_s: float = 3.0      # place recognition needs a few keyframes first
    slam_pose_noise_m: float = 0.005           # jitter of reported camera positions (m)
    slam_pose_noise_deg: float = 0.1           # jitter of reported camera orientations (deg)
    force_loss_at_s: list = dataclasses.field(default_factory=list)  # tracking forced LOST
    #                                            (at the first tracking frame from each time)
    force_loss_duration_s: float = 0.0         # the camera stays blind this long after each (s)

    # Ground robot (unicycle).
    ground_max_linear_m_s: float = 1.0
    ground_max_angular_rad_s: float = 1.5
    ground_radius_m: float = 0.25
    ground_odom_scale_error: float = 0.015     # sigma of the per-run wheel scale error
    ground_odom_curvature_rad_per_m: float = 0.005     # sigma of the per-run heading bias
    ground_odom_noise_m_per_sqrt_m: float = 0.005
    ground_odom_noise_rad_per_sqrt_rad: float = 0.01

    # Drone (DJI Tello SDK).
    drone_flight_height_m: float = 1.0         # after takeoff
    drone_speed_m_s: float = 1.0               # move speed (the "speed" command changes it)
    drone_vertical_speed_m_s: float = 0.5      # takeoff, land
    drone_turn_rate_deg_s: float = 90.0
    drone_auto_land_s: float = 15.0            # lands after this long without a command
    drone_move_error_fraction: float = 0.03    # sigma of distance error
    drone_move_error_deg: float = 2.0          # sigma of direction error of moves
    drone_turn_error_deg: float = 2.0          # sigma of turn angle error
    drone_radius_m: float = 0.15               # with propeller guards
    drone_min_height_m: float = 0.2            # moves below this answer "error: obstacle"
    drone_ceiling_margin_m: float = 0.1

    def validate(self):
        """Raise ValueError naming the first invalid parameter."""
        if self.robot not in ("ground", "drone"):
            raise ValueError(f"robot must be 'ground' or 'drone', got {self.robot!r}")
        positive = ("physics_dt_s", "camera_hfov_deg", "camera_vfov_deg", "camera_max_range_m",
                    "camera_rate_hz", "ground_max_linear_m_s", "ground_max_angular_rad_s",
                    "ground_radius_m", "drone_flight_height_m", "drone_speed_m_s",
                    "drone_vertical_speed_m_s", "drone_turn_rate_deg_s", "drone_auto_land_s",
                    "drone_radius_m", "slam_max_turn_rate_rad_s", "slam_init_min_parallax")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        for name in ("camera_hfov_deg", "camera_vfov_deg"):
            if getattr(self, name) >= 180:
                raise ValueError(f"{name} must be < 180, got {getattr(self, name)}")
        if not 0 <= self.camera_min_range_m < self.camera_max_range_m:
            raise ValueError("camera_min_range_m must be in [0, camera_max_range_m)")
        for name in ("camera_detection_prob", "slam_outlier_fraction",
                     "slam_outlier_far_fraction"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not self.slam_refine_parallax_factor > 1:
            raise ValueError("slam_refine_parallax_factor must be > 1, got "
                             f"{self.slam_refine_parallax_factor}")
        if not 0 <= self.slam_min_relative_depth_noise <= self.slam_max_relative_depth_noise:
            raise ValueError("need 0 <= slam_min_relative_depth_noise <= "
                             "slam_max_relative_depth_noise")
        lo, hi = self.slam_scale_range_m_per_unit
        if not 0 < lo <= hi:
            raise ValueError(f"slam_scale_range_m_per_unit must be (lo, hi) with 0 < lo <= hi, "
                             f"got {self.slam_scale_range_m_per_unit}")
        if not 1 <= self.slam_pose_min_tracked <= self.slam_min_tracked:
            raise ValueError("need 1 <= slam_pose_min_tracked <= slam_min_tracked")
        for name in ("slam_init_min_shared", "slam_min_tracked", "slam_reloc_min_tracked",
                     "slam_merge_min_shared", "slam_lost_frames_before_new_map"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1")
        for name in ("slam_recently_lost_s", "slam_young_map_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        for t in self.force_loss_at_s:
            if not math.isfinite(float(t)):
                raise ValueError(f"force_loss_at_s holds a non-finite time {t!r}")


def _planar(x, y, z, yaw):
    """4x4 pose with position (x, y, z) m and heading yaw rad about +z."""
    c, s = math.cos(yaw), math.sin(yaw)
    t = np.eye(4)
    t[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    t[:3, 3] = (x, y, z)
    return t


class Simulator:
    """A robot in a world with a monocular camera and emulated ORB-SLAM3.

    Args:
      world: a :class:`sparse_nav.sim.World`.
      config: a :class:`SimConfig` (validated here); defaults when None.

    Call :meth:`step` to advance time; robot physics runs every ``physics_dt_s`` and the
    camera + SLAM at ``camera_rate_hz`` (frames at t = k / rate, k >= 1).
    """

    def __init__(self, world, config=None):
        cfg = config if config is not None else SimConfig()
        cfg.validate()
        self.world = world
        self.config = cfg
        # Independent streams, so that e.g. a robot command does not change feature placement.
        streams = np.random.SeedSequence(int(cfg.seed)).spawn(4)
        rng_features, rng_camera, rng_slam, rng_robot = [np.random.default_rng(s)
                                                         for s in streams]
        self.features, self.normals = world.features_with_normals(rng_features)
        segs, heights = world.obstacle_segments()
        heights = np.where(np.arange(len(segs)) < len(world.walls), np.inf, heights)
        self._camera = Camera(self.features, self.normals, segs, heights, cfg.camera_hfov_deg,
                              cfg.camera_vfov_deg, cfg.camera_min_range_m,
                              cfg.camera_max_range_m, cfg.camera_detection_prob, rng_camera)
        self._slam = MonocularSlam(self.features, cfg, rng_slam)
        if cfg.robot == "ground":
            self._robot = GroundRobot(world, cfg, rng_robot)
            mount_xyz = (cfg.ground_camera_forward_m, 0.0, cfg.ground_camera_height_m)
        else:
            self._robot = TelloDrone(world, cfg, rng_robot)
            mount_xyz = (cfg.drone_camera_forward_m, 0.0, 0.0)
        self._mount = np.eye(4)
        self._mount[:3, :3] = _R_BASE_OPTICAL
        self._mount[:3, 3] = mount_xyz
        self._time_s = 0.0
        self._frame_index = 0
        self._output = None
        self._last_frame_rot = None

    # -- time ---------------------------------------------------------------------------------

    @property
    def time_s(self):
        """Simulation time (s) since the start."""
        return self._time_s

    def step(self, dt_s):
        """Advance the simulation by dt_s seconds (> 0)."""
        dt_s = float(dt_s)
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"step: dt_s must be a finite number > 0, got {dt_s!r}")
        end = self._time_s + dt_s
        period = 1.0 / self.config.camera_rate_hz
        while self._time_s < end - 1e-12:
            next_frame = (self._frame_index + 1) * period
            h = min(self.config.physics_dt_s, end - self._time_s, next_frame - self._time_s)
            h = max(h, 0.0)
            self._time_s += h
            if self.config.robot == "ground":
                self._robot.step(h)
            else:
                self._robot.step(h, self._time_s)
            if self._time_s >= next_frame - 1e-9:
                self._time_s = max(self._time_s, next_frame)
                self._frame_index += 1
                self._camera_frame()

    def _camera_frame(self):
        t_wc = self.true_camera_pose()
        rot = t_wc[:3, :3]
        rate = 0.0
        if self._last_frame_rot is not None:
            cos = (np.trace(self._last_frame_rot.T @ rot) - 1.0) / 2.0
            rate = math.acos(min(1.0, max(-1.0, cos))) * self.config.camera_rate_hz
        self._last_frame_rot = rot
        visible = self._camera.detect(t_wc)
        self._output = self._slam.process_frame(self._time_s, t_wc, visible, rate)

    # -- commands -----------------------------------------------------------------------------

    def set_cmd_vel(self, linear_m_s, angular_rad_s):
        """Ground robot velocity command (m/s forward, rad/s counter-clockwise), clamped to the
        limits; it holds until the next call. Raises ValueError for a drone or non-finite input."""
        if self.config.robot != "ground":
            raise ValueError("set_cmd_vel: the simulated robot is a drone; use drone_command")
        self._robot.set_cmd_vel(linear_m_s, angular_rad_s)

    def drone_command(self, text):
        """Send a Tello SDK text command; it is queued and answered via pop_drone_responses().

        Raises:
          DroneCommandError: unknown command or a value outside the Tello's limits.
          ValueError: the simulated robot is not a drone.
        """
        if self.config.robot != "drone":
            raise ValueError("drone_command: the simulated robot is a ground robot; "
                             "use set_cmd_vel")
        self._robot.command(text, self._time_s)

    def pop_drone_responses(self):
        """(command, "ok" | "error: ...") pairs completed since the last call ([] for ground)."""
        if self.config.robot != "drone":
            return []
        return self._robot.pop_responses()

    @property
    def drone_flying(self):
        """True while the drone is airborne (taking off, flying, landing); False for ground."""
        return self.config.robot == "drone" and self._robot.flying

    # -- state and ground truth ---------------------------------------------------------------

    def true_base_pose(self):
        """(x, y, z, yaw) of the robot base in the world frame (m, rad)."""
        return tuple(float(v) for v in self._robot.pose())

    def true_camera_pose(self):
        """4x4 T_world_cameraOptical (m)."""
        x, y, z, yaw = self._robot.pose()
        return _planar(x, y, z, yaw) @ self._mount

    def camera_mount(self):
        """4x4 T_base_cameraOptical (m), static."""
        return self._mount.copy()

    def slam_output(self):
        """The latest :class:`SlamOutput` (a new object per camera frame), None before the first."""
        return self._output

    @property
    def collisions(self):
        """Number of collisions (contact episodes for the ground robot, stopped moves for the
        drone)."""
        return self._robot.collisions

    @property
    def tracking_losses(self):
        """Number of times SLAM tracking was lost (OK -> RECENTLY_LOST or forced LOST)."""
        return self._slam.tracking_losses

    @property
    def last_loss_cause(self):
        """Why SLAM tracking was last lost, in words ("" before the first loss)."""
        return self._slam.last_loss_cause

    def odometry(self):
        """Wheel odometry (x, y, yaw) in the odom frame (m, rad; origin at the start pose) for
        the ground robot, None for the drone."""
        if self.config.robot != "ground":
            return None
        return tuple(self._robot.odom)

    def true_slam_scale(self):
        """Metres per SLAM unit of the current SLAM map (NaN while no map is initialised)."""
        return self._slam.true_scale_m_per_unit()

    def slam_map_origin_world(self):
        """4x4 T_world_slamWorld of the current SLAM map: the optical pose of its reference
        camera; p_slam ~= s * T^-1 p_world with s = 1 / true_slam_scale(), up to the drift
        offset (see :meth:`world_to_slam`). None while no map is initialised."""
        return self._slam.origin_world()

    def world_to_slam(self, points_world):
        """Ground truth: world points (N, 3) m -> current SLAM map frame (units), including the
        accumulated scale drift. None while no map is initialised."""
        m = self._slam.active
        return None if m is None else m.to_slam(np.asarray(points_world, dtype=float))

    def slam_to_world(self, points_slam):
        """Ground truth: current SLAM map points (N, 3) units -> world frame (m). None while no
        map is initialised."""
        m = self._slam.active
        return None if m is None else m.to_world(np.asarray(points_slam, dtype=float))

    def visible_features(self):
        """Indices of the features geometrically visible from the current camera pose (no
        detection dropout), for tests and tools."""
        return self._camera.geometric_visible(self.true_camera_pose())
