#!/usr/bin/python3
"""rostest: the cartographer keeps a fragment per SLAM map, merges, refuses bad input and names."""
import os
import shutil
import threading
import unittest

import numpy as np
import rospy
import rostest
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from sparse_nav.cartographer import FragmentStore, encode
from sparse_nav.msg import SlamState
from sparse_nav.ros.conversions import cloud_to_points, points_to_cloud
from sparse_nav.srv import ListFragments, MapFile


def cloud_points(seed, n=300):
    return np.random.default_rng(seed).uniform(-3.0, 3.0, size=(n, 3))


class CartographerNodeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.map_dir = rospy.get_param("~map_dir")
        cls.store = FragmentStore(cls.map_dir)
        cls.lock = threading.Lock()
        cls.fragments = []
        rospy.Subscriber("cartographer/fragment", PointCloud2, cls._on_fragment, queue_size=5)
        cls.state_pub = rospy.Publisher("slam/state", SlamState, queue_size=10, latch=True)
        cls.cloud_pub = rospy.Publisher("cloud/filtered", PointCloud2, queue_size=10)
        for name in ("save", "load", "list"):
            rospy.wait_for_service(f"cartographer/{name}", timeout=120.0)
        cls.save = rospy.ServiceProxy("cartographer/save", MapFile)
        cls.load = rospy.ServiceProxy("cartographer/load", MapFile)
        cls.list = rospy.ServiceProxy("cartographer/list", ListFragments)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.map_dir, ignore_errors=True)

    @classmethod
    def _on_fragment(cls, msg):
        with cls.lock:
            cls.fragments.append(msg)

    def _state(self, state, index):
        msg = SlamState(state=state, map_index=index, source="test", reason="test")
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = "map"
        self.state_pub.publish(msg)
        rospy.sleep(0.5)

    def _cloud(self, points, frame="map"):
        self.cloud_pub.publish(points_to_cloud(points, Header(stamp=rospy.Time.now(),
                                                              frame_id=frame)))

    def _wait_for(self, condition, timeout_s=60.0):
        deadline = rospy.Time.now() + rospy.Duration(timeout_s)
        while rospy.Time.now() < deadline and not rospy.is_shutdown():
            if condition():
                return True
            rospy.sleep(0.1)
        return False

    def _points_of(self, name):
        try:
            return len(self.store.load(name)[0])
        except ValueError:
            return None

    def test_fragments_switches_merges_and_bad_input(self):
        rospy.sleep(1.0)  # let the node's subscriptions connect
        self._state(SlamState.OK, 1)
        self._cloud(cloud_points(1))
        self.assertTrue(self._wait_for(lambda: self._points_of("s001_map001") == 300),
                        "the first map's fragment was not saved as it went")

        # Bad clouds leave the fragment as it was.
        nan = cloud_points(2)
        nan[3] = np.nan
        self._cloud(nan)
        self._cloud(cloud_points(3), frame="odom")
        no_xyz = points_to_cloud(cloud_points(4), Header(stamp=rospy.Time.now(), frame_id="map"))
        no_xyz.fields = [PointField(name="intensity", offset=0, datatype=PointField.FLOAT32,
                                    count=1)]
        self.cloud_pub.publish(no_xyz)
        truncated = points_to_cloud(cloud_points(5), Header(stamp=rospy.Time.now(),
                                                            frame_id="map"))
        truncated.data = truncated.data[:100]
        self.cloud_pub.publish(truncated)
        rospy.sleep(3.0)
        self.assertEqual(self._points_of("s001_map001"), 300)

        # A new SLAM map: the old fragment is kept, the new one saved as it goes.
        self._state(SlamState.LOST, 1)
        self._state(SlamState.NEW_MAP, 2)
        self._cloud(cloud_points(6, n=200))
        self.assertTrue(self._wait_for(lambda: self._points_of("s001_map002") == 200))
        self.assertEqual(self._points_of("s001_map001"), 300)

        # SLAM merges map 2 back into map 1: one combined fragment.
        self._state(SlamState.NEW_MAP, 1)
        self.assertTrue(self._wait_for(lambda: self._points_of("s001_map001") == 500))
        self.assertFalse(os.path.exists(os.path.join(self.map_dir, "s001_map002.frag")))

        # Hostile names are refused and nothing is written outside map_dir.
        parent = os.path.dirname(self.map_dir)
        before = set(os.listdir(parent))
        for name in ("../escaped", "/tmp/escaped", "a/b", "", ".."):
            answer = self.save(name)
            self.assertFalse(answer.success, name)
            self.assertIn("name", answer.message)
            self.assertFalse(self.load(name).success, name)
        self.assertEqual(set(os.listdir(parent)) - before, set())
        self.assertTrue(self.save("kitchen").success)
        self.assertEqual(self._points_of("kitchen"), 500)

        # A corrupt file is refused with a clear error; the node keeps serving.
        with open(os.path.join(self.map_dir, "broken.frag"), "wb") as f:
            f.write(encode(cloud_points(7))[:-10])
        answer = self.load("broken")
        self.assertFalse(answer.success)
        self.assertIn("truncated", answer.message)
        listing = self.list()
        self.assertTrue(listing.success)
        entries = dict(zip(listing.names, zip(listing.n_points, listing.errors)))
        self.assertEqual(entries["kitchen"], (500, ""))
        self.assertEqual(entries["s001_map001"], (500, ""))
        self.assertEqual(entries["broken"][0], 0)
        self.assertIn("truncated", entries["broken"][1])
        answer = self.load("kitchen")
        self.assertTrue(answer.success, answer.message)
        self.assertTrue(self._wait_for(lambda: len(self.fragments) > 0))
        with self.lock:
            loaded = cloud_to_points(self.fragments[-1])
        self.assertEqual(len(loaded), 500)


if __name__ == "__main__":
    rospy.init_node("test_cartographer_node")
    rostest.rosrun("sparse_nav", "cartographer_node", CartographerNodeTest)
