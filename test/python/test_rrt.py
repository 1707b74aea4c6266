"""Seed 001's RRT (sparse_nav.navigation.rrt) on boolean grids (no master)."""
import math

import numpy as np
import pytest

from sparse_nav.navigation.rrt import Rrt, RrtConfig


def maze():
    """40 x 30 cells: two walls with gaps at opposite ends, so the path must zig-zag."""
    free = np.ones((30, 40), dtype=bool)
    free[0:24, 13] = False
    free[6:30, 26] = False
    return free


def assert_clear(free, path):
    """Every point along every edge (at 0.05 cell spacing) lies in a free cell."""
    for a, b in zip(path, path[1:]):
        n = max(1, int(math.dist(a, b) / 0.05))
        for t in np.linspace(0.0, 1.0, n + 1):
            x = a[0] + t * (b[0] - a[0])
            y = a[1] + t * (b[1] - a[1])
            cx, cy = int(round(x)), int(round(y))
            assert free[cy, cx], f"edge {a} -> {b} crosses cell ({cx}, {cy})"


def test_finds_a_clear_path_through_the_maze():
    free = maze()
    cfg = RrtConfig(step_cells=4.0, goal_threshold_cells=4.0, edge_sample_spacing_cells=0.05)
    result = Rrt(free, cfg).plan((2, 2), (37, 27))
    assert result.found()
    assert result.path[0] == (2.0, 2.0) and result.path[-1] == (37.0, 27.0)
    assert_clear(free, result.path)
    steps = [math.dist(a, b) for a, b in zip(result.path, result.path[1:])]
    assert max(steps[:-1]) <= cfg.step_cells + 1e-9
    assert steps[-1] <= cfg.goal_threshold_cells + 1e-9
    assert result.length == pytest.approx(sum(steps))
    # The walls force a detour: longer than the straight line.
    assert result.length > math.dist((2, 2), (37, 27)) * 1.2


def test_seeded_runs_repeat():
    free = maze()
    a = Rrt(free, RrtConfig(seed=3, step_cells=3.0)).plan((2, 2), (37, 27))
    b = Rrt(free, RrtConfig(seed=3, step_cells=3.0)).plan((2, 2), (37, 27))
    c = Rrt(free, RrtConfig(seed=4, step_cells=3.0)).plan((2, 2), (37, 27))
    assert a.path == b.path and a.iterations == b.iterations
    assert a.path != c.path


def test_full_goal_bias_goes_straight():
    free = np.ones((20, 30), dtype=bool)
    result = Rrt(free, RrtConfig(goal_bias=1.0, step_cells=5.0, goal_threshold_cells=1.0)).plan(
        (0, 0), (24, 18))
    # Each iteration steps 5 cells along the line; the last node is within 1 cell, then the goal.
    assert len(result.path) == 7
    for x, y in result.path:
        assert y == pytest.approx(x * 18 / 24)
    assert result.length == pytest.approx(30.0)


def test_restart_cap_gives_up_on_an_enclosed_goal():
    free = np.ones((20, 20), dtype=bool)
    free[8:13, 8] = free[8:13, 12] = False
    free[8, 8:13] = free[12, 8:13] = False
    cfg = RrtConfig(max_iterations=200, max_restarts=2, step_cells=3.0)
    result = Rrt(free, cfg).plan((1, 1), (10, 10))
    assert not result.found() and math.isinf(result.length)
    assert result.iterations == 3 * 200 and result.restarts == 2


def test_thin_wall_is_not_crossed_with_default_sampling():
    free = np.ones((11, 11), dtype=bool)
    free[:, 5] = False
    free[10, 5] = True
    result = Rrt(free, RrtConfig(step_cells=6.0, seed=1)).plan((1, 1), (9, 1))
    assert result.found()
    assert_clear(free, result.path)
    assert any(p[1] >= 9.5 for p in result.path)  # through the gap in the last row


def test_blocked_start_or_goal_and_bad_config():
    free = np.ones((5, 5), dtype=bool)
    free[2, 2] = False
    assert not Rrt(free).plan((2, 2), (4, 4)).found()
    assert not Rrt(free).plan((0, 0), (7, 0)).found()
    for bad in (dict(goal_bias=1.5), dict(step_cells=0.0), dict(max_iterations=0),
                dict(goal_threshold_cells=math.nan)):
        with pytest.raises(ValueError):
            Rrt(free, RrtConfig(**bad))
    with pytest.raises(ValueError):
        Rrt(np.ones((0, 3), dtype=bool))
