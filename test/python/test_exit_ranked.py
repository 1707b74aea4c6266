"""The ranked exit finder: door candidates, their features, and the learned ranker's model file."""
import json
import math

import numpy as np
import pytest

from sparse_nav.exit_finder import ExitFinderConfig, ExitFinderError, find_exit, finder
from sparse_nav.exit_finder import doors as doorslib
from sparse_nav.exit_finder.ranker import (PACKAGED_MODEL, DoorRanker, RankerModelError,
                                           load_ranker)
from sparse_nav.exit_finder.synthetic import Door, room_cloud, to_orbslam

RECT = [(-3.0, -2.0), (3.0, -2.0), (3.0, 2.0), (-3.0, 2.0)]
VIEW = (0.3, 0.2)


def near(a, b, tol):
    return float(np.hypot(*(np.asarray(a[:2]) - np.asarray(b[:2])))) <= tol


def scene_of(xy, view, cfg=None):
    cfg = cfg or ExitFinderConfig()
    prep = finder.prepare(xy, None, cfg)
    return prep, doorslib.Scene(prep.q, prep.frame.to_norm(np.asarray(view, float)), cfg)


def test_a_door_in_the_middle_of_a_wall_is_the_best_exit():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=VIEW, clutter=150,
                           outliers=30, noise=0.03)
    result = find_exit(to_orbslam(xy), method="ranked")
    assert result.status == "ok" and result.method == "ranked"
    assert near(result.exits[0], doors[0], 0.3)
    scores = [s for _, _, s in result.exits]
    assert scores == sorted(scores, reverse=True) and all(0.0 <= s <= 1.0 for s in scores)
    assert len(result.exits) <= ExitFinderConfig().gap_max_exits
    assert len(result.details["line_points"]) > 0
    corners = np.array(result.room_corners)
    for c in RECT:
        assert np.min(np.hypot(*(corners - c).T)) < 0.5


def test_reported_exits_are_distinct_doors():
    xy, _ = room_cloud(RECT, [Door(side=0, at_m=2.0), Door(side=1, at_m=2.0)], viewpoint=VIEW,
                       clutter=100, noise=0.05, seed=3)
    cfg = ExitFinderConfig()
    result = find_exit(xy, method="ranked", up_axis=None, viewpoint=VIEW)
    prep = finder.prepare(xy, None, cfg)
    pts = prep.frame.to_norm(np.array([e[:2] for e in result.exits]))
    for i in range(len(pts)):
        for j in range(i):
            assert np.hypot(*(pts[i] - pts[j])) > cfg.rank_merge_radius


def test_both_doors_of_an_l_shaped_room_are_ranked_first():
    room = [(0.0, 0.0), (6.0, 0.0), (6.0, 3.0), (3.0, 3.0), (3.0, 6.0), (0.0, 6.0)]
    xy, doors = room_cloud(room, [Door(side=1, at_m=1.5), Door(side=4, at_m=2.0)],
                           viewpoint=(1.5, 1.5), clutter=100, seed=1)
    result = find_exit(xy, method="ranked", up_axis=None, viewpoint=(1.5, 1.5))
    for door in doors:
        assert any(near(e, door, 0.3) for e in result.exits[:2])


def test_a_closed_room_has_no_exit():
    for seed in range(3):
        xy, _ = room_cloud(RECT, [], viewpoint=VIEW, clutter=150, seed=seed)
        result = find_exit(xy, method="ranked", up_axis=None, viewpoint=VIEW)
        assert result.status == "no_exit" and not result.exits and result.reason


def test_min_probability_cuts_the_list_down_to_no_exit():
    xy, _ = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=VIEW, seed=4)
    result = find_exit(xy, method="ranked", up_axis=None, viewpoint=VIEW,
                       config=ExitFinderConfig(rank_min_probability=1.0))
    assert result.status == "no_exit" and result.exits == [] and result.reason


def test_external_door_gaps_raise_the_matching_candidate():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=VIEW, seed=4)
    base = find_exit(xy, method="ranked", up_axis=None, viewpoint=VIEW)
    d = doors[0]
    fused = find_exit(xy, method="ranked", up_axis=None, viewpoint=VIEW,
                      door_gaps=[(d[0] + 0.05, d[1], 1.0)])
    assert near(fused.exits[0], d, 0.3) and fused.exits[0][2] > base.exits[0][2]


def test_features_are_finite_named_and_independent_of_scale_heading_and_position():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=VIEW, noise=0.04,
                           clutter=80, seed=8)
    _, scene = scene_of(xy, VIEW)
    cands = doorslib.candidates(scene, np.random.default_rng(0))
    x = doorslib.feature_matrix(scene, cands)
    assert x.shape == (len(cands), len(doorslib.FEATURE_NAMES)) and np.isfinite(x).all()
    assert {d.source for d in cands} <= set(doorslib.SOURCES)
    # The same door, with the whole scene turned, scaled and moved: the same description. The
    # cloud is normalised (centred, divided by its radius), so compare in metres via the frame.
    angle, scale, shift = 0.7, 3.0, np.array([5.0, -2.0])
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])

    def move(p):
        return scale * np.asarray(p, float) @ rot.T + shift

    prep, scene = scene_of(xy, VIEW)
    prep2, scene2 = scene_of(move(xy), move(VIEW))
    door = cands[0]
    metres = [prep.frame.from_norm(p[None])[0] for p in (door.a, door.b, door.centre)]
    moved = doorslib.Candidate(*[prep2.frame.to_norm(move(p)[None])[0] for p in metres],
                          source=door.source)
    f1, f2 = doorslib.features(scene, door), doorslib.features(scene2, moved)
    np.testing.assert_allclose(f1, f2, atol=0.05)


def test_an_inner_door_has_the_map_beyond_it_and_an_outer_door_has_not():
    # Two rooms side by side in [-3, 3] x [-2, 2], a partition at x = 1 with a door at y = 0,
    # an exit in the bottom wall at x = -1; seen from (-1, 0.5) in the first room.
    rng = np.random.default_rng(2)

    def wall(a, b, n, gap=None):
        t = rng.uniform(0.0, 1.0, n)
        p = np.asarray(a, float) + t[:, None] * (np.asarray(b, float) - a)
        return p if gap is None else p[np.hypot(*(p - gap).T) > 0.5]

    xy = np.vstack([wall((-3, -2), (3, -2), 720, gap=(-1.0, -2.0)), wall((3, -2), (3, 2), 480),
                    wall((3, 2), (-3, 2), 720), wall((-3, 2), (-3, -2), 480),
                    wall((1, -2), (1, 2), 480, gap=(1.0, 0.0))])
    view = (-1.0, 0.5)
    prep, scene = scene_of(xy, view)

    def candidate(a, b):
        a, b = (prep.frame.to_norm(np.array([p], float))[0] for p in (a, b))
        return doorslib.Candidate(a=a, b=b, centre=0.5 * (a + b), source="wall_gap")

    names = list(doorslib.FEATURE_NAMES)
    exit_f = dict(zip(names, doorslib.features(scene, candidate((-1.5, -2.0), (-0.5, -2.0)))))
    inner_f = dict(zip(names, doorslib.features(scene, candidate((1.0, -0.5), (1.0, 0.5)))))
    # A third of the walls' points lie past the partition; none past the outer wall.
    assert exit_f["beyond_share"] < 0.02 and 0.2 < inner_f["beyond_share"] < 0.5
    assert exit_f["beyond_surface_share"] < 0.02 and inner_f["beyond_surface_share"] > 0.1
    assert exit_f["beyond_near_share"] < 0.02 and inner_f["beyond_near_share"] > 0.2
    # The second room's far wall is 2 m past the partition, the door 2.06 m from the viewpoint.
    assert exit_f["beyond_extent"] == 0.0 and 0.9 < inner_f["beyond_extent"] < 1.0
    # The exit lies on the cloud's convex hull, the inner door well inside it.
    assert exit_f["hull_depth"] < 0.05 and inner_f["hull_depth"] > 0.3


def test_wall_gaps_find_a_door_seen_almost_edge_on():
    # A long wall at y = 2 with a 1 m door at x = 6, seen from (0, 0): 18 degrees off the wall.
    rng = np.random.default_rng(9)
    x = rng.uniform(-2.0, 10.0, 3000)
    wall = np.column_stack([x[np.abs(x - 6.0) > 0.5], np.full(np.count_nonzero(
        np.abs(x - 6.0) > 0.5), 2.0)])
    others = [np.column_stack([rng.uniform(-2.0, 10.0, 1500), np.full(1500, -2.0)]),
              np.column_stack([np.full(800, -2.0), rng.uniform(-2.0, 2.0, 800)]),
              np.column_stack([np.full(800, 10.0), rng.uniform(-2.0, 2.0, 800)])]
    xy = np.vstack([wall] + others)
    prep, scene = scene_of(xy, (0.0, 0.0))
    gaps = doorslib.wall_gaps(scene, np.random.default_rng(0))
    centres = prep.frame.from_norm(np.array([d.centre for d in gaps]))
    assert any(near(c, (6.0, 2.0), 0.15) for c in centres)
    assert all(d.source == "wall_gap" for d in gaps)


def test_packaged_model_matches_the_code_and_round_trips(tmp_path):
    ranker = load_ranker("")
    assert load_ranker("") is ranker                    # read once
    info = ranker.info
    assert info["rooms"] > 0 and info["trained_on"].startswith("random_world seeds")
    rng = np.random.default_rng(1)
    x = rng.normal(size=(50, len(doorslib.FEATURE_NAMES)))
    p = ranker.probability(x)
    assert p.shape == (50,) and np.all((p > 0) & (p < 1))
    path = tmp_path / "copy.json"
    path.write_text(json.dumps(ranker.to_dict()))
    np.testing.assert_allclose(load_ranker(str(path)).probability(x), p, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="features must be"):
        ranker.probability(x[:, :3])
    assert ranker.probability(np.zeros((0, len(doorslib.FEATURE_NAMES)))).shape == (0,)


def write_model(path, **changes):
    data = json.load(open(PACKAGED_MODEL))
    data.update(changes)
    path.write_text(json.dumps(data))
    return str(path)


def test_bad_model_files_are_refused_with_the_reason(tmp_path):
    with pytest.raises(RankerModelError, match="cannot read"):
        load_ranker(str(tmp_path / "missing.json"))
    corrupt = tmp_path / "corrupt.json"
    corrupt.write_text('{"format": "sparse_nav door ranker", "trees": [')
    with pytest.raises(RankerModelError, match="not JSON"):
        load_ranker(str(corrupt))
    with pytest.raises(RankerModelError, match="other features"):
        load_ranker(write_model(tmp_path / "f.json", feature_names=["a", "b"]))
    with pytest.raises(RankerModelError, match="version"):
        load_ranker(write_model(tmp_path / "v.json", version=99))
    with pytest.raises(RankerModelError, match="not a sparse_nav door ranker"):
        load_ranker(write_model(tmp_path / "k.json", format="pickle"))
    loop = {"feature": [0, -1, -1], "threshold": [0.0, 0.0, 0.0], "left": [0, -1, -1],
            "right": [2, -1, -1], "value": [0.0, 1.0, 2.0]}
    with pytest.raises(RankerModelError, match="do not form a tree"):
        DoorRanker(0.0, 1.0, [loop])
    with pytest.raises(RankerModelError, match="malformed"):
        load_ranker(write_model(tmp_path / "m.json", trees=[{"feature": [0]}]))
    with pytest.raises(RankerModelError, match="non-finite"):
        DoorRanker(float("nan"), 1.0, [{"feature": [-1], "threshold": [0.0], "left": [-1],
                                        "right": [-1], "value": [0.0]}])
    # Through the finder: a clear error, never an exit from a broken model.
    xy, _ = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=VIEW, seed=4)
    with pytest.raises(ExitFinderError, match="not JSON") as err:
        find_exit(xy, method="ranked", up_axis=None,
                  config=ExitFinderConfig(rank_model=str(corrupt)))
    assert err.value.status == "bad_input"


def test_ranker_follows_its_trees():
    # One stump: feature 0 <= 0.5 -> leaf value -1, else +1; init 0.5, learning rate 2.
    stump = {"feature": [0, -1, -1], "threshold": [0.5, 0.0, 0.0], "left": [1, -1, -1],
             "right": [2, -1, -1], "value": [0.0, -1.0, 1.0]}
    ranker = DoorRanker(0.5, 2.0, [stump, stump])
    x = np.zeros((2, len(doorslib.FEATURE_NAMES)))
    x[1, 0] = 1.0
    expect = 1.0 / (1.0 + np.exp(-np.array([0.5 - 4.0, 0.5 + 4.0])))
    np.testing.assert_allclose(ranker.probability(x), expect)
