"""The navigator core (sparse_nav.navigation.navigator) on synthetic maps (no master)."""
import math

import numpy as np
import pytest

from sparse_nav import _planning as planning
from sparse_nav.navigation.maps import GridGeometry
from sparse_nav.navigation.navigator import (FOLLOWING, GOAL_IN_OBSTACLE, GOAL_OFF_MAP, IDLE, LOST,
                                             NO_PATH, PLANNING, REACHED, Navigator,
                                             NavigatorConfig, NavigatorInputError)

RES = 0.1


def free_map(width_m=10.0, height_m=6.0, origin=(0.0, 0.0)):
    w, h = int(round(width_m / RES)), int(round(height_m / RES))
    return GridGeometry(w, h, RES, (origin[0], origin[1], 0.0)), np.zeros((h, w), dtype=np.int8)


def wall(data, x_m, y0_m, y1_m, value=100):
    """A vertical wall one cell thick at x_m from y0_m to y1_m (map frame, origin 0)."""
    data[int(y0_m / RES):int(y1_m / RES), int(x_m / RES)] = value


def navigator(**kwargs):
    cfg = dict(robot_radius_m=0.15, viewing_range_m=3.0)
    cfg.update(kwargs)
    return Navigator(NavigatorConfig(**cfg))


def path_is_clear(nav, path):
    """Each segment of the published path has line of sight on the navigator's planning grid."""
    cells = [nav.geometry.world_to_cell(x, y) for x, y in path]
    return all(planning.line_of_sight(nav.grid, a, b) for a, b in zip(cells, cells[1:]))


def drive(nav, status, steps=400, step_m=0.1):
    """Moves the robot along the published path until it stops changing; returns the last status."""
    for _ in range(steps):
        if not status.path or status.state not in (FOLLOWING, GOAL_OFF_MAP, GOAL_IN_OBSTACLE):
            return status
        x, y, _ = nav.pose
        tx, ty = status.path[1]
        d = math.hypot(tx - x, ty - y)
        f = min(1.0, step_m / d) if d > 0 else 1.0
        nav.set_pose(x + f * (tx - x), y + f * (ty - y), 0.0)
        status = nav.update()
    return status


def test_clear_path_around_a_wall_then_reached():
    geometry, data = free_map()
    wall(data, 5.0, 0.0, 4.5)
    nav = navigator()
    assert nav.update().state == IDLE
    nav.set_goal(8.0, 1.0)
    assert nav.update().state == PLANNING  # no map yet
    nav.set_map(geometry, data)
    assert nav.update().state == PLANNING  # no pose yet
    nav.set_pose(1.0, 1.0, 0.0)
    status = nav.update()
    assert status.state == FOLLOWING, status.reason
    assert status.path[0] == pytest.approx((1.0, 1.0))
    assert math.dist(status.path[-1], (8.0, 1.0)) < RES
    assert path_is_clear(nav, status.path)
    # The wall ends at y = 4.5: the path climbs over it.
    assert max(y for _, y in status.path) > 4.5
    assert status.path_length_m > math.dist((1, 1), (5, 4.6)) + math.dist((5, 4.6), (8, 1))
    status = drive(nav, status)
    assert status.state == REACHED
    assert nav.update().state == IDLE


def test_goal_off_map_leads_to_the_nearest_known_cell_then_follows_the_grown_map():
    geometry, data = free_map(5.0, 4.0)
    data[:, 45:] = -1  # the map's last half metre is unknown
    nav = navigator()
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 2.0, 0.0)
    nav.set_goal(9.0, 2.0)
    status = nav.update()
    assert status.state == GOAL_OFF_MAP, status.reason
    assert "outside the known map" in status.reason
    assert status.target == pytest.approx((4.45, 2.05))
    assert status.path[-1] == pytest.approx(status.target)
    status = drive(nav, status)
    assert status.state == GOAL_OFF_MAP and status.path == []
    assert "waiting for the map" in status.reason
    bigger, grown = free_map(10.0, 4.0)
    nav.set_map(bigger, grown)
    status = nav.update()
    assert status.state == FOLLOWING
    assert math.dist(status.path[-1], (9.0, 2.0)) < RES


def test_grown_map_cells_beyond_the_viewing_range_start_unknown():
    geometry, data = free_map(5.0, 4.0)
    nav = navigator(viewing_range_m=3.0)
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 2.0, 0.0)
    nav.set_goal(9.0, 2.0)
    assert nav.update().state == GOAL_OFF_MAP
    bigger, grown = free_map(10.0, 4.0)
    grown[10:30, 70:75] = 100  # a block at x = 7.0-7.5 m, y = 1-3 m, 6 m from the robot
    nav.set_map(bigger, grown)
    status = nav.update()
    assert status.state == FOLLOWING
    assert (nav.applied[:, 50:] == -1).all() and nav.pending[:, 50:].all()
    assert all(abs(y - 2.0) < 0.1 for _, y in status.path)  # straight through the unknown
    nav.set_pose(5.0, 2.0, 0.0)
    status = nav.update()
    assert status.state == FOLLOWING and (nav.applied[10:30, 70:75] == 100).all()
    assert max(abs(y - 2.0) for _, y in status.path) > 1.0  # around the block now
    assert path_is_clear(nav, status.path)


def test_viewing_range_defers_far_changes_until_the_robot_is_close():
    geometry, data = free_map()
    nav = navigator(viewing_range_m=2.0)
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 3.0, 0.0)
    nav.set_goal(9.0, 3.0)
    first = nav.update()
    assert first.state == FOLLOWING
    walled = data.copy()
    walled[:, 70] = 100  # a wall across the whole map at x = 7 m: the goal is cut off
    nav.update_map(0, 0, geometry.width, geometry.height, walled)
    status = nav.update()
    assert status.state == FOLLOWING and status.path == first.path
    assert nav.pending.sum() == geometry.height
    for x in np.arange(1.5, 4.6, 0.5):
        nav.set_pose(x, 3.0, 0.0)
        status = nav.update()
        assert status.state == FOLLOWING and status.path[-1] == first.path[-1], x
        assert nav.pending.sum() == geometry.height
    # Closer than 2 m, the wall enters the planner piece by piece until no way round is left.
    status = drive(nav, status)
    assert status.state == NO_PATH and status.path == []
    assert nav.pose[0] > 5.0
    assert nav.pending.sum() < geometry.height


def test_goal_in_obstacle_heads_for_the_nearest_free_cell():
    geometry, data = free_map()
    data[20:40, 60:80] = 100  # a 2 m block from x = 6 to 8, y = 2 to 4
    nav = navigator(goal_search_radius_m=0.6)
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 3.0, 0.0)
    nav.set_goal(6.2, 3.05)
    status = nav.update()
    assert status.state == GOAL_IN_OBSTACLE, status.reason
    # Nearest enterable cell: left of the block beyond the 0.15 m inflation.
    assert status.target[0] == pytest.approx(5.85)
    assert status.target[1] == pytest.approx(3.05)
    assert status.path[-1] == pytest.approx(status.target)
    nav.set_goal(7.0, 3.0)  # 1 m deep: beyond goal_search_radius_m
    status = nav.update()
    assert status.state == NO_PATH and status.path == []
    assert "goal_search_radius_m" in status.reason


def test_slam_loss_keeps_the_goal_relative_and_reanchors_it():
    geometry, data = free_map(20.0, 20.0, origin=(-5.0, -5.0))
    nav = navigator()
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 1.0, 0.0)
    nav.set_goal(4.0, 2.0)
    assert nav.update().state == FOLLOWING
    nav.on_slam_lost()
    nav.set_pose(3.0, 3.0, 0.0)  # ignored for the anchor: taken after the loss
    status = nav.update()
    assert status.state == LOST and status.path == []
    nav.on_slam_new_map()
    assert nav.geometry is None  # the old map's cells do not match the new SLAM map
    assert nav.update().state == LOST  # waiting for the new map and pose
    nav.set_pose(2.0, 0.0, math.pi / 2)
    assert nav.update().state == LOST  # still no new map
    nav.set_map(*free_map(20.0, 20.0, origin=(-6.0, -6.0)))
    status = nav.update()
    assert status.state == FOLLOWING, status.reason
    # 3 m ahead and 1 m left of the robot at the loss, now facing +y: (2 - 1, 0 + 3).
    assert status.goal == pytest.approx((1.0, 3.0))
    assert math.dist(status.path[-1], (1.0, 3.0)) < RES


def test_relocalised_in_the_same_map_keeps_map_coordinates():
    geometry, data = free_map()
    nav = navigator()
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 1.0, 0.0)
    nav.set_goal(4.0, 2.0)
    nav.update()
    nav.on_slam_lost()
    nav.set_pose(1.5, 1.0, 1.0)
    nav.on_slam_ok()
    status = nav.update()
    assert status.state == FOLLOWING and status.goal == (4.0, 2.0)


def test_replans_only_when_the_path_is_affected():
    geometry, data = free_map()
    data[10:50, 50] = 100  # wall x = 5, y = 1..5: the path passes above or below
    nav = navigator(replan_improvement_m=0.5, viewing_range_m=10.0)
    nav.set_map(geometry, data)
    nav.set_pose(2.0, 3.0, 0.0)
    nav.set_goal(8.0, 3.0)
    first = nav.update()
    assert first.state == FOLLOWING
    replans = nav.n_replans
    # A change away from the path is applied (in range) but keeps the path.
    far = data.copy()
    far[55, 20] = 100
    nav.update_map(0, 0, geometry.width, geometry.height, far)
    assert nav.update().path == first.path and nav.n_replans == replans
    # Opening the wall's middle saves far more than 0.5 m: the path switches to the gap.
    opened = far.copy()
    opened[27:34, 50] = 0
    nav.update_map(0, 0, geometry.width, geometry.height, opened)
    status = nav.update()
    assert nav.n_replans == replans + 1
    assert max(abs(y - 3.0) for _, y in status.path) < 0.5
    # Blocking a cell on the followed path forces a new path.
    on_path = opened.copy()
    on_path[27:34, 50] = 100
    on_path[30, 45] = 100
    nav.update_map(0, 0, geometry.width, geometry.height, on_path)
    status = nav.update()
    assert nav.n_replans == replans + 2 and status.state == FOLLOWING
    assert path_is_clear(nav, status.path)


def test_small_shortcut_is_ignored_by_hysteresis():
    geometry, data = free_map()
    data[0:50, 50] = 100  # wall x = 5 from y = 0 to 5: the path goes over the top
    nav = navigator(replan_improvement_m=1.0, viewing_range_m=10.0)
    nav.set_map(geometry, data)
    nav.set_pose(4.0, 1.0, 0.0)
    nav.set_goal(6.0, 1.0)
    first = nav.update()
    replans = nav.n_replans
    before = nav.dstar.cost()
    shorter = data.copy()
    shorter[49, 50] = 0  # the detour shrinks by a few cells only (0.2 m)
    nav.update_map(0, 0, geometry.width, geometry.height, shorter)
    status = nav.update()
    assert nav.pending.sum() == 0 and 1.0 < before - nav.dstar.cost() < 1.0 / RES
    assert status.path == first.path and nav.n_replans == replans


def test_deviation_replans_from_the_robot():
    geometry, data = free_map()
    nav = navigator(max_deviation_m=0.5)
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 1.0, 0.0)
    nav.set_goal(9.0, 1.0)
    first = nav.update()
    assert len(first.path) == 2
    replans = nav.n_replans
    nav.set_pose(3.0, 1.4, 0.0)  # within max_deviation_m: the path stays
    assert nav.update().path[1:] == first.path[1:] and nav.n_replans == replans
    nav.set_pose(3.0, 4.0, 0.0)
    status = nav.update()
    assert nav.n_replans == replans + 1
    assert status.path == [(3.0, 4.0), pytest.approx((9.05, 1.05))]


def test_bad_inputs_are_refused_and_the_last_map_kept():
    geometry, data = free_map()
    data[20:40, 20:40] = 100
    nav = navigator()
    for bad in ((math.nan, 1.0), (1.0, math.inf)):
        with pytest.raises(NavigatorInputError, match="not finite"):
            nav.set_goal(*bad)
    with pytest.raises(NavigatorInputError, match="no map"):
        nav.update_map(0, 0, 1, 1, [0])
    with pytest.raises(NavigatorInputError, match="empty grid"):
        nav.set_map(GridGeometry(0, 0, RES, (0.0, 0.0, 0.0)), [])
    nav.set_map(geometry, data)
    with pytest.raises(NavigatorInputError, match="values for"):
        nav.set_map(geometry, data.ravel()[:-1])
    with pytest.raises(NavigatorInputError, match="resolution"):
        nav.set_map(GridGeometry(3, 3, math.nan, (0.0, 0.0, 0.0)), np.zeros(9))
    with pytest.raises(NavigatorInputError, match="outside"):
        nav.update_map(95, 0, 10, 1, np.zeros(10))
    with pytest.raises(NavigatorInputError, match="exceeds"):
        Navigator(NavigatorConfig(max_cells=100)).set_map(geometry, data)
    assert nav.geometry == geometry and (nav.latest == data).all()
    nav.set_pose(3.0, 3.0, 0.0)  # inside the block
    nav.set_goal(8.0, 5.0)
    status = nav.update()
    assert status.state == NO_PATH and "inside an obstacle" in status.reason and status.path == []
    nav.set_pose(12.0, 3.0, 0.0)
    status = nav.update()
    assert status.state == NO_PATH and "outside the map" in status.reason
    nav.set_pose(1.0, 1.0, 0.0)
    assert nav.update().state == FOLLOWING
    with pytest.raises(ValueError):
        NavigatorConfig(unknown_policy="maybe").validate()
    with pytest.raises(ValueError):
        NavigatorConfig(viewing_range_m=0.0).validate()


def test_start_on_an_inflated_cell_plans_from_the_nearest_free_cell():
    geometry, data = free_map()
    data[:, 30] = 100
    data[55:, 30] = 0
    nav = navigator(robot_radius_m=0.3)
    nav.set_map(geometry, data)
    nav.set_pose(2.85, 1.0, 0.0)  # 0.2 m from the wall at x = 3.0-3.1
    nav.set_goal(1.0, 1.0)
    status = nav.update()
    assert status.state == FOLLOWING
    assert status.path[0] == (2.85, 1.0)
    assert math.dist(status.path[-1], (1.05, 1.05)) < 1e-9


def test_make_plan_uses_the_newest_map():
    geometry, data = free_map()
    nav = navigator(viewing_range_m=1.0)
    nav.set_map(geometry, data)
    nav.set_pose(1.0, 3.0, 0.0)
    walled = data.copy()
    walled[:, 70] = 100
    walled[5:10, 70] = 0  # gap at y = 0.5..1.0
    nav.update_map(0, 0, geometry.width, geometry.height, walled)
    path, reason = nav.make_plan((1.0, 3.0), (9.0, 3.0))
    assert reason == "" and min(y for _, y in path) < 1.0
    path, reason = nav.make_plan((1.0, 3.0), (7.05, 3.05), tolerance_m=0.5)
    assert reason == "" and path[-1][0] < 7.0
    path, reason = nav.make_plan((1.0, 3.0), (7.05, 3.05))
    assert path == [] and "tolerance" in reason
    assert nav.make_plan((math.nan, 0.0), (1.0, 1.0))[0] == []


def through_a_door(door_m, robot_radius_m, squeeze_radius_m):
    """A navigator at (2, 1) asked to (8, 1) beyond a wall across the map at x = 5 m whose one
    door, door_m wide, is centred at y = 3 m."""
    geometry, data = free_map()
    wall(data, 5.0, 0.0, 3.0 - door_m / 2)
    wall(data, 5.0, 3.0 + door_m / 2, 6.0)
    nav = navigator(robot_radius_m=robot_radius_m, squeeze_radius_m=squeeze_radius_m)
    nav.set_map(geometry, data)
    nav.set_pose(2.0, 1.0, 0.0)
    nav.set_goal(8.0, 1.0)
    return nav


def test_a_door_narrower_than_the_robot_radius_allows_is_squeezed_through_for_that_goal_only():
    nav = through_a_door(0.3, robot_radius_m=0.2, squeeze_radius_m=0.15)
    status = nav.update()
    assert status.state == FOLLOWING and "squeezing through" in status.reason, status.reason
    assert path_is_clear(nav, status.path)
    crossing = [ya + (yb - ya) * (5.0 - xa) / (xb - xa)
                for (xa, ya), (xb, yb) in zip(status.path, status.path[1:])
                if min(xa, xb) <= 5.0 < max(xa, xb)]
    assert crossing and abs(crossing[0] - 3.0) < 0.25, crossing  # through the door
    assert drive(nav, status).state == REACHED
    # The next goal is planned with the full radius again: back through the door, no way.
    nav.set_goal(2.0, 1.0)
    assert not nav.squeezing
    status = nav.update()
    assert status.state == FOLLOWING and nav.squeezing  # and it squeezes again, saying so
    nav.cancel()
    assert not nav.squeezing


def test_no_squeeze_below_the_robot_radius_means_no_path():
    assert through_a_door(0.3, robot_radius_m=0.2, squeeze_radius_m=0.2).update().state == NO_PATH
    # A door too narrow even for the squeeze radius stays closed.
    nav = through_a_door(0.1, robot_radius_m=0.2, squeeze_radius_m=0.15)
    status = nav.update()
    assert status.state == NO_PATH and nav.squeezing, status.reason
