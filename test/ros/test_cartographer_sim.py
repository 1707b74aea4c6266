#!/usr/bin/python3
"""rostest: fragments of the simulator's SLAM maps across a forced loss, reloaded by a restart
that refuses a corrupt file and keeps serving."""
import os
import shutil
import sys
import threading
import unittest

import rosnode
import rospy
import rostest
import roslaunch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from motion_harness import MotionHarness  # noqa: E402
from sparse_nav.cartographer import FragmentStore, encode  # noqa: E402
from sparse_nav.msg import SlamState  # noqa: E402
from sparse_nav.srv import ListFragments  # noqa: E402


class CartographerSimTest(unittest.TestCase):
    def setUp(self):
        self.map_dir = rospy.get_param("~map_dir")
        self.loss_s = rospy.get_param("~forced_loss_at_s")
        self.lock = threading.Lock()
        self.states = []
        rospy.Subscriber("slam/state", SlamState, self._on_state, queue_size=50)

    def tearDown(self):
        # Stop the cartographer first: it would otherwise go on saving into a removed directory.
        rosnode.kill_nodes(["/cartographer"])
        rospy.sleep(3.0)
        shutil.rmtree(self.map_dir, ignore_errors=True)

    def _on_state(self, msg):
        with self.lock:
            self.states.append(msg)

    def test_fragments_across_a_loss_and_a_restart(self):
        h = MotionHarness()
        h.wait_for_clock()
        # The initial scan until well after the forced loss: tracking, loss, a new map.
        for _ in range(10):
            h.initialise_slam(limit_s=self.loss_s + 40.0)
            if rospy.Time.now().to_sec() > self.loss_s + 20.0:
                break
        rospy.sleep(5.0)   # more than save_period_s: the last changes are on disk
        with self.lock:
            states = list(self.states)
        seen = [s for s in states if s.state in (SlamState.OK, SlamState.NEW_MAP)]
        self.assertTrue(seen, "SLAM never tracked")
        self.assertTrue(any(s.state == SlamState.LOST for s in states), "no forced loss seen")
        final_index = seen[-1].map_index
        indices = sorted({s.map_index for s in seen})
        rospy.loginfo("cartographer_sim: SLAM maps %s, final %d; files %s", indices, final_index,
                      sorted(os.listdir(self.map_dir)))
        store = FragmentStore(self.map_dir)
        names = store.names()
        self.assertIn(f"s001_map{final_index:03d}", names)
        self.assertIn("s001_map000", names, "the first map's fragment is kept")
        for name in names:
            points, meta = store.load(name)
            self.assertGreater(len(points), 50, name)
            self.assertEqual(meta["frame"], "map")
        if len(indices) > 1 and final_index != 0:
            self.assertGreaterEqual(len(names), 2, "a new SLAM map gets its own fragment")

        # A second cartographer, started now with a corrupt file beside the fragments, reloads
        # every good fragment, refuses the corrupt one with its reason, and keeps serving.
        with open(os.path.join(self.map_dir, "broken.frag"), "wb") as f:
            f.write(encode(points)[:-5])
        launch = roslaunch.scriptapi.ROSLaunch()
        launch.start()
        node = roslaunch.core.Node("sparse_nav", "cartographer", name="cartographer_restarted",
                                   namespace="/", remap_args=[("cloud/filtered", "unused")])
        rospy.set_param("/cartographer_restarted/map_dir", self.map_dir)
        process = launch.launch(node)
        try:
            rospy.wait_for_service("/cartographer_restarted/list", timeout=120.0)
            listing = rospy.ServiceProxy("/cartographer_restarted/list", ListFragments)()
            errors = dict(zip(listing.names, listing.errors))
            self.assertEqual(sorted(listing.names), sorted(names + ["broken"]))
            self.assertIn("truncated", errors.pop("broken"))
            self.assertEqual([e for e in errors.values() if e], [])
        finally:
            process.stop()
            launch.stop()


if __name__ == "__main__":
    rospy.init_node("test_cartographer_sim")
    rostest.rosrun("sparse_nav", "cartographer_sim", CartographerSimTest)
