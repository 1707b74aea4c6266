"""Grid queries of the conductor on a hand-made grid."""
import math

import numpy as np
import pytest

from sparse_nav.conductor.grid_queries import (GridView, order_exits, steps_out_of_obstacle,
                                                widest_opening_deg)


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


def test_nearest_free_cell_is_known_free_and_within_reach(room):
    # (-0.95, 0.45) lies in the west wall (column 0); the free cell next to it is column 1.
    assert room.nearest_free(-0.95, 0.45, 0.5) == pytest.approx((-0.85, 0.45))
    assert room.nearest_free(0.02, 0.03, 0.5) == pytest.approx((0.05, 0.05))  # its own cell
    walled = GridView(np.full((10, 10), 100, dtype=np.int8), 0.1, (0.0, 0.0))
    walled.cells[9, 9] = -1  # unknown is not free
    assert walled.nearest_free(0.05, 0.05, 2.0) is None
    walled.cells[0, 9] = 0  # 0.9 m east of (0.05, 0.05)
    assert walled.nearest_free(0.05, 0.05, 0.5) is None
    assert walled.nearest_free(0.05, 0.05, 1.0) == pytest.approx((0.95, 0.05))


def test_steps_out_of_an_obstacle_face_the_nearest_free_cell_and_end_on_it(room):
    # In the south wall (row 0) facing east: the free cell lies north, a quarter turn left.
    steps = steps_out_of_obstacle(room, (0.55, -0.95, 0.0))
    assert [s.ccw_deg for s in steps] == [90, 0] and steps[0].forward_m == 0.0
    assert steps[1].forward_m == pytest.approx(0.2)  # 0.1 m to the cell + 0.1: the Tello's least
    x, y, yaw = 0.55, -0.95, math.radians(steps[0].ccw_deg)
    end = (x + steps[1].forward_m * math.cos(yaw), y + steps[1].forward_m * math.sin(yaw))
    assert not room.in_obstacle(*end)
    # Facing north-west: the same cell, turned the short way (right).
    steps = steps_out_of_obstacle(room, (0.55, -0.95, math.radians(135.0)))
    assert steps[0].ccw_deg == -45
    walled = GridView(np.full((10, 10), 100, dtype=np.int8), 0.1, (0.0, 0.0))
    assert steps_out_of_obstacle(walled, (0.5, 0.5, 0.0)) is None


@pytest.fixture
def room_with_door():
    # A 4 m x 4 m room at 0.1 m (x, y in [0, 4)), walls 0.2 m thick; a door in the north wall
    # at x 2.5-3.5 with free space beyond it (rays through the door), unknown beyond the rest,
    # and a box inside against the west wall at x 0.2-0.8, y 1.5-2.5.
    cells = np.full((60, 40), -1, dtype=np.int8)
    cells[:40, :] = 0
    cells[:2, :] = cells[38:40, :] = 100
    cells[:40, :2] = cells[:40, 38:] = 100
    cells[38:40, 25:35] = 0
    cells[40:55, 24:36] = 0
    cells[15:25, 2:8] = 100
    return GridView(cells, 0.1, (0.0, 0.0))


def test_free_space_beyond_a_door_not_beyond_a_wall_or_a_box(room_with_door):
    start = (2.0, 2.0)
    assert room_with_door.free_share_beyond((3.0, 3.85), start, 0.3, 1.2) > 0.9
    assert room_with_door.free_share_beyond((1.0, 3.85), start, 0.3, 1.2) == 0.0   # wall
    assert room_with_door.free_share_beyond((0.9, 2.0), start, 0.3, 1.2) == 0.0    # box
    assert room_with_door.free_share_beyond((2.0, 2.0), start, 0.3, 1.2) == 0.0    # no line


def test_exits_with_free_space_beyond_go_first_in_the_finders_order(room_with_door):
    ranked = [(0.9, 2.0), (1.0, 3.85), (3.0, 3.85), (3.1, 3.8)]
    ordered, leads_out = order_exits(ranked, room_with_door, (2.0, 2.0), 0.3, 1.2, 0.3)
    assert ordered == [(3.0, 3.85), (3.1, 3.8), (0.9, 2.0), (1.0, 3.85)] and leads_out
    assert order_exits(ranked[:2], room_with_door, (2.0, 2.0), 0.3, 1.2, 0.3) == \
        (ranked[:2], False)
    assert order_exits(ranked, None, (2.0, 2.0), 0.3, 1.2, 0.3) == (ranked, True)
    # Off the map: left out, whatever the finder's rank.
    assert order_exits([(158.7, -109.1)] + ranked[2:], room_with_door, (2.0, 2.0), 0.3, 1.2,
                       0.3) == (ranked[2:], True)
    assert order_exits([(158.7, -109.1)], room_with_door, (2.0, 2.0), 0.3, 1.2, 0.3) == \
        ([], False)
    assert order_exits(ranked, room_with_door, None, 0.3, 1.2, 0.3) == (ranked, True)


def test_walls_around_and_the_widest_opening(room):
    walls = room.walls_around(0.0, 0.0, max_m=5.0, n_rays=36)
    assert walls.all()  # the border all round
    assert widest_opening_deg(walls) == 0.0
    # A 1 m door in the east wall (x = 2.9 m, y from -0.2 to 0.8 m): the rays at 0 and 10 deg
    # leave the map through it.
    room.cells[8:18, 39] = 0
    walls = room.walls_around(0.0, 0.0, max_m=5.0, n_rays=36)
    assert np.flatnonzero(~walls).tolist() == [0, 1]
    assert widest_opening_deg(walls) == 20.0
    # Walls out of range are no walls: west and south at 0.9 m, north at 1.9 m.
    walls = room.walls_around(0.0, 0.0, max_m=1.5, n_rays=4)
    assert walls.tolist() == [False, False, True, True]
    # Nor are unknown cells or the map's edge.
    assert not room.walls_around(2.5, 1.5, max_m=0.3, n_rays=8).any()
    assert not room.walls_around(20.0, 20.0, max_m=1.0, n_rays=8).any()


def test_the_widest_opening_leaves_out_the_one_toward_a_given_bearing():
    walls = [True, False, False, True, False, True, True, True]  # 45 deg a bearing
    assert widest_opening_deg(walls) == 90.0
    assert widest_opening_deg(walls, skip_bearing_rad=math.radians(90)) == 45.0
    # Runs wrap round bearing 0.
    assert widest_opening_deg([False, True, True, False, False]) == 216.0
    assert widest_opening_deg([False] * 8) == 360.0
    assert widest_opening_deg([]) == 360.0


def test_free_distance_can_take_the_map_edge_for_unknown(room):
    assert room.free_distance(10.0, 10.0, 0.0, off_map_free=True, max_m=2.0) == pytest.approx(2.0)
    # Walls still end it.
    assert room.free_distance(0.0, 0.0, 0.0, off_map_free=True) == pytest.approx(2.9, abs=0.06)


def _building(side_walls_m, backdrop=False):
    """A 4 m x 4 m room (outline (0, 0)-(4, 4)) at 0.05 m with a door at (4, 2) in its east wall;
    its north and south walls carried on east for side_walls_m; a wall beyond the door (x = 6,
    y -0.5..4.5, crossing both side lines) with backdrop."""
    res = 0.05
    cells = np.full((240, 280), -1, dtype=np.int8)   # x, y in [-2, 12)

    def wall(x0, y0, x1, y1):
        for t in np.linspace(0.0, 1.0, 800):
            x, y = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
            cells[int((y + 2.0) / res), int((x + 2.0) / res)] = 100

    for w in [(0, 0, 4, 0), (4, 0, 4, 1.5), (4, 2.5, 4, 4), (4, 4, 0, 4), (0, 4, 0, 0)]:
        wall(*w)
    if side_walls_m > 0:
        wall(4, 0, 4 + side_walls_m, 0)
        wall(4, 4, 4 + side_walls_m, 4)
    if backdrop:
        wall(6, -0.5, 6, 4.5)
    return GridView(cells, res, (-2.0, -2.0))


OUTLINE = ((0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0))


def test_side_walls_beyond_a_door_show_the_building_going_on():
    # Through an outer wall the side walls turn at the corners; a wall standing beyond the exit
    # crosses their lines over a few cells only.
    assert _building(0.0).side_walls_beyond_m(OUTLINE, (4.0, 2.0)) == 0.0
    assert _building(0.0, backdrop=True).side_walls_beyond_m(OUTLINE, (4.0, 2.0)) < 0.5
    # Through a partition's door they go on: mapped 0.5 m (where the count starts) to 3 m.
    assert _building(3.0).side_walls_beyond_m(OUTLINE, (4.0, 2.0)) == pytest.approx(2.5, abs=0.1)
    # The outline's vertex order and the door's place along its wall do not matter.
    assert _building(3.0).side_walls_beyond_m(OUTLINE[::-1], (4.1, 3.0)) == \
        pytest.approx(2.5, abs=0.1)
    # No outline, or no door: nothing to go on from.
    assert _building(3.0).side_walls_beyond_m((), (4.0, 2.0)) is None
    assert _building(3.0).side_walls_beyond_m(OUTLINE, None) is None
