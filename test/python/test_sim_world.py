"""Simulator worlds: loading, validation, the random generator and camera visibility geometry."""
import math
import pathlib

import numpy as np
import pytest

from sparse_nav.sim import World, WorldError, list_worlds, load_world, random_world
from sparse_nav.sim.camera import Camera, frustum_mask, occluded_mask
from sparse_nav.sim.world import (doorway_strip, point_in_polygon, segment_distances,
                                  world_from_dict)

SHIPPED = ["large_hall", "l_room", "office_hallway", "one_room", "two_rooms"]


def _camera_pose(x, y, z, yaw):
    """T_world_cameraOptical of a level camera at (x, y, z) looking along yaw (rad)."""
    c, s = math.cos(yaw), math.sin(yaw)
    forward, left = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    t = np.eye(4)
    t[:3, 0] = -left                 # optical x: right
    t[:3, 1] = [0.0, 0.0, -1.0]      # optical y: down
    t[:3, 2] = forward               # optical z: forward
    t[:3, 3] = (x, y, z)
    return t


def _minimal(**overrides):
    data = {"ceiling_height_m": 2.5,
            "start": {"x": 2.0, "y": 2.0, "yaw_deg": 0},
            "walls": [{"name": "room", "points": [[0, 0], [4, 0], [4, 4], [0, 4]],
                       "closed": True, "doors": [{"segment": 1, "at_m": 2.0, "width_m": 1.0}]}],
            "exits": [{"x": 4.0, "y": 2.0, "width_m": 1.0}]}
    data.update(overrides)
    return data


def _two_rooms_with_door():
    """Rooms x in [0, 4] and [4, 8] split by a partition at x = 4 with a 1 m door at y = 2."""
    return world_from_dict({
        "ceiling_height_m": 2.5, "floor_texture_per_m2": 0, "ceiling_texture_per_m2": 0,
        "start": {"x": 1.0, "y": 2.0, "yaw_deg": 0},
        "walls": [{"points": [[0, 0], [8, 0], [8, 4], [0, 4]], "closed": True},
                  {"name": "partition", "points": [[4, 0], [4, 4]],
                   "doors": [{"segment": 0, "at_m": 2.0, "width_m": 1.0}]}],
        "exits": []}, source="test")


# -- shipped worlds ------------------------------------------------------------------------------

def test_list_worlds_has_the_shipped_worlds():
    assert set(SHIPPED) <= set(list_worlds())


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_world_loads_and_is_valid(name):
    world = load_world(name)
    assert isinstance(world, World)
    assert world.name == name
    assert world.exits, "every shipped world has an exit"
    segs = world.wall_segments()
    assert segs.shape[1] == 4 and len(segs) >= 4
    xmin, ymin, xmax, ymax = world.bounds()
    x, y, _ = world.start
    assert xmin < x < xmax and ymin < y < ymax
    assert segment_distances(np.array([x, y]), world.obstacle_segments()[0]).min() >= 0.3
    for ex in world.exits:
        gap = world.exit_gap(ex)
        assert segment_distances(np.array([ex["x"], ex["y"]]), np.array([gap]))[0] <= 0.3
        assert 0.7 <= ex["width_m"] <= 1.3
    pts = world.features(np.random.default_rng(0))
    assert pts.shape[1] == 3 and len(pts) > 1000
    assert pts[:, 2].min() >= 0.0 and pts[:, 2].max() <= world.ceiling_height_m + 1e-9


def test_shipped_world_specifics():
    one = load_world("one_room")
    x0, y0, x1, y1 = one.bounds()
    assert one.ceiling_height_m == 2.5 and len(one.exits) == 1
    # The 0.9 m gap in the recess end wall.
    assert np.allclose(sorted(one.exit_gap(one.exits[0])), sorted((5.95, 5.8, 5.05, 5.8)))
    hall = load_world("large_hall")
    hx0, hy0, hx1, hy1 = hall.bounds()
    assert hx1 - hx0 >= 40 and hy1 - hy0 >= 30 and hall.ceiling_height_m == 4.0
    assert len(hall.exits) == 2 and len(hall.boxes) >= 4
    hallway = load_world("office_hallway")
    assert min(w.texture_per_m2 for w in hallway.walls) < 5, "a low-texture wall segment"


def test_doorway_strip_is_as_wide_as_the_gap_and_measures_away_from_the_room():
    gap = (5.95, 5.8, 5.05, 5.8)   # one_room's exit, in a wall along x
    xy = np.array([[5.5, 6.5], [5.5, 5.0], [5.0, 6.0], [5.5, 7.0], [5.9, 6.2]])
    strip, beyond = doorway_strip(xy, gap, inside_xy=(3.0, 2.5), reach_m=1.0)
    assert strip.tolist() == [True, True, False, False, True]
    assert np.allclose(beyond, [0.7, -0.8, 0.2, 1.2, 0.4])
    _, from_outside = doorway_strip(xy, gap, inside_xy=(5.5, 9.0))
    assert np.allclose(from_outside, -beyond)


def test_features_are_deterministic_for_a_given_rng():
    world = load_world("one_room")
    a = world.features(np.random.default_rng(7))
    b = world.features(np.random.default_rng(7))
    c = world.features(np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)


def test_features_lie_on_surfaces():
    world = load_world("one_room")
    pts, normals = world.features_with_normals(np.random.default_rng(1))
    clutter = ~np.any(normals != 0, axis=1)             # small objects: no surface normal
    surface, normals = pts[~clutter], normals[~clutter]
    on_floor_or_ceiling = (np.abs(surface[:, 2]) < 1e-9) | (np.abs(surface[:, 2] - 2.5) < 1e-9)
    segs = world.obstacle_segments()[0]
    d = np.array([segment_distances(p[:2], segs).min() for p in surface[~on_floor_or_ceiling]])
    box_tops = np.isin(surface[~on_floor_or_ceiling, 2], [b.height_m for b in world.boxes])
    assert np.all((d < 1e-6) | box_tops)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    # Clutter stands inside the room, off the walls, in the furniture height band.
    assert 0 < np.count_nonzero(clutter) < 0.1 * len(pts)
    outline = world.outlines[0]
    assert all(point_in_polygon(p[:2], outline) for p in pts[clutter])
    assert min(segment_distances(p[:2], segs).min() for p in pts[clutter]) > 0.2


def test_worlds_dir_can_be_overridden(tmp_path, monkeypatch):
    src = pathlib.Path(__file__).resolve().parents[2] / "worlds" / "one_room.yaml"
    (tmp_path / "my_room.yaml").write_text(src.read_text())
    monkeypatch.setenv("SPARSE_NAV_WORLDS_DIR", str(tmp_path))
    assert list_worlds() == ["my_room"]
    assert load_world("my_room").name == "one_room"
    with pytest.raises(WorldError, match="known worlds: my_room"):
        load_world("one_room")


def test_load_by_path_and_random(tmp_path):
    path = pathlib.Path(__file__).resolve().parents[2] / "worlds" / "l_room.yaml"
    assert load_world(str(path)).name == "l_room"
    assert load_world("random:12").name == "random:12"


# -- bad input ----------------------------------------------------------------------------------

def _write(tmp_path, text, name="bad.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_unknown_world_lists_known_names():
    with pytest.raises(WorldError) as err:
        load_world("no_such_world")
    msg = str(err.value)
    assert "no_such_world" in msg and "one_room" in msg and "large_hall" in msg


def test_malformed_yaml_names_file_and_problem(tmp_path):
    path = _write(tmp_path, "walls: [[0, 0], [1, 1]\nceiling_height_m: 2\n")
    with pytest.raises(WorldError, match="YAML syntax error") as err:
        load_world(path)
    assert "bad.yaml" in str(err.value)


def test_missing_file_and_bad_random_seed(tmp_path):
    with pytest.raises(WorldError, match="not found"):
        load_world(str(tmp_path / "absent.yaml"))
    with pytest.raises(WorldError, match="integer"):
        load_world("random:abc")


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: d.pop("walls"), "missing key 'walls'"),
    (lambda d: d.pop("ceiling_height_m"), "missing key 'ceiling_height_m'"),
    (lambda d: d["walls"][0].update(points=[[0, 0]]), "at least 3 points"),
    (lambda d: d["walls"].append({"points": [[1, 1]]}), "at least 2 points"),
    (lambda d: d["walls"][0].update(points=[[0, 0], [4, "a"], [4, 4]]), "must be a number"),
    (lambda d: d["walls"][0]["doors"][0].update(width_m=5.0), "wider than its wall"),
    (lambda d: d["walls"][0]["doors"][0].update(at_m=3.8), "does not fit"),
    (lambda d: d["exits"][0].update(y=3.5), "not at a door gap"),
    (lambda d: d["start"].update(x=9.0), "not inside"),
    (lambda d: d["start"].update(x=0.1), "from a wall"),
    (lambda d: d.update(ceiling_height_m=-1), "ceiling_height_m: must be > 0"),
    (lambda d: d.update(colour="red"), "unknown key"),
    (lambda d: d.update(boxes=[{"center": [2, 2], "size": [1, 1], "height_m": 1}]),
     "inside box 0"),
])
def test_invalid_world_raises_world_error(mutate, expected):
    data = _minimal()
    mutate(data)
    with pytest.raises(WorldError, match=expected) as err:
        world_from_dict(data, source="unit.yaml")
    assert "unit.yaml" in str(err.value)


def test_yaml_file_errors_name_the_file(tmp_path):
    path = _write(tmp_path, "ceiling_height_m: 2.5\nstart: {x: 1, y: 1}\nexits: []\n",
                  name="nowalls.yaml")
    with pytest.raises(WorldError, match="missing key 'walls'") as err:
        load_world(path)
    assert "nowalls.yaml" in str(err.value)


def test_minimal_world_is_valid():
    world = world_from_dict(_minimal(), source="unit")
    assert len(world.door_gaps) == 1
    assert len(world.wall_segments()) == 5     # the door splits one side in two


# -- generator ----------------------------------------------------------------------------------

def _signature(world):
    return (world.wall_segments().round(9).tobytes(), tuple(sorted(
        (round(e["x"], 9), round(e["y"], 9)) for e in world.exits)), world.start,
        len(world.boxes))


def test_generator_is_deterministic():
    assert _signature(random_world(5)) == _signature(random_world(5))
    assert _signature(random_world(5)) != _signature(random_world(6))


def test_generator_makes_valid_varied_worlds():
    kinds, recesses, blanks, boxes = set(), 0, 0, 0
    for seed in range(50):
        world = random_world(seed)          # validated by the same checks as YAML worlds
        assert 1 <= len(world.exits) <= 2
        for ex in world.exits:
            assert 0.8 <= ex["width_m"] <= 1.2
        outline = [w for w in world.walls if w.faces == 1]
        pts = np.array([[w.x1, w.y1] for w in outline] + [[w.x2, w.y2] for w in outline])
        extent = np.ptp(pts @ _principal_axes(outline), axis=0)
        assert np.all(extent >= 4.0 - 1e-6) and np.all(extent <= 2 * 12.0 + 2.0)
        start = np.array(world.start[:2])
        assert segment_distances(start, world.obstacle_segments()[0]).min() >= 0.9
        kinds.add(len(outline))
        recesses += sum(1 for ex in world.exits if _in_recess(world, ex))
        blanks += any(w.texture_per_m2 < 5 for w in world.walls)
        boxes += len(world.boxes) > 0
    assert recesses >= 5 and blanks >= 10 and boxes >= 10
    assert len(kinds) >= 3, "several shapes"


def _principal_axes(outline):
    """Rotation (2, 2) aligning a generated outline with its axes (the longest wall)."""
    longest = max(outline, key=lambda w: w.length_m)
    a = math.atan2(longest.y2 - longest.y1, longest.x2 - longest.x1)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _in_recess(world, ex):
    """An exit in a recess has outline walls on both sides of its door within ~1.4 m."""
    p = np.array([ex["x"], ex["y"]])
    segs = np.array([[w.x1, w.y1, w.x2, w.y2] for w in world.walls if w.faces == 1])
    return np.count_nonzero(segment_distances(p, segs) < 0.8) >= 3


# -- camera geometry ----------------------------------------------------------------------------

def test_frustum_limits():
    pose = _camera_pose(0.0, 0.0, 1.0, 0.0)       # looking along +x
    half_h = math.radians(41.0)
    pts = np.array([
        [3.0, 0.0, 1.0],                                          # straight ahead
        [3.0, 3.0 * math.tan(half_h - 0.02), 1.0],                # just inside hfov
        [3.0, 3.0 * math.tan(half_h + 0.02), 1.0],                # just outside hfov
        [3.0, 0.0, 1.0 + 3.0 * math.tan(math.radians(26.0) + 0.02)],   # above vfov
        [3.0, 0.0, 1.0 + 3.0 * math.tan(math.radians(26.0) - 0.02)],   # inside vfov
        [-3.0, 0.0, 1.0],                                         # behind
        [0.2, 0.0, 1.0],                                          # closer than min range
        [8.5, 0.0, 1.0],                                          # beyond max range
        [7.9, 0.0, 1.0],                                          # within max range
    ])
    mask = frustum_mask(pts, pose, 82.0, 52.0, 0.3, 8.0)
    assert mask.tolist() == [True, True, False, False, True, False, False, False, True]


def test_feature_behind_wall_is_hidden():
    wall = np.array([[2.0, -5.0, 2.0, 5.0]])
    cam = np.array([0.0, 0.0, 1.0])
    pts = np.array([[3.0, 0.0, 1.0], [1.5, 0.0, 1.0], [2.0, 0.5, 1.0]])
    hidden = occluded_mask(cam, pts, wall, np.array([np.inf]))
    assert hidden.tolist() == [True, False, False]   # a point on the wall itself is seen


def test_box_hides_only_below_its_top():
    box = np.array([[2.0, -1.0, 2.0, 1.0]])          # front face of a box 1 m high
    pts = np.array([[4.0, 0.0, 0.5]])
    assert occluded_mask(np.array([0.0, 0.0, 0.5]), pts, box, np.array([1.0]))[0]
    assert not occluded_mask(np.array([0.0, 0.0, 2.5]), pts, box, np.array([1.0]))[0]


def test_next_room_visible_through_door_not_through_wall():
    world = _two_rooms_with_door()
    segs, heights = world.obstacle_segments()
    through_door = [6.0, 2.0, 1.2]       # behind the door gap (y in [1.5, 2.5])
    behind_wall = [6.0, 0.8, 1.2]        # same room, but the ray crosses the partition
    pts = np.array([through_door, behind_wall])
    normals = np.array([[-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    cam = Camera(pts, normals, segs, np.full(len(segs), np.inf), 82.0, 52.0, 0.3, 8.0, 1.0,
                 np.random.default_rng(0))
    visible = cam.geometric_visible(_camera_pose(1.0, 2.0, 1.2, 0.0))
    assert visible.tolist() == [0]
    # From right in front of the door, the ray to the same point passes through the gap.
    assert cam.geometric_visible(_camera_pose(3.5, 2.0, 1.2, 0.0)).tolist() == [0, 1]


def test_back_faces_are_not_seen():
    world = load_world("one_room")
    pts, normals = world.features_with_normals(np.random.default_rng(0))
    segs, heights = world.obstacle_segments()
    cam = Camera(pts, normals, segs, heights, 82.0, 52.0, 0.3, 8.0, 1.0,
                 np.random.default_rng(0))
    idx = cam.geometric_visible(_camera_pose(3.0, 2.5, 1.0, 0.0))
    to_cam = np.array([3.0, 2.5, 1.0]) - pts[idx]
    assert len(idx) > 200
    facing = np.einsum("ij,ij->i", to_cam, normals[idx])
    clutter = ~np.any(normals[idx] != 0, axis=1)       # small objects face every way
    assert np.all((facing > 0) | clutter)
    # Nothing outside the room except through the exit: x <= 6 everywhere in view.
    assert pts[idx, 0].max() <= 6.0 + 1e-9


def test_polygon_helpers():
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], dtype=float)
    assert point_in_polygon(np.array([1.0, 1.0]), square)
    assert not point_in_polygon(np.array([3.0, 1.0]), square)
    d = segment_distances(np.array([1.0, 1.0]), np.array([[0.0, 0.0, 2.0, 0.0]]))
    assert d[0] == pytest.approx(1.0)
