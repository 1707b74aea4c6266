"""sparse_nav._planning: D* Lite, A* and smoothing through the pybind11 module (no master)."""
import math
import os
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparse_nav import _planning as planning

SQRT2 = math.sqrt(2.0)
MOVINGAI = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared",
                        "data", "movingai")
MOVINGAI_MAP = os.path.join(MOVINGAI, "Lucas-707_PAStar", "den312d.map")


def grid_from_text(rows, **kwargs):
    """'.' free, '#' blocked, '?' unknown; rows[y][x]."""
    values = {".": 0, "#": 100, "?": -1}
    array = np.array([[values[c] for c in row] for row in rows], dtype=np.int8)
    return planning.Grid(array, **kwargs)


def path_cost(grid, path):
    total = 0.0
    for a, b in zip(path, path[1:]):
        cost = grid.move_cost(a, b)
        assert math.isfinite(cost), f"illegal move {a} -> {b}"
        total += cost
    return total


def plan_both(grid, start, goal):
    """Plans with D* Lite and A*, checks that they agree and returns the cost."""
    path_a, cost_a = planning.astar(grid, start, goal)
    dstar = planning.DStarLite(grid, start, goal)
    found = dstar.plan()
    assert found == bool(path_a)
    if not found:
        assert math.isinf(cost_a) and math.isinf(dstar.cost())
        assert dstar.path() == []
        return math.inf
    assert dstar.cost() == pytest.approx(cost_a, rel=1e-9, abs=1e-12)
    for path in (path_a, dstar.path()):
        assert path[0] == start and path[-1] == goal
        assert path_cost(grid, path) == pytest.approx(cost_a, rel=1e-9, abs=1e-12)
    return cost_a


def test_open_grid_diagonal():
    for n in (1, 7, 30):
        grid = planning.Grid(np.zeros((n + 1, n + 1), dtype=np.int8))
        assert plan_both(grid, (0, 0), (n, n)) == pytest.approx(SQRT2 * n, rel=1e-12)


def test_wall_with_gap():
    rows = [["."] * 11 for _ in range(10)]
    for y in range(10):
        if y != 8:
            rows[y][5] = "#"
    grid = grid_from_text(["".join(r) for r in rows])
    assert plan_both(grid, (1, 1), (9, 1)) == pytest.approx(6 * SQRT2 + 10, rel=1e-12)


def test_no_corner_cutting():
    assert plan_both(grid_from_text(["..#", ".#.", "..."]), (0, 0), (2, 2)) == pytest.approx(4.0)
    assert math.isinf(plan_both(grid_from_text([".#", "#."]), (0, 0), (1, 1)))


def test_no_path_when_enclosed():
    grid = grid_from_text([".......", ".#####.", ".#...#.", ".#...#.", ".#####.", "......."])
    assert math.isinf(plan_both(grid, (0, 0), (3, 2)))
    assert planning.astar(grid, (0, 0), (3, 2)) == ([], math.inf)


def test_unknown_policy():
    rows = ["..?..", ".###.", "....."]
    assert plan_both(grid_from_text(rows, unknown_policy="free"), (0, 0), (4, 0)) == pytest.approx(4.0)
    costly = grid_from_text(rows, unknown_policy="costly", unknown_cost=1.5)
    assert plan_both(costly, (0, 0), (4, 0)) == pytest.approx(4.5)
    very = grid_from_text(rows, unknown_policy="costly", unknown_cost=10.0)
    assert plan_both(very, (0, 0), (4, 0)) == pytest.approx(8.0)
    blocked = grid_from_text(rows, unknown_policy="blocked")
    assert plan_both(blocked, (0, 0), (4, 0)) == pytest.approx(8.0)
    with pytest.raises(ValueError):
        grid_from_text(rows, unknown_policy="maybe")


def test_uint8_grid_and_inflation():
    array = np.zeros((9, 9), dtype=np.uint8)
    array[4, :] = 100
    array[4, 4:6] = 0  # a two-cell gap
    array[0, 8] = 255  # unknown
    assert plan_both(planning.Grid(array), (4, 0), (4, 8)) == pytest.approx(8.0)
    inflated = planning.Grid(array, inflation_radius=1.0)
    assert not inflated.traversable(4, 4)
    assert math.isinf(plan_both(inflated, (4, 0), (4, 8)))
    assert planning.Grid(array).states()[0, 8] == -1


def test_update_cells_and_move_start():
    grid = planning.Grid(np.zeros((20, 20), dtype=np.int8))
    dstar = planning.DStarLite(grid, (0, 10), (19, 10))
    assert dstar.plan()
    assert dstar.cost() == pytest.approx(19.0)
    wall = [(10, y, 100) for y in range(0, 18)]
    dstar.update_cells(wall)
    grid.update_cells(wall)
    assert dstar.plan()
    _, cost_a = planning.astar(grid, (0, 10), (19, 10))
    assert dstar.cost() == pytest.approx(cost_a, rel=1e-9)
    dstar.move_start(dstar.path()[3])
    with pytest.raises(RuntimeError):
        dstar.path()
    assert dstar.plan()
    _, cost_b = planning.astar(grid, dstar.start, (19, 10))
    assert dstar.cost() == pytest.approx(cost_b, rel=1e-9)
    dstar.update_cells([(10, 18, 100), (10, 19, 100)])
    assert not dstar.plan()
    assert dstar.path() == [] and math.isinf(dstar.cost())


def test_smooth_keeps_clear_of_obstacles():
    grid = grid_from_text(["..........", "..........", "....##....", "....##....", ".........."])
    path, _ = planning.astar(grid, (0, 3), (9, 3))
    smooth = planning.smooth(grid, path)
    assert smooth[0] == path[0] and smooth[-1] == path[-1]
    assert len(smooth) < len(path)
    for a, b in zip(smooth, smooth[1:]):
        assert planning.line_of_sight(grid, a, b)
    assert not planning.line_of_sight(grid_from_text([".#.", "...", "..."]), (0, 0), (2, 2))


SIZE = 14
cells = st.tuples(st.integers(0, SIZE - 1), st.integers(0, SIZE - 1))
values = st.sampled_from([0, 0, 100, 100, -1])


@settings(max_examples=150, deadline=None)
@given(initial=st.lists(cells, max_size=50),
       batches=st.lists(st.lists(st.tuples(cells, values), min_size=1, max_size=4), min_size=1, max_size=25),
       start=cells, goal=cells, inflate=st.booleans())
def test_incremental_replans_equal_fresh_astar(initial, batches, start, goal, inflate):
    array = np.zeros((SIZE, SIZE), dtype=np.int8)
    for x, y in initial:
        array[y, x] = 100
    kwargs = dict(unknown_policy="costly", unknown_cost=2.5, inflation_radius=1.0 if inflate else 0.0)
    reference = planning.Grid(array, **kwargs)
    dstar = planning.DStarLite(planning.Grid(array, **kwargs), start, goal)
    dstar.plan()
    for i, batch in enumerate(batches):
        changes = [(x, y, v) for (x, y), v in batch]
        dstar.update_cells(changes)
        reference.update_cells(changes)
        if i % 3 == 2 and dstar.plan() and len(dstar.path()) > 1:
            start = dstar.path()[1]
            dstar.move_start(start)
        found = dstar.plan()
        path_a, cost_a = planning.astar(reference, start, goal)
        assert found == bool(path_a)
        if found:
            assert dstar.cost() == pytest.approx(cost_a, rel=1e-9, abs=1e-12)
            assert path_cost(reference, dstar.path()) == pytest.approx(cost_a, rel=1e-9, abs=1e-12)


def read_movingai_map(path):
    with open(path) as f:
        lines = f.read().splitlines()
    assert lines[0].strip() == "type octile"
    height = int(lines[1].split()[1])
    width = int(lines[2].split()[1])
    assert lines[3].strip() == "map"
    rows = [line.rstrip("\r") for line in lines[4:4 + height]]
    passable = np.array([[c in ".GS" for c in row[:width]] for row in rows], dtype=bool)
    assert passable.shape == (height, width)
    return np.where(passable, 0, 100).astype(np.int8)


def read_scen(path):
    out = []
    with open(path) as f:
        for line in f.read().splitlines()[1:]:
            fields = line.strip().split("\t")
            if len(fields) == 9:
                out.append(((int(fields[4]), int(fields[5])), (int(fields[6]), int(fields[7])),
                            float(fields[8])))
    return out


@pytest.mark.skipif(not os.path.isdir(MOVINGAI), reason="Moving AI data absent")
def test_movingai_optimal_lengths_and_replan():
    grid = planning.Grid(read_movingai_map(MOVINGAI_MAP))
    scenarios = read_scen(MOVINGAI_MAP + ".scen")
    rng = random.Random(4)
    picked = [scenarios[0], scenarios[-1]] + rng.sample(scenarios, 10)
    for start, goal, optimal in picked:
        dstar = planning.DStarLite(grid, start, goal)
        assert dstar.plan()
        assert dstar.cost() == pytest.approx(optimal, rel=1e-6)
        path_a, cost_a = planning.astar(grid, start, goal)
        assert cost_a == pytest.approx(optimal, rel=1e-6)
        assert path_cost(grid, dstar.path()) == pytest.approx(optimal, rel=1e-6)
        path = dstar.path()
        if len(path) > 2:
            mx, my = path[len(path) // 2]
            dstar.update_cells([(mx, my, 100)])
            changed = planning.Grid(read_movingai_map(MOVINGAI_MAP))
            changed.update_cells([(mx, my, 100)])
            found = dstar.plan()
            _, fresh = planning.astar(changed, start, goal)
            assert found == math.isfinite(fresh)
            if found:
                assert dstar.cost() == pytest.approx(fresh, rel=1e-9)
                assert dstar.cost() >= optimal * (1.0 - 1e-6)
