"""The conductor node's scan thread against a stand-in executor (no ROS master): the recovery
motion moves a robot the map puts inside an obstacle out of it, and a ground robot's scan cut off
for relocalising goes on from where its cut step began.

The recovery motion once handed the scan thread a bare list of steps where it expects a
ScanRunner; the thread died at once, the robot never moved, and the conductor asked again every
tick until it gave up "inside an obstacle"."""
import math
import threading

import numpy as np
import pytest

conductor_node = pytest.importorskip("sparse_nav.ros.conductor_node")

from sparse_nav.conductor import Action, ActionKind, Observation  # noqa: E402
from sparse_nav.conductor.grid_queries import GridView  # noqa: E402
from sparse_nav.conductor.scan_runner import ScanRunner, ScanRunnerConfig  # noqa: E402
from sparse_nav.scanning import Step, pose_after  # noqa: E402


class RecordingExecutor:
    """Records the steps and moves the odometry pose by each (None: the robot has none);
    cut_at: the step, by count, during which the scan is stopped (relocalising)."""

    def __init__(self, node, cut_at=None):
        self.node, self.cut_at = node, cut_at
        self.steps, self.poses = [], []

    def execute(self, step, speed_factor=1.0, should_stop=lambda: False):
        self.steps.append(step)
        self.poses.append(self.node.odom_pose)
        if len(self.steps) == self.cut_at:
            self.node.scan_stop.set()
            return False
        if self.node.odom_pose is not None:
            self.node.odom_pose = pose_after(self.node.odom_pose, [step])
        return True


def node_with(grid):
    """A ConductorNode with only what its scan thread and _carry_out use."""
    node = conductor_node.ConductorNode.__new__(conductor_node.ConductorNode)
    node.grid = grid
    node.tello = None
    node.robot = "ground"
    node.odom_frame = "odom"
    node.odom_pose = None
    node._robot_pose = lambda frame=None: node.odom_pose if frame == "odom" else None
    node.executor = RecordingExecutor(node)
    node.runner_config = ScanRunnerConfig()
    node.scan_thread = None
    node.scan_stop = threading.Event()
    node.lock = threading.Lock()
    node.obs = Observation(time_s=0.0)
    node.paused_scan = None
    return node


def recover(node, pose):
    node._carry_out(Action(ActionKind.RECOVER_MOTION), pose)
    node.scan_thread.join(timeout=30.0)
    assert not node.scan_thread.is_alive()


def test_the_recovery_motion_moves_the_robot_to_the_nearest_free_cell():
    cells = np.zeros((40, 40), dtype=np.int8)
    cells[:, 18:] = 100                       # everything east of x = 0.9 m is occupied
    grid = GridView(cells=cells, resolution_m=0.05, origin_xy=(0.0, 0.0))
    node = node_with(grid)
    recover(node, (1.025, 1.025, 0.0))        # a cell centre in the occupied part, facing east
    turn, forward = node.executor.steps
    assert abs(abs(turn.ccw_deg) - 180) <= 1  # about to face west, to the free cells
    assert forward.forward_m >= 0.2
    assert node.paused_scan is None           # a recovery motion is never resumed as a scan


def test_without_a_free_cell_nearby_it_still_moves_aside_and_back():
    node = node_with(None)
    recover(node, (1.0, 1.0, 0.0))
    assert [(s.forward_m, s.ccw_deg) for s in node.executor.steps] == [(0.2, 30.0), (-0.2, 0.0)]


def test_a_ground_scan_cut_off_goes_on_from_where_its_cut_step_began():
    node = node_with(None)
    node.odom_pose = (0.0, 0.0, 0.0)
    node.executor.cut_at = 2                  # stopped during the turn, to relocalise
    steps = [Step(forward_m=0.3), Step(ccw_deg=-60.0), Step(forward_m=0.3)]
    node._start_runner(ScanRunner(steps, node.runner_config))
    node.scan_thread.join(timeout=30.0)
    assert node.paused_scan is not None
    node.odom_pose = (0.9, 0.4, 1.2)          # where relocalising left the robot
    node._start_scan("resume", None)
    node.scan_thread.join(timeout=30.0)
    assert not node.scan_thread.is_alive() and node.paused_scan is None
    redone = node.executor.steps.index(steps[1], 2)
    # Back to (0.3, 0, 0), where the cut turn began, then the turn and the rest of the scan.
    assert node.executor.poses[redone] == pytest.approx((0.3, 0.0, 0.0), abs=1e-9)
    assert node.executor.steps[redone:] == steps[1:]
    assert node.odom_pose == pytest.approx((0.3 + 0.3 * math.cos(math.radians(-60)),
                                            0.3 * math.sin(math.radians(-60)),
                                            math.radians(-60)), abs=1e-9)


def test_without_odometry_a_cut_scan_goes_on_where_it_is():
    node = node_with(None)
    node.executor.cut_at = 2
    steps = [Step(forward_m=0.3), Step(ccw_deg=-60.0)]
    node._start_runner(ScanRunner(steps, node.runner_config))
    node.scan_thread.join(timeout=30.0)
    node._start_scan("resume", None)
    node.scan_thread.join(timeout=30.0)
    assert node.executor.steps == [steps[0], steps[1], steps[1]]


class LosingExecutor(RecordingExecutor):
    """Loses tracking halfway through the step numbered lose_at (by count): the robot stops
    there when the scan thread asks, and tracking is back once it has moved again."""

    def __init__(self, node, lose_at):
        super().__init__(node)
        self.lose_at, self.speeds = lose_at, []

    def execute(self, step, speed_factor=1.0, should_stop=lambda: False):
        self.steps.append(step)
        self.speeds.append(speed_factor)
        self.poses.append(self.node.odom_pose)
        if self.node.obs.tracking_lost:
            self.node.obs.tracking_lost = False
        half = Step(step.forward_m / 2, step.left_m / 2, step.ccw_deg / 2)
        self._move(half)
        if len(self.steps) == self.lose_at:
            self.node.obs.tracking_lost = True
            if should_stop():
                return False
        self._move(half)
        return True

    def _move(self, step):
        if self.node.odom_pose is not None:
            self.node.odom_pose = pose_after(self.node.odom_pose, [step])


def test_a_ground_step_that_loses_tracking_stops_backs_off_and_is_redone_slower():
    node = node_with(None)
    node.odom_pose = (0.0, 0.0, 0.0)
    node.executor = LosingExecutor(node, lose_at=2)
    steps = [Step(forward_m=0.3), Step(ccw_deg=-60.0), Step(forward_m=0.3)]
    node._start_runner(ScanRunner(steps, node.runner_config))
    node.scan_thread.join(timeout=30.0)
    done = node.executor.steps
    # Stopped 30 deg into the turn, back 30 deg at full speed, the turn again at half speed.
    assert done[:2] == steps[:2]
    assert done[2].ccw_deg == pytest.approx(30.0) and not done[2].forward_m
    assert node.executor.speeds[2] == 1.0
    assert node.executor.poses[3] == pytest.approx((0.3, 0.0, 0.0), abs=1e-9)
    assert done[3:] == steps[1:] and node.executor.speeds[3] == 0.5
    assert node.odom_pose == pytest.approx((0.3 + 0.3 * math.cos(math.radians(-60)),
                                            0.3 * math.sin(math.radians(-60)),
                                            math.radians(-60)), abs=1e-9)


def test_without_odometry_a_step_that_loses_tracking_runs_to_its_end():
    node = node_with(None)
    node.executor = LosingExecutor(node, lose_at=2)
    steps = [Step(forward_m=0.3), Step(ccw_deg=-60.0)]
    node._start_runner(ScanRunner(steps, node.runner_config))
    node.scan_thread.join(timeout=30.0)
    # The drone's odometry is SLAM's own: the whole turn, then undone and redone slower.
    assert node.executor.steps == [steps[0], steps[1], steps[1].undo(), steps[1]]
