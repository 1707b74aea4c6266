"""The demo's pictures, from the ROS-free plotting module."""
import numpy as np

from sparse_nav.sim.world import load_world
from sparse_nav.summary import plot_grid, plot_summary


def test_the_grid_picture_is_written_for_a_grid_and_for_an_empty_one(tmp_path):
    # The demo's last grid is empty when SLAM started a new map just before the end: the picture
    # (and the report written after it) must not be lost to it.
    world = load_world("one_room")
    cells = np.full((40, 60), -1, dtype=np.int8)
    cells[10:30, 10:50] = 0
    cells[10, 10:50] = 100
    for name, grid in (("grid.png", cells), ("empty.png", np.zeros((0, 0), dtype=np.int8))):
        path = tmp_path / name
        plot_grid(str(path), world, grid, 0.1, (0.0, 0.0), np.eye(4), title="test")
        assert path.stat().st_size > 1000


def test_the_summary_picture_takes_an_empty_cloud(tmp_path):
    world = load_world("one_room")
    path = tmp_path / "summary.png"
    plot_summary(str(path), world, np.empty((0, 3)), [(3.0, 2.5), (5.5, 6.6)], [], title="test")
    assert path.stat().st_size > 1000
