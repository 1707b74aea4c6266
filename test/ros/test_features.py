#!/usr/bin/python3
"""rostest: feature_extractor on synthetic scans and clouds, good and bad."""
import math
import threading
import unittest

import numpy as np
import rospy
import rostest
from sensor_msgs.msg import LaserScan, PointCloud2, PointField
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from sparse_nav.msg import Corner, Features
from sparse_nav.ros.conversions import points_to_cloud

# A 6 m x 4 m room (map frame) with a 0.9 m door in its east wall, a wall 3 m beyond the door.
WALLS = [((-2, -1.5), (4, -1.5)), ((4, -1.5), (4, 0.3)), ((4, 1.2), (4, 2.5)), ((4, 2.5), (-2, 2.5)),
         ((-2, 2.5), (-2, -1.5)), ((7, -4), (7, 6))]
DOOR_CENTRE = (4.0, 0.75)


def cast(x, y, yaw, n=360):
    """Ranges of a full-turn scan from (x, y, yaw), beams from -pi."""
    ranges = []
    for i in range(n):
        a = yaw - math.pi + i * 2 * math.pi / n
        dx, dy = math.cos(a), math.sin(a)
        best = math.inf
        for (x1, y1), (x2, y2) in WALLS:
            ex, ey = x2 - x1, y2 - y1
            den = dx * ey - dy * ex
            if abs(den) < 1e-12:
                continue
            ax, ay = x1 - x, y1 - y
            t = (ax * ey - ay * ex) / den
            u = (ax * dy - ay * dx) / den
            if t > 0 and 0 <= u <= 1:
                best = min(best, t)
        ranges.append(best)
    return ranges


def room_cloud(seed=0):
    rng = np.random.default_rng(seed)
    pts = []
    for (x1, y1), (x2, y2) in WALLS:
        n = int(math.hypot(x2 - x1, y2 - y1) * 200)
        t = rng.random(n)
        pts.append(np.stack([x1 + t * (x2 - x1), y1 + t * (y2 - y1), rng.uniform(0.2, 1.9, n)], 1))
    pts.append(np.stack([rng.uniform(-2, 4, 500), rng.uniform(-1.5, 2.5, 500), np.zeros(500)], 1))  # floor
    return np.vstack(pts)


class FeatureExtractorTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.got = {"from_scan": [], "from_cloud": []}
        self.markers = []
        for ns in self.got:
            rospy.Subscriber(ns + "/features", Features, self._on, ns, queue_size=20)
        rospy.Subscriber("from_scan/features/markers", MarkerArray, self._on_markers, queue_size=5)
        self.scan_pub = rospy.Publisher("from_scan/scan", LaserScan, queue_size=5)
        self.cloud_pub = rospy.Publisher("from_cloud/cloud/obstacles", PointCloud2, queue_size=5)
        deadline = rospy.Time.now() + rospy.Duration(60.0)
        while rospy.Time.now() < deadline and (self.scan_pub.get_num_connections() == 0
                                               or self.cloud_pub.get_num_connections() == 0):
            rospy.sleep(0.1)

    def _on(self, msg, ns):
        with self.lock:
            self.got[ns].append(msg)

    def _on_markers(self, msg):
        with self.lock:
            self.markers.append(msg)

    def _send(self, ns, pub, msg, timeout_s=30.0):
        with self.lock:
            before = len(self.got[ns])
        pub.publish(msg)
        deadline = rospy.Time.now() + rospy.Duration(timeout_s)
        while rospy.Time.now() < deadline:
            with self.lock:
                if len(self.got[ns]) > before:
                    return self.got[ns][-1]
            rospy.sleep(0.05)
        self.fail(f"no features on {ns} within {timeout_s} s")

    def _scan(self, ranges, frame="laser", n=None):
        n = len(ranges) if n is None else n
        inc = 2 * math.pi / 360
        return LaserScan(header=Header(frame_id=frame, stamp=rospy.Time.now()), angle_min=-math.pi,
                         angle_max=-math.pi + (n - 1) * inc, angle_increment=inc, range_min=0.05,
                         range_max=30.0, ranges=ranges)

    def test_scan_input_good_and_bad(self):
        good = self._scan(cast(0.0, 0.5, 0.0))
        f = self._send("from_scan", self.scan_pub, good)
        self.assertTrue(f.ok, f.status)
        self.assertEqual(f.header.frame_id, "laser")
        self.assertGreaterEqual(len(f.walls), 5)
        self.assertEqual(len(f.doors), 1)
        door = f.doors[0].center
        self.assertAlmostEqual(door.x, DOOR_CENTRE[0] - 0.0, delta=0.1)
        self.assertAlmostEqual(door.y, DOOR_CENTRE[1] - 0.5, delta=0.1)
        self.assertEqual({c.type for c in f.corners if c.type != Corner.POTENTIAL}, {Corner.OUTER})

        one = [math.inf] * 360
        one[10] = 2.0
        shifted = self._scan(cast(0.0, 0.5, 0.0))
        shifted.angle_max = 0.3
        bad = {"empty": self._scan([]),
               "all NaN": self._scan([math.nan] * 360),
               "one point": self._scan(one),
               "mismatched angles": shifted,
               "no frame": self._scan(cast(0.0, 0.5, 0.0), frame="")}
        for name, msg in bad.items():
            f = self._send("from_scan", self.scan_pub, msg)
            self.assertFalse(f.ok, name)
            self.assertTrue(f.status and f.status != "ok", name)
            self.assertEqual(len(f.walls) + len(f.doors) + len(f.corners) + len(f.corridors), 0, name)
        # Still running, and the markers still show the last good features.
        f = self._send("from_scan", self.scan_pub, good)
        self.assertTrue(f.ok, f.status)
        with self.lock:
            last = self.markers[-1]
        walls = [m for m in last.markers if m.ns == "walls"]
        self.assertEqual(len(walls[0].points), 2 * len(f.walls))

    def test_cloud_input_good_and_bad(self):
        cloud = points_to_cloud(room_cloud(), Header(frame_id="map"))
        f = self._send("from_cloud", self.cloud_pub, cloud)
        self.assertTrue(f.ok, f.status)
        self.assertEqual(f.header.frame_id, "map")
        self.assertAlmostEqual(f.robot.x, 1.0, delta=1e-6)
        self.assertAlmostEqual(f.robot.theta, 0.3, delta=1e-6)
        # Walls come out in the map frame: one lies along x = -2, one along y = 2.5.
        west = [w for w in f.walls if abs(w.start.x + 2) < 0.1 and abs(w.end.x + 2) < 0.1]
        north = [w for w in f.walls if abs(w.start.y - 2.5) < 0.1 and abs(w.end.y - 2.5) < 0.1]
        self.assertTrue(west and north, [(w.start, w.end) for w in f.walls])
        self.assertEqual(len(f.doors), 1)
        self.assertAlmostEqual(f.doors[0].center.x, DOOR_CENTRE[0], delta=0.1)
        self.assertAlmostEqual(f.doors[0].center.y, DOOR_CENTRE[1], delta=0.1)

        nan = room_cloud()
        nan[::2] = np.nan
        f = self._send("from_cloud", self.cloud_pub, points_to_cloud(nan, Header(frame_id="map")))
        self.assertTrue(f.ok, "NaN points are skipped: " + f.status)

        no_xyz = PointCloud2(header=Header(frame_id="map"), height=1, width=4, point_step=4, row_step=16,
                             data=bytes(16), fields=[PointField("intensity", 0, PointField.FLOAT32, 1)])
        bad = {"unknown frame": points_to_cloud(room_cloud(), Header(frame_id="odom")),
               "no x/y/z": no_xyz,
               "empty": points_to_cloud(np.empty((0, 3)), Header(frame_id="map")),
               "all NaN": points_to_cloud(np.full((100, 3), np.nan), Header(frame_id="map"))}
        for name, msg in bad.items():
            f = self._send("from_cloud", self.cloud_pub, msg)
            self.assertFalse(f.ok, name)
            self.assertNotEqual(f.status, "ok", name)
            self.assertEqual(len(f.walls), 0, name)
        self.assertIn("odom", self._send("from_cloud", self.cloud_pub, bad["unknown frame"]).status)
        f = self._send("from_cloud", self.cloud_pub, cloud)
        self.assertTrue(f.ok, f.status)


if __name__ == "__main__":
    rospy.init_node("test_features")
    rostest.rosrun("sparse_nav", "test_features", FeatureExtractorTest)
