#!/usr/bin/python3
"""rostest: the Tello client's first command reaches a driver that subscribes late."""
import time
import unittest

import rospy
import rostest
from std_msgs.msg import String

from sparse_nav.ros.robot_io import TelloClient


class TelloClientTest(unittest.TestCase):
    def test_the_first_command_waits_for_the_driver_to_listen(self):
        client = TelloClient(timeout_s=30.0)
        answers = rospy.Subscriber("tello/response", String)  # shares the client's connections
        # Once the driver's answer publisher is connected, its command subscriber is still
        # seconds away: a command sent now without waiting is lost and times out.
        give_up = time.monotonic() + 30.0
        while not answers.get_num_connections() and time.monotonic() < give_up:
            time.sleep(0.01)
        self.assertTrue(answers.get_num_connections(), "the driver advertises tello/response")
        self.assertEqual(client.send("command"), "ok")
        self.assertEqual(client.send("takeoff"), "ok", "and the answers stay in step")


if __name__ == "__main__":
    rospy.init_node("test_tello_client")
    rostest.rosrun("sparse_nav", "tello_client", TelloClientTest)
