"""numpy <-> ROS message conversions, including malformed clouds and poses."""
import numpy as np
import pytest
from geometry_msgs.msg import Pose
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from sparse_nav.ros.conversions import (CloudError, cloud_to_points, matrix_to_pose,
                                        matrix_to_transform_stamped, points_to_cloud,
                                        pose_to_matrix, transform_to_matrix)
from sparse_nav.transforms import planar


def test_cloud_round_trip():
    pts = np.random.default_rng(0).normal(size=(100, 3))
    msg = points_to_cloud(pts, Header(frame_id="map"))
    assert msg.width == 100 and msg.header.frame_id == "map"
    np.testing.assert_allclose(cloud_to_points(msg), pts.astype(np.float32), rtol=1e-6)


def test_cloud_with_extra_fields_and_big_endian():
    dtype = np.dtype([("x", ">f8"), ("rgb", ">u4"), ("y", ">f8"), ("z", ">f8")])
    rec = np.zeros(3, dtype=dtype)
    rec["x"], rec["y"], rec["z"] = [1, 2, 3], [4, 5, 6], [7, 8, 9]
    msg = PointCloud2(height=1, width=3, is_bigendian=True, point_step=dtype.itemsize,
                      data=rec.tobytes())
    msg.fields = [PointField("x", 0, PointField.FLOAT64, 1), PointField("rgb", 8, PointField.UINT32, 1),
                  PointField("y", 12, PointField.FLOAT64, 1), PointField("z", 20, PointField.FLOAT64, 1)]
    np.testing.assert_allclose(cloud_to_points(msg), [[1, 4, 7], [2, 5, 8], [3, 6, 9]])


def test_cloud_without_xyz_is_refused():
    msg = PointCloud2(height=1, width=2, point_step=4, data=bytes(8))
    msg.fields = [PointField("intensity", 0, PointField.FLOAT32, 1)]
    with pytest.raises(CloudError, match="no x/y/z field"):
        cloud_to_points(msg)


def test_truncated_cloud_is_refused():
    msg = points_to_cloud(np.zeros((10, 3)), Header())
    msg.data = msg.data[:50]
    with pytest.raises(CloudError, match="bytes"):
        cloud_to_points(msg)


def test_empty_cloud():
    assert cloud_to_points(points_to_cloud(np.empty((0, 3)), Header())).shape == (0, 3)


def test_pose_round_trip_and_bad_poses():
    t = planar(1, 2, 3, 0.5)
    np.testing.assert_allclose(pose_to_matrix(matrix_to_pose(t)), t, atol=1e-12)
    bad = Pose()
    bad.position.x = float("nan")
    bad.orientation.w = 1.0
    with pytest.raises(ValueError, match="non-finite"):
        pose_to_matrix(bad)
    with pytest.raises(ValueError, match="zero quaternion"):
        pose_to_matrix(Pose())


def test_transform_stamped():
    t = planar(-1, 0.5, 0, 2.0)
    msg = matrix_to_transform_stamped(t, None, "map", "odom")
    assert (msg.header.frame_id, msg.child_frame_id) == ("map", "odom")
    np.testing.assert_allclose(transform_to_matrix(msg.transform), t, atol=1e-12)
