"""Exit finder beyond seed 000: door gaps on any outline, confidence, external gaps, auto."""
import numpy as np
import pytest

from sparse_nav.exit_finder import ExitFinderConfig, ExitFinderError, find_exit, finder
from sparse_nav.exit_finder import gaps as gapslib
from sparse_nav.exit_finder.synthetic import Door, room_cloud, to_orbslam

RECT = [(-3.0, -2.0), (3.0, -2.0), (3.0, 2.0), (-3.0, 2.0)]
L_ROOM = [(0.0, 0.0), (6.0, 0.0), (6.0, 3.0), (3.0, 3.0), (3.0, 6.0), (0.0, 6.0)]


def near(a, b, tol):
    return float(np.hypot(*(np.asarray(a[:2]) - np.asarray(b[:2])))) <= tol


def test_a_door_in_the_middle_of_a_wall():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=(0.3, 0.2), clutter=150,
                           outliers=30, noise=0.03)
    result = find_exit(to_orbslam(xy), method="gaps")
    assert result.status == "ok" and result.method == "gaps"
    assert near(result.exits[0], doors[0], 0.3)
    assert all(0.0 <= s <= 1.0 for _, _, s in result.exits)
    scores = [s for _, _, s in result.exits]
    assert scores == sorted(scores, reverse=True)
    # The outline follows the room: its corners near the room's.
    corners = np.array(result.room_corners)
    for c in RECT:
        assert np.min(np.hypot(*(corners - c).T)) < 0.5


def test_two_doors_in_an_l_shaped_room_are_both_ranked():
    xy, doors = room_cloud(L_ROOM, [Door(side=1, at_m=1.5), Door(side=4, at_m=2.0)],
                           viewpoint=(1.5, 1.5), clutter=100, seed=1)
    result = find_exit(xy, method="gaps", up_axis=None, viewpoint=(1.5, 1.5))
    assert len(result.room_corners) > 4
    top = result.exits[:2]
    for door in doors:
        assert any(near(e, door, 0.3) for e in top)


def test_a_closed_room_has_no_confident_exit():
    xy, _ = room_cloud(RECT, [], viewpoint=(0.3, 0.2), clutter=150, seed=2)
    result = find_exit(xy, method="gaps", up_axis=None, viewpoint=(0.3, 0.2))
    assert all(s < 0.3 for _, _, s in result.exits)
    if not result.exits:
        assert result.status == "no_exit" and result.reason


def test_a_wider_blank_gap_without_anything_behind_is_less_likely_than_a_door():
    # Side 2 is missing 2.4 m of wall with nothing seen through it; side 0 has a real door.
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=4.0)], viewpoint=(0.0, 0.0), seed=3)
    blank = (np.abs(xy[:, 1] - 2.0) < 0.2) & (np.abs(xy[:, 0]) < 1.2)
    result = find_exit(xy[~blank], method="gaps", up_axis=None, viewpoint=(0.0, 0.0))
    assert near(result.exits[0], doors[0], 0.3)


def test_external_door_gaps_are_fused():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=(0.3, 0.2), seed=4)
    base = find_exit(xy, method="gaps", up_axis=None, viewpoint=(0.3, 0.2))
    d = doors[0]
    fused = find_exit(xy, method="gaps", up_axis=None, viewpoint=(0.3, 0.2),
                      door_gaps=[(d[0] + 0.05, d[1], 1.0), (2.5, 2.0, 0.9)])
    assert near(fused.exits[0], d, 0.3)
    assert fused.exits[0][2] > base.exits[0][2]
    # The gap the extractor saw elsewhere (nothing seen through it here) is a weak candidate.
    other = [e for e in fused.exits if near(e, (2.5, 2.0), 0.05)]
    assert other and other[0][2] < fused.exits[0][2]
    with pytest.raises(ExitFinderError, match="door_gaps"):
        find_exit(xy, method="gaps", up_axis=None, door_gaps=[(0.0, 0.0, -1.0)])
    with pytest.raises(ExitFinderError, match="door_gaps"):
        find_exit(xy, method="gaps", up_axis=None, door_gaps=[(0.0, 0.0)])


def test_surface_profile_of_a_circle():
    angles = np.linspace(-np.pi, np.pi, 3600, endpoint=False)
    q = 0.8 * np.column_stack([np.cos(angles), np.sin(angles)])
    profile = gapslib.surface_profile(q, np.zeros(2), ExitFinderConfig())
    assert np.isfinite(profile.ranges).all()
    np.testing.assert_allclose(profile.ranges, 0.8, rtol=0.03)
    assert gapslib.hidden_points(profile, 0.15) == 0


def test_viewpoint_is_estimated_where_the_cloud_was_seen_from():
    view = np.array([1.2, -0.6])
    xy, _ = room_cloud(RECT, [Door(side=0, at_m=1.5), Door(side=1, at_m=2.0)], viewpoint=view,
                       noise=0.05, seed=5)
    cfg = ExitFinderConfig(gap_viewpoint="estimate")
    prep = finder.prepare(xy, None, cfg)
    est = prep.frame.from_norm(gapslib.estimate_viewpoint(prep.q, cfg,
                                                          np.random.default_rng(0)))
    assert np.hypot(*(est - view)) < 0.8
    centroid = xy.mean(axis=0)
    assert np.hypot(*(est - view)) < np.hypot(*(centroid - view))


def test_origin_viewpoint_falls_back_outside_the_cloud():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=(0.3, 0.2), seed=6)
    cfg = ExitFinderConfig()
    inside = finder.prepare(xy, None, cfg)
    assert finder._viewpoint(inside, cfg, None) is not None
    far = finder.prepare(xy + [100.0, 0.0], None, cfg)
    assert finder._viewpoint(far, cfg, None) is None      # estimated instead
    result = find_exit(xy + [100.0, 0.0], method="gaps", up_axis=None)
    assert result.exits


def test_auto_uses_ranked_when_confident_and_the_seed_otherwise():
    xy, doors = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=(0.3, 0.2), seed=7)
    result = find_exit(xy, method="auto", up_axis=None)
    assert result.method == "auto:ranked" and near(result.exits[0], doors[0], 0.3)
    strict = ExitFinderConfig(auto_min_confidence=1.0)
    fallback = find_exit(xy, method="auto", up_axis=None, config=strict)
    assert fallback.method in ("auto:seed", "auto:concave_vertex", "auto:ranked")
    assert fallback.method != "auto:ranked" or all(e[2] < 1.0 for e in fallback.exits)


def test_door_centre_follows_the_points_seen_through_the_opening():
    n = 360
    angles = (np.arange(n) + 0.5) * (2 * np.pi / n) - np.pi
    profile = gapslib.Profile(centre=np.zeros(2), angles=angles, ranges=np.ones(n),
                              bearing=np.zeros(0, dtype=int), radius=np.zeros(0))
    a, b = profile.point(80), profile.point(100)
    aperture = a + 0.75 * (b - a)
    # A bundle of points beyond the bridge, all on the bearing of its three-quarter point.
    q = np.outer(np.linspace(1.5, 2.5, 10), aperture / np.hypot(*aperture))
    cfg = ExitFinderConfig()
    centre = gapslib.door_centre(profile, q, 80, 100, np.ones(10, dtype=bool), cfg)
    assert np.allclose(centre, aperture, atol=1e-9)
    few = np.zeros(10, dtype=bool)
    few[:cfg.gap_centre_min_points - 1] = True
    assert np.allclose(gapslib.door_centre(profile, q, 80, 100, few, cfg), 0.5 * (a + b))


def test_an_opening_seen_through_in_part_only_ranks_below_one_filled_by_its_backdrop():
    # Door A (y = -2) shows its backdrop across its width, like an exit; opening B (y = 2) is
    # narrower, nearer the likeliest door width, but shows something in only a quarter of its
    # bearings, like an inner door onto a room whose far walls are out of reach.
    doors = [Door(side=0, at_m=2.0, width_m=1.0), Door(side=2, at_m=3.0, width_m=0.8, beyond_m=3.0)]
    xy, centres = room_cloud(RECT, doors, viewpoint=(0.0, 0.0), seed=5)
    seen_through_b = xy[:, 1] > 2.3
    xy = xy[~(seen_through_b & (xy[:, 0] > -0.5))]
    result = find_exit(xy, method="gaps", up_axis=None, viewpoint=(0.0, 0.0))
    assert near(result.exits[0], centres[0], 0.3)
    assert any(near(e, centres[1], 0.4) for e in result.exits[1:])
    ignored = ExitFinderConfig(gap_cover_weight=0.0)
    without = find_exit(xy, method="gaps", up_axis=None, viewpoint=(0.0, 0.0), config=ignored)
    assert near(without.exits[0], centres[1], 0.4)


def test_an_opening_onto_walls_at_many_depths_loses_confidence_a_single_backdrop_keeps():
    # What is seen through opening B (y = 2) spreads from just behind it to over twice as far:
    # a room beyond, not outside. Door A (y = -2) shows one backdrop.
    doors = [Door(side=0, at_m=2.0, width_m=1.0), Door(side=2, at_m=3.0, width_m=0.8)]
    xy, centres = room_cloud(RECT, doors, viewpoint=(0.0, 0.0), seed=5)
    through_b = xy[:, 1] > 2.3
    xy[through_b] *= np.random.default_rng(6).uniform(0.8, 2.0, np.count_nonzero(through_b))[:, None]

    def confidences(config):
        result = find_exit(xy, method="gaps", up_axis=None, viewpoint=(0.0, 0.0), config=config)
        return [next(e[2] for e in result.exits if near(e, c, 0.4)) for c in centres]

    a, b = confidences(None)
    a_without, b_without = confidences(ExitFinderConfig(gap_spread_weight=0.0))
    assert a == pytest.approx(a_without) and a > b
    assert b < 0.5 * b_without


def test_spread_beyond_the_free_share_divides_the_confidence():
    cfg = ExitFinderConfig(gap_spread_free=0.5, gap_spread_weight=2.0)
    base = gapslib.door_confidence(50, 0.2, cfg, 1.0)
    assert gapslib.door_confidence(50, 0.2, cfg, 1.0, spread=0.4) == pytest.approx(base)
    assert gapslib.door_confidence(50, 0.2, cfg, 1.0, spread=1.0) == pytest.approx(base / 2.0)


def test_the_depth_spread_of_what_is_seen_through_an_opening():
    n = 40
    profile = gapslib.Profile(centre=np.zeros(2), angles=np.zeros(1), ranges=np.ones(1),
                              bearing=np.zeros(n, dtype=int), radius=np.linspace(2.0, 4.0, n))
    through = np.ones(n, dtype=bool)
    expected = (np.quantile(profile.radius, 0.9) - np.quantile(profile.radius, 0.1)) / 2.0
    assert gapslib.through_depth_spread(profile, through, 2.0) == pytest.approx(expected)
    few = np.zeros(n, dtype=bool)
    few[:9] = True
    assert gapslib.through_depth_spread(profile, few, 2.0) == 0.0


def test_a_stray_surface_in_an_opening_does_not_hide_the_door_behind_it():
    # A round room of radius 1 with an opening over bearings 80-99 that shows a backdrop at 1.6,
    # and at bearing 85 one stray surface in the opening: the first jump back inwards.
    n = 360
    angles = (np.arange(n) + 0.5) * (2 * np.pi / n) - np.pi
    ranges = np.ones(n)
    ranges[80:100] = 1.6
    ranges[85] = 0.7
    profile = gapslib.Profile(centre=np.zeros(2), angles=angles, ranges=ranges,
                              bearing=np.zeros(0, dtype=int), radius=np.zeros(0))
    # With only the first jump tried, the wall's end at 79 pairs with the stray surface, which
    # is no jamb (nothing of a wall after it), and the door's left jamb is lost.
    assert (79, 100) not in gapslib.find_notches(profile, ExitFinderConfig(gap_max_rights=1))
    assert (79, 100) in gapslib.find_notches(profile, ExitFinderConfig(gap_max_rights=2))
    assert ExitFinderConfig().gap_max_rights == 2
