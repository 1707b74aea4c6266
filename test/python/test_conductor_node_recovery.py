"""The conductor node's recovery motion, run by its scan thread against a stand-in executor (no
ROS master): a robot the map puts inside an obstacle is moved out of it.

The recovery motion once handed the scan thread a bare list of steps where it expects a
ScanRunner; the thread died at once, the robot never moved, and the conductor asked again every
tick until it gave up "inside an obstacle"."""
import threading

import numpy as np
import pytest

conductor_node = pytest.importorskip("sparse_nav.ros.conductor_node")

from sparse_nav.conductor import Action, ActionKind, Observation  # noqa: E402
from sparse_nav.conductor.grid_queries import GridView  # noqa: E402
from sparse_nav.conductor.scan_runner import ScanRunnerConfig  # noqa: E402


class RecordingExecutor:
    def __init__(self):
        self.steps = []

    def execute(self, step, speed_factor=1.0, should_stop=lambda: False):
        self.steps.append(step)
        return True


def node_with(grid):
    """A ConductorNode with only what its scan thread and _carry_out use."""
    node = conductor_node.ConductorNode.__new__(conductor_node.ConductorNode)
    node.grid = grid
    node.tello = None
    node.executor = RecordingExecutor()
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
