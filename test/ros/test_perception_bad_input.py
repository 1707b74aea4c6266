#!/usr/bin/python3
"""rostest: malformed clouds and map files leave the perception nodelets running with their map;
a new SLAM map starts the octree afresh."""
import os
import threading
import unittest

import numpy as np
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from sparse_nav.msg import SlamState
from sparse_nav.ros.conversions import cloud_to_points, points_to_cloud
from sparse_nav.srv import MapFile


def synthetic_room(seed=0):
    """A 6 m x 5 m room (map frame, z up) with a 1 m door in the north wall, and a floor."""
    rng = np.random.default_rng(seed)
    walls = [((0, 0), (6, 0)), ((6, 0), (6, 5)), ((0, 5), (0, 0)), ((6, 5), (3.5, 5)),
             ((2.5, 5), (0, 5))]
    points = []
    for (x1, y1), (x2, y2) in walls:
        n = int(np.hypot(x2 - x1, y2 - y1) * 60)
        t = rng.random(n)
        points.append(np.stack([x1 + t * (x2 - x1), y1 + t * (y2 - y1), rng.uniform(0.2, 2.0, n)], 1))
    floor = np.stack([rng.uniform(0.3, 5.7, 600), rng.uniform(0.3, 4.7, 600), np.zeros(600)], 1)
    points.append(floor)
    return np.vstack(points) + rng.normal(0, 0.01, (sum(len(p) for p in points), 3))


class PerceptionBadInputTest(unittest.TestCase):
    def setUp(self):
        self.map_dir = rospy.get_param("~map_dir")
        self.lock = threading.Lock()
        self.maps = []
        self.octree_leaves = []
        self.filter_changed = []
        self.filtered = []
        rospy.Subscriber("map", OccupancyGrid, self._on_map, queue_size=5)
        rospy.Subscriber("cloud/filtered", PointCloud2, self._on_filtered, queue_size=5)
        rospy.Subscriber("/diagnostics", DiagnosticArray, self._on_diagnostics, queue_size=20)
        self.pub = rospy.Publisher("slam/points", PointCloud2, queue_size=2, latch=True)

    def _on_map(self, msg):
        with self.lock:
            self.maps.append(msg)

    def _on_filtered(self, msg):
        with self.lock:
            self.filtered.append(cloud_to_points(msg))

    def _on_diagnostics(self, msg):
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name == "ground_mapper":
                with self.lock:
                    self.octree_leaves.append(int(values["octree_leaves"]))
            elif status.name == "cloud_filter" and status.level == status.OK:
                with self.lock:
                    self.filter_changed.append(int(values["points_changed"]))

    def _publish(self, msg):
        msg.header.stamp = rospy.Time.now()
        self.pub.publish(msg)
        rospy.sleep(2.0)

    def _good(self, seed=0):
        return points_to_cloud(synthetic_room(seed), Header(frame_id="map"))

    def _wait_for_map(self, count, timeout_s=60.0):
        deadline = rospy.Time.now() + rospy.Duration(timeout_s)
        while rospy.Time.now() < deadline:
            with self.lock:
                if len(self.maps) >= count:
                    return self.maps[-1]
            rospy.sleep(0.1)
        return None

    def test_a_new_slam_map_starts_afresh(self):
        """The old map's points sit in another anchoring: after a map switch the octree holds only
        the new map's. Half the room after the switch gives fewer leaves than the whole room did,
        where a kept octree would only have grown."""
        rospy.wait_for_service("ground_mapper/load", 60.0)
        state = rospy.Publisher("slam/state", SlamState, queue_size=5, latch=True)
        state.publish(SlamState(state=SlamState.OK, map_index=0, source="wrapper", reason="test"))
        rospy.sleep(1.0)
        self._publish(self._good(seed=2))
        self.assertIsNotNone(self._wait_for_map(1), "a map from the whole room")
        with self.lock:
            whole = self.octree_leaves[-1]
        state.publish(SlamState(state=SlamState.NEW_MAP, map_index=1, source="wrapper",
                                reason="test: SLAM started a new map"))
        rospy.sleep(1.0)
        room = synthetic_room(seed=3)
        self._publish(points_to_cloud(room[room[:, 0] < 3.0], Header(frame_id="map")))
        with self.lock:
            half = self.octree_leaves[-1]
        self.assertLess(half, 0.8 * whole, f"octree leaves: {whole} for the room, {half} after the "
                        "switch for half of it")

    def test_cloud_filter_updates_the_voxels_of_the_points_that_moved(self):
        """SLAM map points keep their order: a cloud with 30 points moved is 30 changed points,
        and its voxel centroids are those of the whole moved cloud."""
        room = synthetic_room(seed=4)
        self._publish(points_to_cloud(room, Header(frame_id="map")))
        moved = room.copy()
        moved[::40][:30] += 0.2   # 30 of its ~1900 points
        with self.lock:
            n_filtered = len(self.filtered)
        self._publish(points_to_cloud(moved, Header(frame_id="map")))
        with self.lock:
            changed = self.filter_changed[-1]
            got = self.filtered[-1] if len(self.filtered) > n_filtered else None
        self.assertEqual(changed, 30)
        self.assertIsNotNone(got, "no cloud/filtered after the moved cloud")
        as_sent = moved.astype(np.float32).astype(np.float64)
        # The voxel of a point as the core computes it: floor(coordinate * (1 / leaf)) in double.
        keys, inverse = np.unique(np.floor(as_sent * (1.0 / 0.05)).astype(np.int64), axis=0,
                                  return_inverse=True)
        expected = np.zeros((len(keys), 3))
        np.add.at(expected, inverse.ravel(), as_sent)
        expected /= np.bincount(inverse.ravel())[:, None]
        order = lambda p: p[np.lexsort((p[:, 0], p[:, 1], p[:, 2]))]
        self.assertEqual(len(got), len(expected))
        np.testing.assert_allclose(order(got), order(expected), atol=1e-5)

    def test_bad_clouds_and_files(self):
        rospy.wait_for_service("ground_mapper/load", 60.0)
        self._publish(self._good())
        first = self._wait_for_map(1)
        self.assertIsNotNone(first, "a map from the good cloud")
        occupied = np.count_nonzero(np.asarray(first.data) == 100)
        self.assertGreater(occupied, 100)

        nan = synthetic_room()
        nan[::3] = np.nan
        nan[1::7] = np.inf
        huge = np.full((1000, 3), 1e9)
        no_xyz = PointCloud2(header=Header(frame_id="map"), height=1, width=4, point_step=4,
                             row_step=16, data=bytes(16),
                             fields=[PointField("intensity", 0, PointField.FLOAT32, 1)])
        truncated = self._good()
        truncated.data = truncated.data[:100]
        bad = [points_to_cloud(np.empty((0, 3)), Header(frame_id="map")),
               no_xyz, truncated,
               points_to_cloud(huge, Header(frame_id="map")),
               points_to_cloud(synthetic_room(), Header(frame_id="unknown_frame")),
               points_to_cloud(np.zeros((6_000_000, 3), np.float32), Header(frame_id="map")),
               points_to_cloud(nan, Header(frame_id="map"))]
        for msg in bad:
            self._publish(msg)
        with self.lock:
            latest = self.maps[-1]
        self.assertGreater(np.count_nonzero(np.asarray(latest.data) == 100), 100,
                           "the last good map is kept")

        save = rospy.ServiceProxy("ground_mapper/save", MapFile)
        load = rospy.ServiceProxy("ground_mapper/load", MapFile)
        result = save("room")
        self.assertTrue(result.success, result.message)
        self.assertTrue(os.path.isfile(os.path.join(self.map_dir, "room.bt")))
        with open(os.path.join(self.map_dir, "corrupt.bt"), "wb") as f:
            f.write(b"# Octomap OcTree binary file\nid OcTree\nsize 9\nres 0.05\ndata\n\x01\x02")
        result = load("corrupt")
        self.assertFalse(result.success)
        self.assertIn("not a valid OctoMap", result.message)
        for hostile in ("../x", "/etc/passwd", "a/b", ""):
            result = load(hostile)
            self.assertFalse(result.success, hostile)
            self.assertIn("invalid name", result.message)
        self.assertTrue(load("room").success)

        # Still running: a new good cloud still updates the map.
        with self.lock:
            before = len(self.maps)
        self._publish(self._good(seed=1))
        self.assertIsNotNone(self._wait_for_map(before + 1), "the nodes keep running")


if __name__ == "__main__":
    rospy.init_node("test_perception_bad_input")
    rostest.rosrun("sparse_nav", "perception_bad_input", PerceptionBadInputTest)
