"""Carrying out scan Steps on a robot: Tello commands or cmd_vel segments (rospy glue)."""
import threading

import rosgraph
import rospy
from geometry_msgs.msg import Twist
from std_msgs.msg import String

from sparse_nav.scanning import (GROUND_SPEED_M_S, GROUND_TURN_RATE_RAD_S, to_tello_commands,
                                 to_velocity_segments)

TELLO_SPEED_CM_S = 100  # the sim's and the SDK's top speed; retries go slower from here
TELLO_MIN_SPEED_CM_S = 10


class TelloClient:
    """Sends SDK commands on tello/command one at a time and waits (sim time) for each answer.

    The Tello answers in order and without an id, so only one command may be in flight. It also
    watches the line for other senders' commands and answers, so idle_s() is the drone's idle time.
    """

    def __init__(self, timeout_s=30.0, on_wait=None):
        self.timeout_s = timeout_s
        self.on_wait = on_wait
        self._lock = threading.Lock()
        self._responses = []
        self._busy = threading.Lock()
        self.last_traffic = None  # rospy.Time of the last command or answer of anyone
        self._driver = None  # caller id of the node answering our commands, once connected
        self._sub = rospy.Subscriber("tello/response", String, self._on_response, queue_size=20)
        self._pub = rospy.Publisher("tello/command", String, queue_size=10)
        self._watch = rospy.Subscriber("tello/command", String, self._on_command, queue_size=20)

    def _on_response(self, msg):
        with self._lock:
            self._responses.append(msg.data)
            self.last_traffic = rospy.Time.now()

    def _on_command(self, _msg):
        with self._lock:
            self.last_traffic = rospy.Time.now()

    def send(self, text):
        """The drone's answer ("ok", "error: ..."), or "timeout"."""
        with self._busy:
            deadline = rospy.Time.now() + rospy.Duration(self.timeout_s)
            # A command published before the driver is connected is lost for good, and so is an
            # answer sent before this node listens: the first "command" at launch was.
            while (not rospy.is_shutdown() and rospy.Time.now() < deadline
                   and not self._driver_connected()):
                rospy.sleep(0.05)
            with self._lock:
                before = len(self._responses)
            self._pub.publish(String(data=text))
            with self._lock:
                self.last_traffic = rospy.Time.now()
            while not rospy.is_shutdown() and rospy.Time.now() < deadline:
                with self._lock:
                    if len(self._responses) > before:
                        return self._responses[before]
                if self.on_wait is not None:
                    self.on_wait()
                rospy.sleep(0.05)
            return "timeout"

    def _driver_connected(self):
        """True when a node that answers on tello/response receives our tello/command. Counting
        connections is not enough: this node's own watch, the motion node's and rosbag's listen
        too, and the driver makes its answer publisher before its command subscriber."""
        if self._driver is not None and self._pub.impl.has_connection(self._driver):
            return True
        if not self._sub.get_num_connections():
            return False
        try:
            publishers, _, _ = rosgraph.Master(rospy.get_name()).getSystemState()
        except (OSError, rosgraph.MasterException):
            return False
        answering = next((nodes for topic, nodes in publishers
                          if topic == self._sub.resolved_name), [])
        self._driver = next((n for n in answering if self._pub.impl.has_connection(n)), None)
        return self._driver is not None

    def idle_s(self):
        """Seconds since the last command or answer on the line, or None before the first."""
        with self._lock:
            last = self.last_traffic
        return None if last is None else (rospy.Time.now() - last).to_sec()


class StepExecutor:
    """Executes one scanning.Step at a given speed factor on the drone or the ground robot."""

    def __init__(self, robot, tello=None, ground_speed_m_s=GROUND_SPEED_M_S,
                 ground_turn_rate_rad_s=GROUND_TURN_RATE_RAD_S,
                 rate_hz=20.0, on_wait=None):
        if robot not in ("drone", "ground"):
            raise ValueError(f"robot must be 'drone' or 'ground', got {robot!r}")
        self.robot = robot
        self.tello = tello if tello is not None or robot == "ground" else TelloClient()
        self.ground_speed_m_s = ground_speed_m_s
        self.ground_turn_rate_rad_s = ground_turn_rate_rad_s
        self.rate_hz = rate_hz
        self.on_wait = on_wait
        self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=10) if robot == "ground" else None
        self._tello_speed = None

    def execute(self, step, speed_factor=1.0, should_stop=lambda: False):
        """True when every command of the step was carried out."""
        if self.robot == "drone":
            speed = max(TELLO_MIN_SPEED_CM_S, int(round(TELLO_SPEED_CM_S * speed_factor)))
            if speed != self._tello_speed:
                if self.tello.send(f"speed {speed}") != "ok":
                    return False
                self._tello_speed = speed
            try:
                commands = to_tello_commands([step])
            except ValueError as exc:  # a move below the Tello's 20 cm: skipped, not failed
                rospy.logdebug("step skipped: %s", exc)
                return True
            return all(not should_stop() and self.tello.send(c) == "ok" for c in commands)
        rate = rospy.Rate(self.rate_hz)
        segments = to_velocity_segments([step], speed_m_s=self.ground_speed_m_s * speed_factor,
                                        turn_rate_rad_s=self.ground_turn_rate_rad_s * speed_factor)
        try:
            for v, w, duration in segments:
                end = rospy.Time.now() + rospy.Duration(duration)
                while not rospy.is_shutdown() and rospy.Time.now() < end:
                    if should_stop():
                        return False
                    cmd = Twist()
                    cmd.linear.x, cmd.angular.z = v, w
                    self.cmd_pub.publish(cmd)
                    if self.on_wait is not None:
                        self.on_wait()
                    rate.sleep()
        finally:
            self.cmd_pub.publish(Twist())
        return True
