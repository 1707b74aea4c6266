"""Exit finder, seed 000 steps 4-8 and the seed's alternatives, on small hand-made clouds."""
import numpy as np
import pytest

from sparse_nav.exit_finder import ExitFinderConfig, ExitFinderError, find_exit
from sparse_nav.exit_finder import geometry as geo
from sparse_nav.exit_finder import seed as seedlib

CFG = ExitFinderConfig()


def segment(a, b, per_unit, rng):
    """Points spread uniformly along the segment a-b."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n = int(per_unit * np.hypot(*(b - a)))
    return a + rng.uniform(0.0, 1.0, (n, 1)) * (b - a)


def square(per_unit=100, half=1.0, seed=0):
    rng = np.random.default_rng(seed)
    c = [(-half, -half), (half, -half), (half, half), (-half, half)]
    return np.vstack([segment(c[i], c[(i + 1) % 4], per_unit, rng) for i in range(4)])


def recessed_room(seed=0, per_m=150):
    """Seed 000's escape room: a 4 m square whose corner (4, 4) opens into an alcove that holds
    the door (its jambs at the alcove's far side): the two walls meeting there stop 0.8 m short
    of the corner and the alcove adds two more lines."""
    rng = np.random.default_rng(seed)
    walls = [((0, 0), (4, 0)), ((4, 0), (4, 3.2)), ((3.2, 4), (0, 4)), ((0, 4), (0, 0)),
             ((4, 3.2), (4.8, 3.2)), ((3.2, 4), (3.2, 4.8)),
             ((3.2, 4.8), (3.6, 4.8)), ((4.8, 3.2), (4.8, 3.6))]
    pts = np.vstack([segment(a, b, per_m, rng) for a, b in walls])
    return pts + rng.normal(0.0, 0.01, pts.shape)


def test_step4_ransac_finds_a_known_line_among_outliers():
    rng = np.random.default_rng(1)
    x = rng.uniform(-1.0, 1.0, 200)
    on_line = np.column_stack([x, 2.0 * x + 1.0])
    q = np.vstack([on_line, rng.uniform(-3.0, 3.0, (100, 2))])
    line, inliers = seedlib.ransac_line(q, np.random.default_rng(0), 200, 0.01)
    assert abs(abs(np.dot(line.direction, [1.0, 2.0] / np.sqrt(5.0))) - 1.0) < 1e-6
    assert line.distances(np.array([[0.0, 1.0]]))[0] < 1e-6
    assert inliers[:200].all() and inliers[200:].sum() < 10
    assert seedlib.ransac_line(q[:1], np.random.default_rng(0), 10, 0.01) is None


def test_step4_lines_are_found_one_after_another_on_the_remaining_points():
    inside = np.random.default_rng(5).uniform(-0.8, 0.8, (30, 2))
    q = np.vstack([square(per_unit=100), inside])
    lines = seedlib.sequential_lines(q, 6, np.random.default_rng(0), 200, 0.02)
    assert len(lines) == 6
    # Without the scattered points, the points run out after the four sides.
    assert len(seedlib.sequential_lines(square(), 6, np.random.default_rng(0), 200, 0.02)) == 4
    # The first four are the four sides, each once: their points were removed after each find.
    normals = sorted(round(abs(float(np.dot(line.normal, [1.0, 0.0]))), 1) for line in lines[:4])
    assert normals == [0.0, 0.0, 1.0, 1.0]
    offsets = sorted(round(float(abs(line.signed(np.zeros((1, 2)))[0])), 2) for line in lines[:4])
    assert offsets == [1.0, 1.0, 1.0, 1.0]


def test_step5_line_scores_rpcl_count_and_extent():
    line = geo.Line.through([0.0, 0.0], [1.0, 0.0])
    spread = np.column_stack([np.arange(10) * 0.1, np.zeros(10)])
    blob = np.column_stack([0.55 + np.linspace(0, 0.004, 20), np.full(20, 0.01)])
    near = np.vstack([spread, blob])
    # RPCL keeps the spread points (no 8 others within 0.02) and drops the dense blob.
    assert seedlib.line_score(near, line, "rpcl", 0.02, 8) == 10
    assert seedlib.line_score(near, line, "count") == 30
    assert seedlib.line_score(near, line, "extent") == pytest.approx(0.9)
    assert seedlib.line_score(spread, line, "rpcl", 0.02, 8) == 10
    assert seedlib.line_score(spread[:1], line, "extent") == 0.0
    with pytest.raises(ValueError):
        seedlib.line_score(near, line, "nonsense")


def test_step5_best_lines_by_score_skipping_repeats_of_a_thick_wall():
    q = square(per_unit=100)
    lines = [geo.Line.through([-1, -1], [1, -1]), geo.Line.through([-1, -0.98], [1, -0.98]),
             geo.Line.through([1, -1], [1, 1]), geo.Line.through([1, 1], [-1, 1]),
             geo.Line.through([-1, 1], [-1, -1])]
    scores = np.array([50.0, 40.0, 30.0, 20.0, 10.0])
    near = np.array([line.distances(q) <= 0.03 for line in lines])
    assert seedlib.best_lines(q, lines, scores, near, CFG) == [0, 2, 3, 4]
    plain = ExitFinderConfig(distinct_lines=False)
    assert seedlib.best_lines(q, lines, scores, near, plain) == [0, 1, 2, 3]


def test_step6_quadrilateral_corners_of_a_known_square():
    q = square(per_unit=50)
    lines = [geo.Line.through([-1, 1], [1, 1]), geo.Line.through([-1, -1], [1, -1]),
             geo.Line.through([1, -1], [1, 1]), geo.Line.through([-1, 1], [-1, -1])]
    near = np.array([line.distances(q) <= 0.03 for line in lines])
    sides, corners = seedlib.polygon_from_lines(q, lines, near, [0, 1, 2, 3], np.zeros(2), CFG)
    # Counter-clockwise around the centre: ... bottom, right, top, left ...
    start = sides.index(1)
    assert sides[start:] + sides[:start] == [1, 2, 0, 3]
    # Vertex i is where sides i-1 and i meet.
    for i in range(4):
        expected = geo.intersect(lines[sides[i - 1]], lines[sides[i]])
        np.testing.assert_allclose(corners[i], expected, atol=1e-12)
    np.testing.assert_allclose(np.roll(corners, -start, axis=0),
                               [[-1, -1], [1, -1], [1, 1], [-1, 1]], atol=1e-12)
    assert geo.signed_area(corners) == pytest.approx(4.0)


def test_step6_degenerate_quadrilaterals_are_refused():
    q = square(per_unit=50)
    lines = [geo.Line.through([-1, -1], [1, -1]), geo.Line.through([-1, -0.7], [1, -0.6]),
             geo.Line.through([1, 1], [-1, 1]), geo.Line.through([-1, 1], [-1, -1])]
    near = np.array([line.distances(q) <= 0.03 for line in lines])
    with pytest.raises(ExitFinderError, match="parallel") as info:
        seedlib.polygon_from_lines(q, lines, near, [0, 1, 2, 3], np.zeros(2), CFG)
    assert info.value.status == "no_room_shape"


def test_step7_perimeter_samples_are_evenly_spaced():
    poly = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    samples, side = geo.perimeter_samples(poly, 8)
    np.testing.assert_allclose(samples, [[0.5, 0], [1.5, 0], [2, 0.5], [2, 1.5],
                                         [1.5, 2], [0.5, 2], [0, 1.5], [0, 0.5]])
    np.testing.assert_array_equal(side, [0, 0, 1, 1, 2, 2, 3, 3])


def test_step7_samples_with_cloud_points_near_them_are_dropped():
    poly = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    rng = np.random.default_rng(0)
    # Walls everywhere except the first half of side 0 and all of side 3.
    q = np.vstack([segment([1.0, 0.0], [2.0, 0.0], 400, rng), segment([2, 0], [2, 2], 400, rng),
                   segment([2, 2], [0, 2], 400, rng)])
    cfg = ExitFinderConfig(perimeter_samples=8, sample_radius=0.1, sample_max_points=2)
    _, side, kept = seedlib.empty_samples(q, poly, cfg)
    np.testing.assert_array_equal(kept, [True, False, False, False, False, False, True, True])
    per_side, sums = seedlib.corner_sums(side, kept, 4)
    np.testing.assert_array_equal(per_side, [1, 0, 0, 2])
    # Vertex i joins sides i-1 and i: vertex 0 (the origin) has 2 + 1.
    np.testing.assert_array_equal(sums, [3, 1, 0, 2])


def test_step8_the_exit_is_the_recessed_corner():
    result = find_exit(recessed_room(), method="seed", up_axis=None)
    assert result.status == "ok" and result.method == "seed"
    best = np.array(result.exits[0][:2])
    assert np.hypot(*(best - [4.0, 4.0])) < 0.4
    assert len(result.room_corners) == 4
    assert all(0.0 <= s <= 1.0 for _, _, s in result.exits)
    # The plot's blue points: on the two room lines that meet at the exit.
    assert len(result.details["line_points"]) > 100
    assert result.exits == find_exit(recessed_room(), method="seed", up_axis=None).exits


def test_seed_alternatives_on_the_recessed_room():
    xy = recessed_room()
    corners = find_exit(xy, method="farthest_corner", up_axis=None)
    assert len(corners.exits) == 4
    assert sum(s for _, _, s in corners.exits) == pytest.approx(1.0)
    scores = [s for _, _, s in corners.exits]
    assert scores == sorted(scores, reverse=True)
    # DBSCAN's clusters lie outside the room: in the alcove, beyond the corner.
    dbscan = find_exit(xy, method="dbscan", up_axis=None)
    assert dbscan.exits and all(x > 3.0 and y > 3.0 for x, y, _ in dbscan.exits)
    concave = find_exit(xy, method="concave_vertex", up_axis=None)
    assert concave.exits
    best = np.array(concave.exits[0][:2])
    assert np.hypot(*(best - [4.0, 4.0])) < 1.5


def test_concave_vertex_of_an_l_shaped_outline():
    # A dense L: the square (0..2)^2 without its upper-right quarter; its reflex corner is (1, 1).
    rng = np.random.default_rng(2)
    inside = rng.uniform(0.0, 2.0, (6000, 2))
    inside = inside[~((inside[:, 0] > 1) & (inside[:, 1] > 1))]
    exits, poly = seedlib.concave_vertices((inside - 1.0) / 1.0, ExitFinderConfig())
    assert poly is not None and len(poly) >= 5
    assert np.hypot(*(np.array(exits[0][:2]) - [0.0, 0.0])) < 0.1


def test_other_line_scores_run_as_methods():
    for method in ("seed_count", "seed_extent"):
        try:
            result = find_exit(recessed_room(), method=method, up_axis=None)
        except ExitFinderError as exc:
            assert exc.status == "no_room_shape"
        else:
            assert result.method == method
