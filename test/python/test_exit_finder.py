"""Exit finder entry point: bad input, configuration, result form, and that rotating, moving or
scaling the input moves the answer with it."""
import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparse_nav.exit_finder import (DEFAULT_METHOD, METHODS, ExitFinderConfig, ExitFinderError,
                                    find_exit)
from sparse_nav.exit_finder.synthetic import Door, room_cloud, to_orbslam

RECT = [(-3.0, -2.0), (3.0, -2.0), (3.0, 2.0), (-3.0, 2.0)]
VIEW = np.array([0.3, 0.2])
ROOM_XY, ROOM_DOORS = room_cloud(RECT, [Door(side=0, at_m=2.0)], viewpoint=VIEW, clutter=100,
                                 noise=0.02, seed=11)
ROOM = to_orbslam(ROOM_XY)
# Two doors and realistic depth noise: enough for the viewpoint to be found from the cloud.
ROOM2 = to_orbslam(room_cloud(RECT, [Door(side=0, at_m=2.0), Door(side=1, at_m=2.5)],
                              viewpoint=VIEW, clutter=100, noise=0.08, seed=12)[0])


def test_methods_and_default():
    assert DEFAULT_METHOD == "ranked" and {"gaps", "seed", "auto"} <= set(METHODS)
    with pytest.raises(ValueError, match="unknown method"):
        find_exit(ROOM, method="magic")


@pytest.mark.parametrize("method", METHODS)
def test_too_few_points_is_an_error_never_an_exit(method):
    pts = np.random.default_rng(0).uniform(-1.0, 1.0, (5, 3))
    with pytest.raises(ExitFinderError, match="a room needs at least") as info:
        find_exit(pts, method=method)
    assert info.value.status == "too_few_points" and info.value.n_points_in == 5


@pytest.mark.parametrize("method", METHODS)
def test_collinear_points_are_an_error(method):
    t = np.linspace(0.0, 5.0, 500)
    pts = np.column_stack([t, np.random.default_rng(1).uniform(-1, 0, 500), 2.0 * t + 1.0])
    with pytest.raises(ExitFinderError, match="collinear") as info:
        find_exit(pts, method=method)
    assert info.value.status == "collinear"
    with pytest.raises(ExitFinderError, match="identical"):
        find_exit(np.ones((100, 3)), method=method)


def test_scattered_noise_after_ipcl_is_too_few_points():
    pts = np.random.default_rng(2).uniform(-100.0, 100.0, (60, 3))
    with pytest.raises(ExitFinderError, match="after de-duplication and IPCL") as info:
        find_exit(pts)
    assert info.value.status == "too_few_points"


def test_nan_rows_are_dropped_and_counted_or_refused():
    pts = ROOM.copy()
    pts[::50, 0] = np.nan
    pts[1::50, 2] = np.inf
    result = find_exit(pts, method="gaps")
    n_bad = len(pts[::50]) + len(pts[1::50])
    assert result.n_dropped_non_finite == n_bad and result.n_points_in == len(pts)
    assert result.exits
    pts[:, 1] = np.nan          # the vertical axis is dropped: its NaNs do not matter
    assert find_exit(pts, method="gaps").n_dropped_non_finite == n_bad
    with pytest.raises(ExitFinderError, match="NaN or infinite") as info:
        find_exit(pts, config=ExitFinderConfig(drop_non_finite=False))
    assert info.value.status == "bad_input"
    with pytest.raises(ExitFinderError, match="0 finite points"):
        find_exit(np.full((30, 3), np.nan))


def test_wrong_shapes_are_refused():
    with pytest.raises(ExitFinderError, match="2 columns"):
        find_exit(ROOM[:, :2])
    with pytest.raises(ExitFinderError, match="shape"):
        find_exit(np.zeros((40, 4)))
    result = find_exit(ROOM_XY, up_axis=None)
    assert result.exits


def test_config_validation():
    ExitFinderConfig().validate()
    for bad in ({"ipcl_radius": 0.0}, {"line_score": "mean"}, {"ransac_lines": 3},
                {"scale_percentile": 0.0}, {"gap_min_width": 1.0}, {"gap_viewpoint": "x"},
                {"min_points": 2.5}, {"ransac_refit": 1}, {"external_weight": 1.5},
                {"line_near_dist": float("nan")}):
        with pytest.raises(ValueError):
            dataclasses.replace(ExitFinderConfig(), **bad).validate()
    with pytest.raises(ValueError, match="ipcl_radius"):
        find_exit(ROOM, config=ExitFinderConfig(ipcl_radius=-1.0))


def test_result_form_json_and_determinism():
    result = find_exit(ROOM, seed=3)
    data = result.to_json_dict()
    assert list(data) == ["exits", "method", "room_corners", "n_points_in", "n_points_used",
                          "runtime_s"]
    assert all(list(e) == ["x", "y", "score"] for e in data["exits"])
    assert data["n_points_in"] == len(ROOM) and 0 < data["n_points_used"] <= len(ROOM)
    assert all(len(c) == 2 for c in data["room_corners"]) and data["runtime_s"] > 0
    again = find_exit(ROOM, seed=3)
    assert again.exits == result.exits and again.room_corners == result.room_corners
    # Results are in the input's x and z (ORB-SLAM: y is down and is dropped).
    assert math.hypot(result.exits[0][0] - ROOM_DOORS[0][0],
                      result.exits[0][1] - ROOM_DOORS[0][1]) < 0.3


def transform(xy, angle, scale, shift):
    c, s = math.cos(angle), math.sin(angle)
    return scale * np.asarray(xy) @ np.array([[c, s], [-s, c]]) + shift


def moved_input(angle, scale, shift, room=ROOM):
    moved = room.copy()
    moved[:, [0, 2]] = transform(room[:, [0, 2]], angle, scale, shift)
    moved[:, 1] *= scale
    return moved


ANGLES = st.floats(-math.pi, math.pi)
SCALES = st.floats(0.05, 20.0)
SHIFTS = st.tuples(st.floats(-50.0, 50.0), st.floats(-50.0, 50.0))


@settings(max_examples=12, deadline=None, derandomize=True)
@given(angle=ANGLES, scale=SCALES, shift=SHIFTS)
def test_gap_answer_moves_with_the_input(angle, scale, shift):
    # The viewpoint is part of the input (where the map was seen from): it moves with it.
    base = find_exit(ROOM, method="gaps", viewpoint=VIEW)
    moved = find_exit(moved_input(angle, scale, shift), method="gaps",
                      viewpoint=transform(VIEW, angle, scale, shift))
    expect = transform(base.exits[0][:2], angle, scale, shift)
    assert np.hypot(*(np.array(moved.exits[0][:2]) - expect)) < 0.1 * scale
    assert moved.exits[0][2] == pytest.approx(base.exits[0][2], abs=0.15)


@settings(max_examples=8, deadline=None, derandomize=True)
@given(angle=ANGLES, scale=SCALES)
def test_default_answer_moves_with_rotation_and_scaling_about_the_origin(angle, scale):
    # The default takes the input's origin (an ORB-SLAM map's first camera) as the viewpoint,
    # which rotation and scaling about it keep.
    base = find_exit(ROOM)
    moved = find_exit(moved_input(angle, scale, (0.0, 0.0)))
    assert moved.method == base.method
    expect = transform(base.exits[0][:2], angle, scale, (0.0, 0.0))
    assert np.hypot(*(np.array(moved.exits[0][:2]) - expect)) < 0.1 * scale


@settings(max_examples=8, deadline=None, derandomize=True)
@given(angle=ANGLES, scale=SCALES, shift=SHIFTS)
def test_estimated_viewpoint_answer_moves_with_the_input(angle, scale, shift):
    cfg = ExitFinderConfig(gap_viewpoint="estimate")
    base = find_exit(ROOM2, method="gaps", config=cfg)
    moved = find_exit(moved_input(angle, scale, shift, ROOM2), method="gaps", config=cfg)
    expect = transform(base.exits[0][:2], angle, scale, shift)
    assert np.hypot(*(np.array(moved.exits[0][:2]) - expect)) < 0.15 * scale


def seed_room():
    """A 4 m square whose corner (4, 4) opens into an alcove (seed 000's recessed exit)."""
    rng = np.random.default_rng(4)
    walls = [((0, 0), (4, 0)), ((4, 0), (4, 3.2)), ((3.2, 4), (0, 4)), ((0, 4), (0, 0)),
             ((4, 3.2), (4.8, 3.2)), ((3.2, 4), (3.2, 4.8))]
    pts = []
    for a, b in walls:
        a, b = np.array(a, dtype=float), np.array(b, dtype=float)
        pts.append(a + rng.uniform(0, 1, (int(150 * np.hypot(*(b - a))), 1)) * (b - a))
    return np.vstack(pts) + rng.normal(0.0, 0.005, (sum(len(p) for p in pts), 2))


SEED_ROOM = seed_room()


@settings(max_examples=12, deadline=None, derandomize=True)
@given(angle=ANGLES, scale=SCALES, shift=SHIFTS)
def test_seed_answer_moves_with_the_input(angle, scale, shift):
    base = find_exit(SEED_ROOM, method="seed", up_axis=None)
    moved = find_exit(transform(SEED_ROOM, angle, scale, shift), method="seed", up_axis=None)
    expect = transform(base.exits[0][:2], angle, scale, shift)
    # Rounding to the grid of the moved cloud changes which points RANSAC fits, so a corner may
    # move by a few per cent of the room (line band 0.05 cloud radii): 0.2 m in this 4 m room.
    assert np.hypot(*(np.array(moved.exits[0][:2]) - expect)) < 0.2 * scale
    corners = transform(np.array(base.room_corners), angle, scale, shift)
    for c in moved.room_corners:
        assert np.min(np.hypot(*(corners - c).T)) < 0.25 * scale


def test_gaps_falls_back_to_the_estimated_viewpoint_when_the_given_one_shows_no_exit(monkeypatch):
    from sparse_nav.exit_finder import gaps
    real = gaps.find_gaps
    calls = []

    def origin_blind(q, cfg, rng=None, external=None, viewpoint=None):
        calls.append(viewpoint)
        found = real(q, cfg, rng, external, viewpoint)
        if viewpoint is not None:  # as if the door were hidden from the given viewpoint
            return dataclasses.replace(found, exits=[])
        return found

    monkeypatch.setattr(gaps, "find_gaps", origin_blind)
    r = find_exit(ROOM2, method="gaps", viewpoint=tuple(VIEW))
    assert calls[0] is not None and calls[1] is None
    assert r.status == "ok" and r.exits
    assert "from the viewpoint the cloud suggests" in r.reason
    # An exit found from the given viewpoint needs no second search.
    calls.clear()
    monkeypatch.setattr(gaps, "find_gaps", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    assert find_exit(ROOM2, method="gaps", viewpoint=tuple(VIEW)).exits and len(calls) == 1
