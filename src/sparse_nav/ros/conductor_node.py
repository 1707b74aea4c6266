"""conductor: runs the escape mission by feeding the ROS-free Conductor and carrying out its
actions (scans here, goals through the navigator's MoveBase action, the exit finder's service)."""
import dataclasses
import math
import threading

import actionlib
import numpy as np
import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import OccupancyGrid
from std_srvs.srv import Trigger, TriggerResponse

from sparse_nav.conductor import (ActionKind, Conductor, ConductorConfig, Observation, Phase,
                                  ScanRunner, ScanRunnerConfig, take_off)
from sparse_nav.conductor.grid_queries import GridView, order_exits, steps_out_of_obstacle
from sparse_nav.conductor.outlines import OutlinesByMap
from sparse_nav.conductor.scan_runner import config_for_scan, drive_scan
from sparse_nav.msg import ConductorState, MotionStatus, NavigatorStatus, SlamState
from sparse_nav.ros.conversions import transform_to_matrix
from sparse_nav.ros.params import read_fields
from sparse_nav.ros.robot_io import StepExecutor, TelloClient
from sparse_nav.scanning import (GROUND_INITIAL_SCAN_TURN_DEG, GROUND_SPEED_M_S,
                                 GROUND_TURN_RATE_RAD_S, InitialScanConfig,
                                 RelocaliseConfig, Step, WallScanConfig, circular_scan,
                                 initial_scan, random_scan, relocalise, wall_scan)
from sparse_nav.srv import FindExit

# Navigator action states as the conductor names them.
_NAVIGATOR_STATES = {GoalStatus.PENDING: "planning", GoalStatus.ACTIVE: "following",
                     GoalStatus.SUCCEEDED: "reached", GoalStatus.ABORTED: "no_path",
                     GoalStatus.REJECTED: "no_path"}


def _dataclass_params(prefix, cls):
    """A config dataclass filled from private parameters named like its fields."""
    config = read_fields(cls(), [f.name for f in dataclasses.fields(cls)], "~" + prefix)
    config.validate()
    return config


def _free_distance(grid, pose, off_map_free=False):
    """free_distance(bearing_deg) -> metres free on the grid from pose; None without both."""
    if grid is None or pose is None:
        return None
    x, y, yaw = pose
    return lambda bearing_deg: grid.free_distance(x, y, yaw + math.radians(bearing_deg),
                                                  off_map_free=off_map_free)


class ConductorNode:
    def __init__(self):
        self.robot = rospy.get_param("~robot", "drone")
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.base_frame = rospy.get_param("~base_frame", "base_link")
        self.odom_frame = rospy.get_param("~odom_frame", "odom")
        self.rate_hz = float(rospy.get_param("~rate_hz", 2.0))
        self.auto_start = bool(rospy.get_param("~auto_start", False))
        self.min_free_cells = int(rospy.get_param("~map_ready_min_free_cells", 20))
        self.wall_bearings_deg = [float(b) for b in rospy.get_param("~wall_bearings_deg",
                                                                    [0.0, 90.0, 180.0, 270.0])]
        action_name = rospy.get_param("~navigator_action", "move_base")
        self.exit_service = rospy.get_param("~exit_service", "exit_finder/find_exit")
        self.rng = np.random.default_rng(int(rospy.get_param("~seed", 0)))
        self.config = _dataclass_params("", ConductorConfig)
        self.initial_config = _dataclass_params("initial_scan/", InitialScanConfig)
        self.wall_config = _dataclass_params("wall_scan/", WallScanConfig)
        self.runner_config = _dataclass_params("retry/", ScanRunnerConfig)
        self.relocalise_config = _dataclass_params("relocalise/", RelocaliseConfig)

        self.conductor = Conductor(self.config)
        self.lock = threading.Lock()
        self.obs = Observation(time_s=0.0)
        self.outlines = OutlinesByMap()
        self.requests = {"start": self.auto_start, "stop": False, "return": False}
        self.grid = None
        self.took_off = False
        self.scan_thread = None
        self.scan_stop = threading.Event()
        self.paused_scan = None  # the ScanRunner of a phase scan stopped with steps left
        self.exit_thread = None
        self.keepalive_s = float(rospy.get_param("~drone_keepalive_s", 8.0))
        self.landed = False
        self.motion_moving = False
        self.final_since_s = None
        self.land_wait_s = float(rospy.get_param("~drone_land_wait_s", 3.0))

        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        tello = TelloClient() if self.robot == "drone" else None
        self.tello = tello
        if self.robot == "ground":
            self.initial_config = dataclasses.replace(self.initial_config, turn_deg=float(
                rospy.get_param("~ground_initial_scan_turn_deg", GROUND_INITIAL_SCAN_TURN_DEG)))
            self.initial_config.validate()
        ground_speed = float(rospy.get_param("~ground_scan_speed_m_s", GROUND_SPEED_M_S))
        ground_turn_rate = float(rospy.get_param("~ground_scan_turn_rate_rad_s",
                                                 GROUND_TURN_RATE_RAD_S))
        for name, value in (("ground_scan_speed_m_s", ground_speed),
                            ("ground_scan_turn_rate_rad_s", ground_turn_rate)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        if not (math.isfinite(self.land_wait_s) and self.land_wait_s >= 0):
            raise ValueError(f"drone_land_wait_s must be finite and >= 0, got {self.land_wait_s}")
        self.executor = StepExecutor(self.robot, tello=tello, ground_speed_m_s=ground_speed,
                                     ground_turn_rate_rad_s=ground_turn_rate)
        self.navigator = actionlib.SimpleActionClient(action_name, MoveBaseAction)
        self.state_pub = rospy.Publisher("conductor/state", ConductorState, queue_size=5, latch=True)
        self.diag_pub = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=5)
        rospy.Subscriber("slam/state", SlamState, self._on_slam_state, queue_size=10)
        rospy.Subscriber("map", OccupancyGrid, self._on_map, queue_size=1)
        rospy.Subscriber("motion/status", MotionStatus, self._on_motion_status, queue_size=10)
        self.navigator_planning = False
        rospy.Subscriber("navigator/status", NavigatorStatus, self._on_navigator_status,
                         queue_size=10)
        rospy.Service("~start", Trigger, lambda _: self._request("start"))
        rospy.Service("~stop", Trigger, lambda _: self._request("stop"))
        rospy.Service("~return_to_start", Trigger, lambda _: self._request("return"))
        self._publish_state()

    def _request(self, name):
        with self.lock:
            self.requests[name] = True
        return TriggerResponse(success=True, message=f"{name} requested")

    def _on_slam_state(self, msg):
        with self.lock:
            lost = msg.state == SlamState.LOST  # not initialised is no loss
            previous = self.obs.slam_map_index
            if msg.map_index != previous:
                self.obs.room_outline = self.outlines.get(msg.map_index)
                if previous is not None and not lost and not self.obs.tracking_lost:
                    # No loss in between: SLAM merged the map (or the bridge re-anchored it).
                    self.obs.slam_merges += ((previous, msg.map_index),)
            self.obs.tracking_lost = lost
            self.obs.slam_map_given_up = lost and msg.map_given_up
            self.obs.slam_map_index = msg.map_index
            self.obs.slam_tracked_points = msg.n_tracked_points

    def _on_motion_status(self, msg):
        with self.lock:
            self.obs.motion_failed = msg.state == MotionStatus.FAILED
            self.motion_moving = msg.state in (MotionStatus.FOLLOWING, MotionStatus.WALL_SEEKING)

    def _on_navigator_status(self, msg):
        with self.lock:
            self.navigator_planning = msg.state == NavigatorStatus.PLANNING

    def _on_map(self, msg):
        if msg.info.resolution <= 0 or len(msg.data) != msg.info.width * msg.info.height:
            rospy.logwarn_throttle(10.0, "conductor: malformed map ignored (%dx%d, %d cells)",
                                   msg.info.width, msg.info.height, len(msg.data))
            return
        if msg.header.frame_id and msg.header.frame_id != self.map_frame:
            rospy.logwarn_throttle(10.0, "conductor: map in frame %r, expected %r: ignored",
                                   msg.header.frame_id, self.map_frame)
            return
        cells = np.asarray(msg.data, dtype=np.int8).reshape(msg.info.height, msg.info.width)
        o = msg.info.origin.position
        with self.lock:
            self.grid = GridView(cells, msg.info.resolution, (o.x, o.y))

    def _robot_pose(self, frame=None):
        """(x, y, yaw) of the base in the map frame (or the frame given), or None."""
        try:
            tf = self.tf_buffer.lookup_transform(frame or self.map_frame, self.base_frame,
                                                 rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return None
        m = transform_to_matrix(tf.transform)
        return float(m[0, 3]), float(m[1, 3]), math.atan2(m[1, 0], m[0, 0])

    def _observe(self):
        pose = self._robot_pose()
        with self.lock:
            obs = self.obs
            obs.time_s = rospy.Time.now().to_sec()
            obs.robot_xy = pose[:2] if pose else None
            grid = self.grid
            if grid is not None and pose is not None:
                obs.map_ready = grid.free_cells_near(pose[0], pose[1], 1.0) >= self.min_free_cells
                obs.robot_in_obstacle = grid.in_obstacle(pose[0], pose[1])
            looking = (self.conductor.phase == Phase.LOOK_AROUND and grid is not None
                       and pose is not None)
            obs.walls_around = tuple(grid.walls_around(
                pose[0], pose[1], self.config.walls_around_range_m)) if looking else ()
            obs.side_walls_beyond_m = grid.side_walls_beyond_m(
                obs.room_outline, self.conductor.door_xy) if looking else None
            obs.scan_running = self.scan_thread is not None and self.scan_thread.is_alive()
            obs.scan_resumable = self.paused_scan is not None and not self.paused_scan.done
            obs.start_requested = self.requests["start"]
            obs.stop_requested = self.requests["stop"]
            obs.return_requested = self.requests["return"]
            self.requests = {"start": False, "stop": False, "return": False}
            state = self.navigator.get_state() if self.conductor.goal_xy is not None else None
            obs.navigator_state = _NAVIGATOR_STATES.get(state, "")
            if obs.navigator_state == "following" and self.navigator_planning:
                obs.navigator_state = "planning"  # the goal accepted, no map or pose to plan on
            snapshot = Observation(**vars(obs))
            obs.exit_answered = False  # an answer is seen once
        return snapshot, pose

    def _scan_steps(self, name, pose):
        grid = self.grid
        if name == "initial":
            return initial_scan(self.initial_config)
        if name == "look_around":
            return circular_scan(self.wall_config)
        if name == "relocalise":
            # 004's LOST: look and move around. Each try also turns, so that a robot stuck
            # facing a bare wall ends up looking at the mapped room again. The last grid, with
            # the pose tf still gives, tells the ground robot which way there is room to drive;
            # past its edge is unknown, not a wall: the grid of a SLAM map seconds old is small,
            # and its edge would cut every drive to min_baseline_m, too short for a new map.
            return relocalise(self.robot, _free_distance(grid, pose, off_map_free=True),
                              self.relocalise_config, self.initial_config)
        if grid is None or pose is None:
            return initial_scan(self.initial_config)  # nothing to aim at yet
        room = _free_distance(grid, pose)
        if name == "wall":
            return wall_scan([(b, room(b)) for b in self.wall_bearings_deg], self.wall_config)
        return random_scan(self.rng, room, self.wall_config)

    def _start_scan(self, name, pose):
        self._stop_scan()
        if name == "resume" and self.paused_scan is not None:
            runner, self.paused_scan = self.paused_scan, None
            rospy.loginfo("conductor: the stopped scan goes on")
        else:
            if name == "resume":  # the conductor asks only while obs.scan_resumable
                rospy.logwarn("conductor: no stopped scan to go on with: a random scan instead")
                name = "random"
            if name != "relocalise":
                self.paused_scan = None  # a new phase scan replaces the stopped one
            steps = self._scan_steps(name, pose)
            rospy.loginfo("conductor: %s scan, %d steps", name, len(steps))
            runner = ScanRunner(steps, config_for_scan(name, self.runner_config),
                                while_lost=name == "relocalise")
        self._start_runner(runner)

    def _start_runner(self, runner, resumable=True):
        """Runs the runner's steps in the scan thread; a resumable one stopped midway is kept
        to go on with later."""
        self.scan_stop.clear()
        self.scan_thread = threading.Thread(target=self._run_scan, args=(runner, resumable),
                                            daemon=True)
        self.scan_thread.start()

    def _run_scan(self, runner, resumable=True):
        if self.tello is not None and not self.took_off:
            self.took_off, why = take_off(self.tello.send)
            if not self.took_off:
                rospy.logwarn("conductor: the drone did not take off (%s): the scan is not flown", why)
                with self.lock:
                    self.obs.scan_failed, self.obs.scan_share_done = True, 0.0
                return
        # Only the ground robot's odometry holds still through SLAM losses: the drone's odom
        # frame is SLAM's own.
        odom_pose = (lambda: self._robot_pose(self.odom_frame)) if self.robot == "ground" \
            else (lambda: None)
        drive_scan(runner, self.executor.execute, self._tracking_lost, odom_pose,
                   stop_requested=lambda: self.scan_stop.is_set() or rospy.is_shutdown(),
                   pause=rospy.sleep, log=lambda text: rospy.loginfo("conductor: %s", text))
        with self.lock:
            self.obs.scan_failed = runner.failed
            self.obs.scan_share_done = runner.share_done
            if (resumable and self.scan_stop.is_set() and not runner.while_lost
                    and not runner.done):
                self.paused_scan = runner

    def _tracking_lost(self):
        with self.lock:
            return self.obs.tracking_lost

    def _stop_scan(self):
        if self.scan_thread is not None and self.scan_thread.is_alive():
            self.scan_stop.set()
            self.scan_thread.join(timeout=60.0)

    def _ask_exit(self, request):
        def call():
            answer, alternatives, leads_out, outline = None, (), True, ()
            with self.lock:
                map_index = self.obs.slam_map_index
            try:
                rospy.wait_for_service(self.exit_service, timeout=10.0)
                response = rospy.ServiceProxy(self.exit_service, FindExit)(
                    method="", viewpoint=request.viewpoint or "",
                    any_probability=request.last_attempt)
                if response.success and response.candidates.exits:
                    ranked = [(p.x, p.y) for p in response.candidates.exits]
                    cfg = self.config
                    with self.lock:
                        grid = self.grid
                    ordered, leads_out = order_exits(ranked, grid, self.conductor.room_origin_xy,
                                                     cfg.exit_check_near_m, cfg.exit_check_far_m,
                                                     cfg.exit_min_free_share)
                    if ordered != ranked or not leads_out:
                        rospy.loginfo("conductor: exits in order, free space beyond first, those "
                                      "off the map left out: %s%s",
                                      [(round(x, 2), round(y, 2)) for x, y in ordered],
                                      "" if leads_out else " (none has free space beyond)")
                    if ordered:
                        answer, alternatives = ordered[0], tuple(ordered[1:])
                # A room without an exit ("no_exit") is still a room to measure against.
                outline = tuple((p.x, p.y) for p in response.candidates.room_outline)
                rospy.loginfo("conductor: exit finder: %s (%s)", response.candidates.status,
                              response.candidates.reason)
            except (rospy.ROSException, rospy.ServiceException) as exc:
                rospy.logwarn("conductor: exit finder call failed: %s", exc)
                return  # no answer: the conductor's timeout decides
            with self.lock:
                self.obs.exit_xy = answer
                self.obs.exit_alternatives = alternatives
                self.obs.exit_leads_out = leads_out
                self.obs.exit_answered = True
                outline = self.outlines.answered(map_index, outline)
                if map_index == self.obs.slam_map_index:
                    self.obs.room_outline = outline
        self.exit_thread = threading.Thread(target=call, daemon=True)
        self.exit_thread.start()

    def _send_goal(self, xy):
        goal = MoveBaseGoal()
        goal.target_pose = PoseStamped()
        goal.target_pose.header.frame_id = self.map_frame
        goal.target_pose.header.stamp = rospy.Time.now()
        goal.target_pose.pose.position.x, goal.target_pose.pose.position.y = xy
        goal.target_pose.pose.orientation.w = 1.0
        if not self.navigator.wait_for_server(rospy.Duration(5.0)):
            rospy.logwarn_throttle(10.0, "conductor: navigator action server not available")
        self.navigator.send_goal(goal)

    def _carry_out(self, action, pose):
        if action.kind == ActionKind.SCAN:
            self._start_scan(action.payload, pose)
        elif action.kind == ActionKind.FIND_EXIT:
            self._ask_exit(action.payload)
        elif action.kind == ActionKind.GOAL:
            self._send_goal(action.payload)
        elif action.kind == ActionKind.CANCEL_GOAL:
            self.navigator.cancel_all_goals()
        elif action.kind == ActionKind.STOP:
            self._stop_scan()
            if self.robot == "ground":
                self.executor.execute(Step())  # publishes one zero velocity
        elif action.kind == ActionKind.RECOVER_MOTION:
            self._stop_scan()
            grid = self.grid
            steps = steps_out_of_obstacle(grid, pose) if grid is not None and pose else None
            if steps is None:  # no free cell nearby: look around from a little aside
                steps = [Step(forward_m=0.2, ccw_deg=30.0), Step(forward_m=-0.2)]
            rospy.loginfo("conductor: recovery motion, %d steps", len(steps))
            # Not resumable: a phase scan asked to go on must not go on with this motion.
            self._start_runner(ScanRunner(steps, self.runner_config), resumable=False)

    def _publish_state(self):
        c = self.conductor
        msg = ConductorState(state=c.state.value, phase=c.phase.value, reason=c.reason,
                             has_exit=c.exit_xy is not None)
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.map_frame
        if c.exit_xy is not None:
            msg.exit = Point(x=c.exit_xy[0], y=c.exit_xy[1], z=0.0)
        self.state_pub.publish(msg)

    def _publish_diagnostics(self, obs):
        c = self.conductor
        level = DiagnosticStatus.ERROR if c.phase.value == "gave_up" else DiagnosticStatus.OK
        status = DiagnosticStatus(level=level, name="sparse_nav: conductor", hardware_id="conductor",
                                  message=f"{c.state.value} / {c.phase.value}: {c.reason}")
        status.values = [KeyValue(key="tracking_lost", value=str(obs.tracking_lost)),
                         KeyValue(key="map_ready", value=str(obs.map_ready)),
                         KeyValue(key="transitions", value=str(len(c.history)))]
        array = DiagnosticArray(status=[status])
        array.header.stamp = rospy.Time.now()
        self.diag_pub.publish(array)

    def _drone_upkeep(self):
        """A Tello lands by itself after 15 s without a command: when nobody (this node or the
        motion node) has talked to it for keepalive_s, a "command"; at the mission's end, land."""
        if self.tello is None or not self.took_off or self.landed:
            return
        if self.scan_thread is not None and self.scan_thread.is_alive():
            return
        if self.conductor.phase.final:
            now = rospy.Time.now().to_sec()
            if self.final_since_s is None:
                self.final_since_s = now
            with self.lock:
                moving = self.motion_moving
            # The motion layer stops once the navigator's cancelled path reaches it; a command
            # it sent after "land" would only be refused.
            if moving and now - self.final_since_s < self.land_wait_s:
                return
            self.landed = True
            threading.Thread(target=self.tello.send, args=("land",), daemon=True).start()
        else:
            idle = self.tello.idle_s()
            if idle is not None and idle > self.keepalive_s:
                threading.Thread(target=self.tello.send, args=("command",), daemon=True).start()

    def spin(self):
        while not rospy.is_shutdown() and rospy.Time.now().is_zero():
            rospy.sleep(0.05)
        rate = rospy.Rate(self.rate_hz)
        last_history = -1
        while not rospy.is_shutdown():
            obs, pose = self._observe()
            for action in self.conductor.update(obs):
                rospy.loginfo("conductor: %s %s", action.kind.value,
                              "" if action.payload is None else action.payload)
                self._carry_out(action, pose)
            if len(self.conductor.history) != last_history:
                last_history = len(self.conductor.history)
                rospy.loginfo("conductor: %s / %s: %s", self.conductor.state.value,
                              self.conductor.phase.value, self.conductor.reason)
                self._publish_state()
            self._publish_diagnostics(obs)
            self._drone_upkeep()
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break
        self._stop_scan()


def main():
    rospy.init_node("conductor")
    ConductorNode().spin()
