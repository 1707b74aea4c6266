#!/usr/bin/python3
"""rostest: bad clouds give the exit finder a clear status and no exit; it keeps running."""
import threading
import unittest

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from sparse_nav.msg import Door, ExitCandidates, Features
from sparse_nav.ros.conversions import points_to_cloud
from sparse_nav.srv import FindExit

DOOR = np.array([3.0, 5.0])   # centre of the 1 m door of synthetic_room (map frame)


def synthetic_room(seed=0):
    """A 6 m x 5 m room (map frame, z up) mapped from (3, 2.5): walls, a 1 m door in the north
    wall, the part of a wall 1.5 m beyond it that is seen through the door, and a floor."""
    rng = np.random.default_rng(seed)
    walls = [((0, 0), (6, 0)), ((6, 0), (6, 5)), ((0, 5), (0, 0)), ((6, 5), (3.5, 5)),
             ((2.5, 5), (0, 5)), ((2.3, 6.5), (3.7, 6.5))]
    points = []
    for (x1, y1), (x2, y2) in walls:
        n = int(np.hypot(x2 - x1, y2 - y1) * 80)
        t = rng.random(n)
        points.append(np.stack([x1 + t * (x2 - x1), y1 + t * (y2 - y1),
                                rng.uniform(0.2, 2.0, n)], 1))
    points.append(np.stack([rng.uniform(0.3, 5.7, 300), rng.uniform(0.3, 4.7, 300),
                            np.zeros(300)], 1))
    cloud = np.vstack(points)
    # The map origin is where SLAM started: put the room around it.
    return cloud + rng.normal(0, 0.02, cloud.shape) - np.array([3.0, 2.5, 0.0])


class ExitFinderBadInputTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.exits = []
        rospy.Subscriber("exit", PointStamped, self._on_exit, queue_size=10)
        self.pub = rospy.Publisher("slam/points", PointCloud2, queue_size=2, latch=True)
        self.features_pub = rospy.Publisher("features", Features, queue_size=2, latch=True)
        rospy.wait_for_service("exit_finder/find_exit", 60.0)
        self.find = rospy.ServiceProxy("exit_finder/find_exit", FindExit)

    def _on_exit(self, msg):
        with self.lock:
            self.exits.append(msg)

    def _send(self, msg):
        """Publishes a cloud, waits until the node has it, and asks for the exit."""
        msg.header.stamp = rospy.Time.now()
        self.pub.publish(msg)
        rospy.sleep(1.5)
        return self.find(method="")

    def _n_exits(self):
        rospy.sleep(0.5)
        with self.lock:
            return len(self.exits)

    def _assert_refused(self, answer, statuses, what):
        cand = answer.candidates
        self.assertFalse(answer.success, f"{what}: no success")
        self.assertIn(cand.status, statuses, f"{what}: {cand.status}: {cand.reason}")
        self.assertTrue(cand.reason, f"{what}: a reason")
        self.assertEqual(len(cand.exits), 0, f"{what}: no made-up exit")

    def test_bad_clouds(self):
        answer = self.find(method="")
        self._assert_refused(answer, (ExitCandidates.STATUS_NO_CLOUD,), "before any cloud")

        header = Header(frame_id="map")
        rng = np.random.default_rng(1)
        all_nan = np.full((500, 3), np.nan)
        few = synthetic_room()[::400][:10]
        line = np.stack([np.linspace(0, 5, 300), np.zeros(300), rng.uniform(0, 2, 300)], 1)
        cases = [
            ("empty cloud", points_to_cloud(np.empty((0, 3)), header),
             (ExitCandidates.STATUS_TOO_FEW_POINTS,)),
            ("all NaN", points_to_cloud(all_nan, header), (ExitCandidates.STATUS_TOO_FEW_POINTS,)),
            ("10 points", points_to_cloud(few, header), (ExitCandidates.STATUS_TOO_FEW_POINTS,)),
            ("collinear", points_to_cloud(line, header),
             (ExitCandidates.STATUS_COLLINEAR, ExitCandidates.STATUS_TOO_FEW_POINTS)),
        ]
        for what, msg, statuses in cases:
            self._assert_refused(self._send(msg), statuses, what)
        self.assertEqual(self._n_exits(), 0, "no exit published for bad clouds")

        answer = self.find(method="no_such_method")
        self._assert_refused(answer, (ExitCandidates.STATUS_BAD_INPUT,), "unknown method")

        good = self._send(points_to_cloud(synthetic_room(), header))
        self.assertTrue(good.success, f"the good cloud gives an exit ({good.candidates.status}: "
                                      f"{good.candidates.reason})")
        best = good.candidates.exits[0]
        self.assertLess(np.hypot(best.x - (DOOR[0] - 3.0), best.y - (DOOR[1] - 2.5)), 0.8,
                        f"at the door: ({best.x:.2f}, {best.y:.2f})")
        n_good = self._n_exits()
        self.assertEqual(n_good, 1, "the exit is published once")

        # The feature extractor's door at the same place raises the confidence; a NaN door and
        # one in an unknown frame are ignored.
        door = Door(width_m=1.0)
        door.center.x, door.center.y = DOOR[0] - 3.0, DOOR[1] - 2.5
        nan_door = Door(width_m=1.0)
        nan_door.center.x = float("nan")
        self.features_pub.publish(Features(header=Header(frame_id="nowhere"), ok=True,
                                           doors=[door]))
        rospy.sleep(1.5)
        same = self.find(method="")
        self.assertAlmostEqual(same.candidates.scores[0], good.candidates.scores[0], places=6)
        self.features_pub.publish(Features(header=Header(frame_id="map", stamp=rospy.Time.now()),
                                           ok=True, doors=[door, nan_door]))
        rospy.sleep(1.5)
        fused = self.find(method="")
        self.assertTrue(fused.success)
        self.assertGreater(fused.candidates.scores[0], good.candidates.scores[0] + 0.05,
                           "a matching door gap raises the confidence")
        top = fused.candidates.exits[0]
        self.assertLess(np.hypot(top.x - best.x, top.y - best.y), 0.3, "the same door")

        nan_rows = synthetic_room()
        nan_rows[::5] = np.nan
        answer = self._send(points_to_cloud(nan_rows, header))
        self.assertTrue(answer.success, "NaN rows are dropped, the rest still holds the room")
        self.assertIn("non-finite", answer.candidates.reason)

        no_xyz = PointCloud2(header=Header(frame_id="map"), height=1, width=4, point_step=4,
                             row_step=16, data=bytes(16),
                             fields=[PointField("intensity", 0, PointField.FLOAT32, 1)])
        truncated = points_to_cloud(synthetic_room(), header)
        truncated.data = truncated.data[:100]
        unknown_frame = points_to_cloud(synthetic_room(), Header(frame_id="nowhere"))
        with self.lock:
            before = len(self.exits)
        for what, msg in (("no x/y/z", no_xyz), ("truncated", truncated),
                          ("unknown frame", unknown_frame)):
            msg.header.stamp = rospy.Time.now()
            self.pub.publish(msg)
            deadline = rospy.Time.now() + rospy.Duration(10.0)
            cand = None
            while rospy.Time.now() < deadline:
                cand = rospy.wait_for_message("exit_candidates", ExitCandidates, 5.0)
                if cand.status == ExitCandidates.STATUS_BAD_INPUT:
                    break
                rospy.sleep(0.2)
            self.assertEqual(cand.status, ExitCandidates.STATUS_BAD_INPUT, what)
            self.assertIn("refused", cand.reason, what)
            # The refused cloud did not replace the last good one.
            answer = self.find(method="")
            self.assertTrue(answer.success, f"after {what}: the last good cloud still answers")
        with self.lock:
            after = self.exits[before:]
        self.assertTrue(all(np.hypot(e.point.x - best.x, e.point.y - best.y) < 0.5
                            for e in after), "only the good cloud's exit is published")


if __name__ == "__main__":
    rospy.init_node("test_exit_finder_bad_input")
    rostest.rosrun("sparse_nav", "exit_finder_bad_input", ExitFinderBadInputTest)
