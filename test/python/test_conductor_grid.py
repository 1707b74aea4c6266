"""Grid queries of the conductor on a hand-made grid."""
import math

import numpy as np
import pytest

from sparse_nav.conductor.grid_queries import GridView


@pytest.fixture
def room():
    # 4 m x 3 m at 0.1 m with walls on the border, unknown beyond x = 3 on the top rows.
    cells = np.zeros((30, 40), dtype=np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 100
    cells[20:29, 30:39] = -1
    return GridView(cells, 0.1, (-1.0, -1.0))


def test_free_distance_stops_at_walls_and_the_map_edge(room):
    assert room.free_distance(0.0, 0.0, 0.0) == pytest.approx(2.9, abs=0.06)     # wall at x=2.9
    assert room.free_distance(0.0, 0.0, math.pi / 2) == pytest.approx(1.9, abs=0.06)
    assert room.free_distance(0.0, 0.0, math.pi, max_m=0.5) == pytest.approx(0.5)
    assert room.free_distance(10.0, 10.0, 0.0) == 0.0  # off the map


def test_cells_and_obstacles(room):
    assert room.cell(-0.95, 0.0) == 100 and room.in_obstacle(-0.95, 0.0)
    assert room.cell(0.0, 0.0) == 0 and not room.in_obstacle(0.0, 0.0)
    assert room.cell(2.5, 1.5) == -1 and not room.in_obstacle(2.5, 1.5)
    assert room.cell(-5.0, 0.0) is None
    assert room.free_cells_near(0.0, 0.0, 0.2) == 25
