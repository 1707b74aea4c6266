"""Small rigid-transform helpers on 4x4 numpy matrices (ROS-free).

Quaternions are (x, y, z, w), as in geometry_msgs.
"""
import numpy as np


def quaternion_to_matrix(q):
    """Rotation matrix (3x3) of a unit quaternion (x, y, z, w); the quaternion is normalised."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def matrix_to_quaternion(rot):
    """Unit quaternion (x, y, z, w) of a 3x3 rotation matrix (Shepperd's method, w >= 0)."""
    m = np.asarray(rot, dtype=float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def make_transform(rotation=None, translation=None):
    """4x4 homogeneous transform from a 3x3 rotation and a 3-vector."""
    t = np.eye(4)
    if rotation is not None:
        t[:3, :3] = rotation
    if translation is not None:
        t[:3, 3] = translation
    return t


def invert(t):
    """Inverse of a rigid 4x4 transform."""
    inv = np.eye(4)
    inv[:3, :3] = t[:3, :3].T
    inv[:3, 3] = -t[:3, :3].T @ t[:3, 3]
    return inv


def yaw_of(t):
    """Heading (rad) of the x axis of a transform, projected on the x-y plane."""
    return float(np.arctan2(t[1, 0], t[0, 0]))


def planar(x, y, z, yaw):
    """4x4 transform of a pose with position (x, y, z) and heading yaw (rad) about +z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return make_transform(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]), [x, y, z])


def scaled(t, metres_per_unit):
    """A SLAM-frame transform with its translation converted from SLAM units to metres."""
    out = np.array(t, dtype=float)
    out[:3, 3] *= metres_per_unit
    return out


def apply_planar(t, xy):
    """(N, 2) points xy carried by the x-y part of the 4x4 transform t."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return xy @ t[:2, :2].T + t[:2, 3]
