"""Sends Tello commands to the simulator one at a time, waiting for each answer (rostest helper)."""
import threading

import rospy
from std_msgs.msg import String


class DroneDriver:
    """Publishes on tello/command and waits (sim time) for the answer on tello/response."""

    def __init__(self, timeout_s=30.0):
        self.timeout_s = timeout_s
        self.lock = threading.Lock()
        self.responses = []
        rospy.Subscriber("tello/response", String, self._on_response, queue_size=20)
        self.publisher = rospy.Publisher("tello/command", String, queue_size=10)

    def _on_response(self, msg):
        with self.lock:
            self.responses.append(msg.data)

    def command(self, text):
        """Sends one command; returns its answer, or "timeout"."""
        with self.lock:
            before = len(self.responses)
        self.publisher.publish(String(data=text))
        deadline = rospy.Time.now() + rospy.Duration(self.timeout_s)
        while rospy.Time.now() < deadline and not rospy.is_shutdown():
            with self.lock:
                if len(self.responses) > before:
                    return self.responses[before]
            rospy.sleep(0.05)
        return "timeout"
