#!/usr/bin/python3
"""rostest: rviz/sparse_nav.rviz under Xvfb draws the SLAM cloud (red points) of the running sim.

rviz renders in wall-clock time with software GL, so this test waits in wall time, generously.
"""
import os
import shutil
import subprocess
import tempfile
import threading
import time
import unittest

import cv2
import numpy as np
import rospkg
import rospy
import rostest
from sensor_msgs.msg import PointCloud2

from sparse_nav.ros.robot_io import TelloClient
from sparse_nav.scanning import initial_scan, to_tello_commands

SCREENSHOT = os.path.join(tempfile.gettempdir(), "sparse_nav_rviz_screenshot.png")


def _free_display():
    for n in range(90, 140):
        if not os.path.exists(f"/tmp/.X11-unix/X{n}") and not os.path.exists(f"/tmp/.X{n}-lock"):
            return f":{n}"
    raise RuntimeError("no free X display number")


def _screenshot(display):
    xwd = subprocess.run(["xwd", "-root", "-silent", "-display", display], capture_output=True,
                         timeout=60, check=True).stdout
    ppm = subprocess.run(["xwdtopnm"], input=xwd, capture_output=True, timeout=60,
                         check=True).stdout
    return cv2.imdecode(np.frombuffer(ppm, np.uint8), cv2.IMREAD_COLOR)


def red_pixels(image):
    """Pixels of the flat red cloud colour (BGR image)."""
    b, g, r = (image[:, :, i].astype(int) for i in range(3))
    return int(np.count_nonzero((r > 180) & (g < 80) & (b < 80)))


class RvizScreenshotTest(unittest.TestCase):
    def setUp(self):
        self.points = 0
        self.lock = threading.Lock()
        rospy.Subscriber("slam/points", PointCloud2, self._on_points, queue_size=2)
        self.drone = TelloClient()
        self.procs = []

    def tearDown(self):
        for proc in reversed(self.procs):
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()

    def _on_points(self, msg):
        with self.lock:
            self.points = msg.width * msg.height

    def test_cloud_is_drawn(self):
        for tool in ("Xvfb", "xwd", "xwdtopnm", "rviz"):
            self.assertIsNotNone(shutil.which(tool), f"{tool} is installed by make setup")
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        rospy.sleep(1.0)
        for command in ["command", "takeoff"] + to_tello_commands(initial_scan())[:30]:
            self.drone.send(command)
            with self.lock:
                if self.points >= 300:
                    break
        with self.lock:
            self.assertGreaterEqual(self.points, 100, "the bridge publishes a cloud to draw")

        display = _free_display()
        env = dict(os.environ, DISPLAY=display, LIBGL_ALWAYS_SOFTWARE="1")
        self.procs.append(subprocess.Popen(
            ["Xvfb", display, "-screen", "0", "1280x1024x24", "+extension", "GLX", "-nolisten",
             "tcp"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        time.sleep(3.0)
        config = os.path.join(rospkg.RosPack().get_path("sparse_nav"), "rviz", "sparse_nav.rviz")
        self.procs.append(subprocess.Popen(["rviz", "-d", config], env=env,
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        best, image = 0, None
        deadline = time.monotonic() + 150.0
        while time.monotonic() < deadline and best < 200:
            time.sleep(5.0)
            self.drone.send("cw 10")  # keep flying while rviz draws: no auto-landing
            shot = _screenshot(display)
            count = red_pixels(shot)
            if count >= best:
                best, image = count, shot
        self.assertIsNotNone(image, "a screenshot was taken")
        cv2.imwrite(SCREENSHOT, image)
        rospy.loginfo("rviz screenshot with %d cloud pixels: %s", best, SCREENSHOT)
        self.assertGreater(float(np.std(image)), 5.0, "the screen is not blank")
        self.assertGreaterEqual(best, 200, f"the 3D view shows the red SLAM cloud ({SCREENSHOT})")


if __name__ == "__main__":
    rospy.init_node("test_rviz_screenshot")
    rostest.rosrun("sparse_nav", "rviz_screenshot", RvizScreenshotTest)
