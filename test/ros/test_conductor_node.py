#!/usr/bin/python3
"""rostest: the conductor node drives the mission's phases on the simulated drone.

The test node stands in for the navigator (a MoveBase action server that reports each goal
reached) and the exit finder (a FindExit service answering a fixed exit), so the conductor's own
behaviour is what is checked: scans with takeoff, LOST on a forced SLAM loss and back, the exit
request, the goal to the exit, the pass-through goal beyond it, done, and landing only once the
motion layer (also a stand-in: it reports "following" until told otherwise) has stopped.
"""
import threading
import unittest

import actionlib
import rospy
import rostest
from geometry_msgs.msg import Point
from move_base_msgs.msg import MoveBaseAction, MoveBaseResult
from std_msgs.msg import String
from std_srvs.srv import Trigger

from sparse_nav.msg import ConductorState, ExitCandidates, MotionStatus
from sparse_nav.srv import FindExit, FindExitResponse

EXIT = (2.5, 3.0)  # map frame; any reachable-looking point will do for the stand-ins


class ConductorNodeTest(unittest.TestCase):
    def setUp(self):
        self.limit_s = float(rospy.get_param("~sim_time_limit_s"))
        self.lock = threading.Lock()
        self.states = []
        self.commands = []   # (sim time s, command)
        self.goals = []
        self.exit_calls = 0
        rospy.Subscriber("conductor/state", ConductorState, self._on_state, queue_size=50)
        rospy.Subscriber("tello/command", String, self._on_command, queue_size=200)
        rospy.Service("exit_finder/find_exit", FindExit, self._find_exit)
        self.motion_pub = rospy.Publisher("motion/status", MotionStatus, queue_size=5, latch=True)
        self.server = actionlib.SimpleActionServer("move_base", MoveBaseAction,
                                                   execute_cb=self._navigate, auto_start=False)
        self.server.start()

    def _on_state(self, msg):
        with self.lock:
            self.states.append(msg)

    def _on_command(self, msg):
        with self.lock:
            self.commands.append((rospy.Time.now().to_sec(), msg.data))

    def _find_exit(self, request):
        with self.lock:
            self.exit_calls += 1
        candidates = ExitCandidates(status=ExitCandidates.STATUS_OK, reason="stand-in",
                                    method="stand-in", exits=[Point(x=EXIT[0], y=EXIT[1])],
                                    scores=[1.0])
        candidates.header.frame_id = "map"
        return FindExitResponse(success=True, candidates=candidates)

    def _navigate(self, goal):
        with self.lock:
            p = goal.target_pose.pose.position
            self.goals.append((goal.target_pose.header.frame_id, p.x, p.y))
        self._motion(MotionStatus.FOLLOWING)
        end = rospy.Time.now() + rospy.Duration(3.0)
        while rospy.Time.now() < end and not rospy.is_shutdown():
            if self.server.is_preempt_requested():
                self.server.set_preempted()
                return
            rospy.sleep(0.1)
        self.server.set_succeeded(MoveBaseResult())

    def _motion(self, state):
        msg = MotionStatus(state=state, reason="stand-in", distance_to_goal_m=float("nan"),
                           heading_error_deg=float("nan"))
        msg.header.stamp = rospy.Time.now()
        self.motion_pub.publish(msg)

    def _phase(self):
        with self.lock:
            return self.states[-1].phase if self.states else None

    def test_mission_phases_on_the_drone(self):
        while rospy.Time.now().is_zero() and not rospy.is_shutdown():
            rospy.sleep(0.05)
        rospy.wait_for_service("conductor/start", timeout=60.0)
        # The latched state reaches this subscriber some time after the service is up.
        give_up = rospy.Time.now() + rospy.Duration(30.0)
        while self._phase() is None and rospy.Time.now() < give_up and not rospy.is_shutdown():
            rospy.sleep(0.1)
        self.assertEqual(self._phase(), "waiting", "the conductor waits for ~start")
        self.assertTrue(rospy.ServiceProxy("conductor/start", Trigger)().success)
        while (self._phase() not in ("done", "gave_up") and not rospy.is_shutdown()
               and rospy.Time.now().to_sec() < self.limit_s):
            rospy.sleep(0.5)
        # The motion layer still follows its last path for a moment after the final state.
        rospy.sleep(1.5)
        motion_stopped_s = rospy.Time.now().to_sec()
        self._motion(MotionStatus.IDLE)
        rospy.sleep(5.0)  # the landing command follows
        with self.lock:
            states = list(self.states)
            landed_s = [t for t, c in self.commands if c == "land"]
            commands = [c for _, c in self.commands]
            goals = list(self.goals)
        phases = [s.phase for s in states]
        trail = [(s.state, s.phase, s.reason) for s in states]
        self.assertEqual(phases[-1], "done", f"the mission ends done: {trail}")
        # Up to the look around beyond the exit: every phase, in order, never going back. What
        # the look around decides depends on the map (without one, done; the stand-in exit lies
        # inside the room, so walls all round send the conductor to the finder again).
        order = ["initial_scan", "find_exit", "go_to_exit", "pass_through", "look_around"]
        self.assertIn("look_around", phases, f"the robot looks around beyond the exit: {trail}")
        until_look = phases[:phases.index("look_around") + 1]
        self.assertEqual([p for p in order if p in until_look], order,
                         f"every phase, in order: {trail}")
        self.assertEqual([p for p in until_look if p in order], sorted(
            [p for p in until_look if p in order], key=order.index),
            f"phases never go back: {trail}")
        self.assertIn("LOST", [s.state for s in states], f"the forced loss is seen: {trail}")
        self.assertTrue(all(s.reason for s in states), "every state carries its reason")
        self.assertEqual(commands[:2], ["command", "takeoff"], "the drone takes off first")
        self.assertEqual(commands[-1], "land", "and lands at the end")
        self.assertEqual(len(landed_s), 1, "once")
        self.assertGreaterEqual(landed_s[0], motion_stopped_s,
                                "after the motion layer stopped sending commands")
        self.assertTrue(any(c.startswith("speed") for c in commands))
        self.assertGreater(sum(1 for c in commands if c.split()[0] in ("cw", "ccw")), 12,
                           "the scans turn the drone")
        # A goal is sent again after a loss or a recovery; the distinct goals are what matters.
        goals = [g for i, g in enumerate(goals) if i == 0 or g != goals[i - 1]]
        self.assertEqual(len(goals), 2, f"a goal to the exit, then beyond it: {goals}")
        self.assertEqual(goals[0], ("map", EXIT[0], EXIT[1]))
        last = states[-1]
        self.assertTrue(last.has_exit)
        self.assertAlmostEqual(last.exit.x, EXIT[0])
        # The pass-through goal lies further from the start than the exit, on the same side.
        start_to_exit = (EXIT[0] ** 2 + EXIT[1] ** 2) ** 0.5
        beyond = (goals[1][1] ** 2 + goals[1][2] ** 2) ** 0.5
        self.assertGreater(beyond, start_to_exit - 0.5)


if __name__ == "__main__":
    rospy.init_node("test_conductor_node")
    rostest.rosrun("sparse_nav", "conductor_phases", ConductorNodeTest)
