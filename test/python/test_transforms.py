"""Rigid transform helpers."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sparse_nav.transforms import (apply_planar, invert, make_transform, matrix_to_quaternion,
                                   planar, quaternion_to_matrix)

quaternions = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 0.1)


@settings(max_examples=200, deadline=None)
@given(quaternions)
def test_quaternion_round_trip(q):
    rot = quaternion_to_matrix(q)
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(rot) > 0
    np.testing.assert_allclose(quaternion_to_matrix(matrix_to_quaternion(rot)), rot, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(quaternions, st.lists(st.floats(-100, 100), min_size=3, max_size=3))
def test_invert(q, t):
    m = make_transform(quaternion_to_matrix(q), t)
    np.testing.assert_allclose(invert(m) @ m, np.eye(4), atol=1e-9)


def test_planar():
    m = planar(1, 2, 3, np.pi / 2)
    np.testing.assert_allclose(m[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(m[:3, 3], [1, 2, 3])


def test_apply_planar_carries_points_by_the_x_y_part():
    t = planar(1.0, 2.0, 5.0, np.pi / 2)
    assert np.allclose(apply_planar(t, [(1.0, 0.0), (0.0, 1.0)]), [(1.0, 3.0), (0.0, 2.0)])
    assert apply_planar(t, []).shape == (0, 2)
