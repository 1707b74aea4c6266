"""The world a navigator rostest feeds the node: /clock, a synthetic map, TF map -> base_link from
a kinematic robot that follows navigator/path, and slam/state; it records the node's output."""
import math
import threading
import time

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Quaternion, TransformStamped
from map_msgs.msg import OccupancyGridUpdate
from nav_msgs.msg import OccupancyGrid, Path
from rosgraph_msgs.msg import Clock

from sparse_nav.msg import NavigatorStatus, SlamState

CLOCK_STEP_S = 0.01       # sim time per /clock message
CLOCK_PERIOD_S = 0.01     # wall time between /clock messages: sim time runs at wall speed
STATE_NAMES = {getattr(NavigatorStatus, n): n.lower() for n in dir(NavigatorStatus)
               if n.isupper() and isinstance(getattr(NavigatorStatus, n), int)}


def start_clock():
    """Publishes /clock from a wall-clock thread; call right after rospy.init_node."""
    pub = rospy.Publisher("/clock", Clock, queue_size=10)

    def run():
        t = 1.0
        while not rospy.is_shutdown():
            t += CLOCK_STEP_S
            pub.publish(Clock(clock=rospy.Time.from_sec(t)))
            time.sleep(CLOCK_PERIOD_S)
    threading.Thread(target=run, daemon=True).start()


def occupancy_grid(data, resolution, origin=(0.0, 0.0), frame="map"):
    msg = OccupancyGrid()
    msg.header.frame_id = frame
    msg.header.stamp = rospy.Time.now()
    msg.info.resolution = resolution
    msg.info.height, msg.info.width = data.shape
    msg.info.origin.position.x, msg.info.origin.position.y = origin
    msg.info.origin.orientation.w = 1.0
    msg.data = data.astype(np.int8).ravel().tolist()
    return msg


class NavWorld:
    def __init__(self):
        self.lock = threading.Lock()
        self.statuses = []
        self.path = None
        self.paths = 0
        self.unstamped_paths = 0
        self.pose = (0.0, 0.0, 0.0)
        self.follow = False
        self.speed_mps = 0.5
        self.map_pub = rospy.Publisher("map", OccupancyGrid, queue_size=2, latch=True)
        self.update_pub = rospy.Publisher("map_updates", OccupancyGridUpdate, queue_size=5)
        self.goal_pub = rospy.Publisher("move_base_simple/goal", PoseStamped, queue_size=2)
        self.slam_pub = rospy.Publisher("slam/state", SlamState, queue_size=5, latch=True)
        self.tf = tf2_ros.TransformBroadcaster()
        rospy.Subscriber("navigator/status", NavigatorStatus, self._on_status, queue_size=50)
        rospy.Subscriber("navigator/path", Path, self._on_path, queue_size=5)
        rospy.Timer(rospy.Duration(0.05), self._on_tick)

    def _on_status(self, msg):
        with self.lock:
            self.statuses.append(msg)

    def _on_path(self, msg):
        with self.lock:
            self.paths += 1
            if msg.header.stamp.is_zero() or msg.header.frame_id != "map":
                self.unstamped_paths += 1
            self.path = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]

    def _on_tick(self, event):
        dt = 0.05
        with self.lock:
            x, y, yaw = self.pose
            if self.follow and self.path and len(self.path) > 1:
                tx, ty = self.path[1]
                d = math.hypot(tx - x, ty - y)
                if d > 1e-9:
                    f = min(1.0, self.speed_mps * dt / d)
                    x, y = x + f * (tx - x), y + f * (ty - y)
                    yaw = math.atan2(ty - y, tx - x) if d > 1e-3 else yaw
                self.pose = (x, y, yaw)
        t = TransformStamped()
        t.header.stamp = rospy.Time.now()
        t.header.frame_id = "map"
        t.child_frame_id = "base_link"
        t.transform.translation.x, t.transform.translation.y = x, y
        t.transform.rotation = Quaternion(0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        self.tf.sendTransform(t)

    def set_pose(self, x, y, yaw=0.0):
        with self.lock:
            self.pose = (x, y, yaw)

    def publish_map(self, data, resolution=0.1, origin=(0.0, 0.0), frame="map"):
        self.map_pub.publish(occupancy_grid(data, resolution, origin, frame))

    def publish_update(self, x, y, window):
        msg = OccupancyGridUpdate()
        msg.header.frame_id = "map"
        msg.header.stamp = rospy.Time.now()
        msg.x, msg.y = x, y
        msg.height, msg.width = window.shape
        msg.data = window.astype(np.int8).ravel().tolist()
        self.update_pub.publish(msg)

    def send_goal(self, x, y, frame="map"):
        goal = PoseStamped()
        goal.header.frame_id = frame
        goal.header.stamp = rospy.Time.now()
        goal.pose.position.x, goal.pose.position.y = x, y
        goal.pose.orientation.w = 1.0
        self.goal_pub.publish(goal)

    def slam(self, state, map_index):
        self.slam_pub.publish(SlamState(state=state, map_index=map_index, source="test"))

    def mark(self):
        """Index of the next status: wait_status looks only at statuses from here on."""
        with self.lock:
            return len(self.statuses)

    def wait_status(self, since, names, timeout_s=60.0, reason=None):
        """The first status at or after index since whose state is in names (and whose reason
        contains reason); None after timeout_s of sim time."""
        deadline = rospy.Time.now() + rospy.Duration(timeout_s)
        while rospy.Time.now() < deadline and not rospy.is_shutdown():
            with self.lock:
                for msg in self.statuses[since:]:
                    if STATE_NAMES[msg.state] in names and (reason is None or reason in msg.reason):
                        return msg
            rospy.sleep(0.05)
        return None

    def last_state(self):
        with self.lock:
            return STATE_NAMES[self.statuses[-1].state] if self.statuses else None

    def current_path(self):
        with self.lock:
            return list(self.path) if self.path is not None else None

    def wait_path(self, predicate, timeout_s=30.0):
        deadline = rospy.Time.now() + rospy.Duration(timeout_s)
        while rospy.Time.now() < deadline and not rospy.is_shutdown():
            path = self.current_path()
            if path is not None and predicate(path):
                return path
            rospy.sleep(0.05)
        return None

    def wait_for_node(self, timeout_s=60.0):
        deadline = time.time() + timeout_s
        while time.time() < deadline and not rospy.is_shutdown():
            with self.lock:
                if self.statuses and self.paths:
                    return True
            time.sleep(0.1)
        return False


def crosses(path, data, resolution, origin=(0.0, 0.0), step_m=0.02):
    """True when a straight segment of the path passes through an occupied cell."""
    for a, b in zip(path, path[1:]):
        n = max(1, int(math.dist(a, b) / step_m))
        for t in np.linspace(0.0, 1.0, n + 1):
            cx = int(math.floor((a[0] + t * (b[0] - a[0]) - origin[0]) / resolution))
            cy = int(math.floor((a[1] + t * (b[1] - a[1]) - origin[1]) / resolution))
            if 0 <= cy < data.shape[0] and 0 <= cx < data.shape[1] and data[cy, cx] >= 50:
                return True
    return False
