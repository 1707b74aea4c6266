"""Exit finder, seed 000 steps 1-3: horizontal points, normalisation, rounding, PCL/IPCL/RPCL."""
import numpy as np
import pytest

from sparse_nav.exit_finder import ExitFinderError
from sparse_nav.exit_finder.cloud import (CloudFrame, check_spread, ipcl, neighbour_counts,
                                          pcl_mask, planar_columns, planar_points, round_dedup,
                                          rpcl)

PTS3 = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])


@pytest.mark.parametrize("up, cols", [("-y", (0, 2)), ("y", (0, 2)), ("+y", (0, 2)),
                                      ("z", (0, 1)), ("-z", (0, 1)), ("X", (1, 2))])
def test_step1_drops_the_vertical_axis_keeping_the_others_in_order(up, cols):
    assert planar_columns(up) == cols
    xy, dropped = planar_points(PTS3, up)
    np.testing.assert_array_equal(xy, PTS3[:, cols])
    assert dropped == 0


def test_planar_input_and_bad_shapes():
    xy, _ = planar_points(PTS3[:, :2], None)
    np.testing.assert_array_equal(xy, PTS3[:, :2])
    for points, up, what in ((PTS3[:, :2], "-y", "2 columns"), (np.zeros((3, 4)), "-y", "shape"),
                             (PTS3, None, "up_axis"), (PTS3, "w", "up_axis"),
                             (np.zeros(5), "-y", "shape"), ([["a", "b", "c"]], "-y", "numeric")):
        with pytest.raises(ExitFinderError, match=what) as info:
            planar_points(points, up)
        assert info.value.status == "bad_input"


def test_non_finite_rows_are_dropped_and_counted_or_refused():
    pts = np.array([[0.0, 9.0, 0.0], [np.nan, 0.0, 1.0], [1.0, np.inf, 1.0], [2.0, 0.0, np.inf]])
    xy, dropped = planar_points(pts, "-y")
    # The vertical coordinate is dropped, so only x and z decide.
    np.testing.assert_array_equal(xy, [[0.0, 0.0], [1.0, 1.0]])
    assert dropped == 2
    with pytest.raises(ExitFinderError, match="2 of 4 points .* row 1"):
        planar_points(pts, "-y", drop_non_finite=False)


def test_cloud_frame_is_centred_and_scaled_and_moves_with_the_input():
    xy = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    frame = CloudFrame.of(xy, 80.0)
    np.testing.assert_allclose(frame.centre, [1.0, 1.0])
    assert frame.scale == pytest.approx(np.sqrt(2.0))
    np.testing.assert_allclose(frame.from_norm(frame.to_norm(xy)), xy)
    moved = CloudFrame.of(3.0 * xy + [5.0, -7.0], 80.0)
    np.testing.assert_allclose(moved.to_norm(3.0 * xy + [5.0, -7.0]), frame.to_norm(xy))


def test_step2_rounds_to_two_decimals_and_removes_duplicates_in_order():
    q = np.array([[0.5, 0.5], [0.123, 0.456], [0.1249, 0.4551], [-0.001, 0.0], [0.001, 0.0]])
    out = round_dedup(q, 2)
    # 0.123/0.1249 -> 0.12 and 0.456/0.4551 -> 0.46: one point; -0.00 and 0.00 are one point.
    np.testing.assert_array_equal(out, [[0.5, 0.5], [0.12, 0.46], [0.0, 0.0]])
    assert not np.signbit(out[2]).any()


def test_pcl_judges_every_point_against_the_same_set():
    q = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [10.0, 0.0]])
    np.testing.assert_array_equal(neighbour_counts(q, 1.01), [1, 2, 2, 1, 0])
    np.testing.assert_array_equal(pcl_mask(q, 1.01, 1), [True, True, True, True, False])


def test_ipcl_applies_removals_at_the_end_of_each_round():
    # With two neighbours needed, the chain's ends go in round 1 (together: removing x=0 first
    # does not make x=1 fail in the same round); round 2 then removes the middle pair.
    q = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    np.testing.assert_array_equal(ipcl(q, 1.01, 2, 1), [[1.0, 0.0], [2.0, 0.0]])
    assert len(ipcl(q, 1.01, 2, 2)) == 0
    # A dense square survives any number of rounds unchanged (early stop).
    grid = np.array([[x, y] for x in range(3) for y in range(3)], dtype=float)
    np.testing.assert_array_equal(ipcl(grid, 1.01, 2, 5), grid)
    np.testing.assert_array_equal(ipcl(grid, 1.01, 2, 0), grid)


def test_rpcl_is_the_complement_of_pcl():
    rng = np.random.default_rng(3)
    q = np.vstack([rng.normal(0.0, 0.01, (30, 2)), rng.uniform(-1.0, 1.0, (30, 2))])
    kept, removed = q[pcl_mask(q, 0.05, 4)], rpcl(q, 0.05, 4)
    assert len(kept) + len(removed) == len(q)
    assert not set(map(tuple, kept)) & set(map(tuple, removed))
    assert len(removed) >= 20      # the spread points
    assert len(rpcl(np.zeros((0, 2)), 0.05, 4)) == 0


def test_check_spread_refuses_small_collinear_or_identical_clouds():
    line = np.column_stack([np.arange(50.0), 2.0 * np.arange(50.0)])
    with pytest.raises(ExitFinderError, match="at least 20") as info:
        check_spread(line[:5], 20, 0.02, 5)
    assert info.value.status == "too_few_points"
    with pytest.raises(ExitFinderError, match="collinear") as info:
        check_spread(line, 20, 0.02, 50)
    assert info.value.status == "collinear"
    with pytest.raises(ExitFinderError, match="identical"):
        check_spread(np.ones((30, 2)), 20, 0.02, 30)
    check_spread(np.column_stack([line[:, 0], np.tile([0.0, 5.0], 25)]), 20, 0.02, 50)
