"""Conversions between numpy arrays / 4x4 transforms and ROS messages."""
import numpy as np
from geometry_msgs.msg import Pose, Transform, TransformStamped
from sensor_msgs.msg import PointCloud2, PointField

from sparse_nav.transforms import make_transform, matrix_to_quaternion, quaternion_to_matrix

_XYZ_FIELDS = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
               for i, n in enumerate("xyz")]
_NUMPY_OF_FIELD = {PointField.INT8: "i1", PointField.UINT8: "u1", PointField.INT16: "i2",
                   PointField.UINT16: "u2", PointField.INT32: "i4", PointField.UINT32: "u4",
                   PointField.FLOAT32: "f4", PointField.FLOAT64: "f8"}


class CloudError(ValueError):
    """A PointCloud2 that cannot be read as x/y/z points."""


def points_to_cloud(points, header):
    """PointCloud2 (x, y, z float32, dense) of an (N, 3) array."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float32).reshape(-1, 3))
    msg = PointCloud2()
    msg.header = header
    msg.height = 1
    msg.width = len(pts)
    msg.fields = _XYZ_FIELDS
    msg.is_bigendian = False
    msg.point_step = 12
    msg.row_step = 12 * len(pts)
    msg.is_dense = bool(np.all(np.isfinite(pts)))
    msg.data = pts.tobytes()
    return msg


def cloud_to_points(msg):
    """(N, 3) float64 array of a PointCloud2's x/y/z fields; raises CloudError naming the problem."""
    fields = {f.name: f for f in msg.fields}
    missing = [n for n in "xyz" if n not in fields]
    if missing:
        raise CloudError(f"PointCloud2 has no {'/'.join(missing)} field (fields: "
                         f"{', '.join(fields) or 'none'})")
    n = msg.width * msg.height
    if n == 0:
        return np.empty((0, 3))
    if msg.point_step <= 0 or len(msg.data) < n * msg.point_step:
        raise CloudError(f"PointCloud2 data holds {len(msg.data)} bytes, "
                         f"{n} points of {msg.point_step} bytes need {n * msg.point_step}")
    endian = ">" if msg.is_bigendian else "<"
    names, formats, offsets = [], [], []
    for name in "xyz":
        f = fields[name]
        if f.datatype not in _NUMPY_OF_FIELD:
            raise CloudError(f"PointCloud2 field {name} has unknown datatype {f.datatype}")
        names.append(name)
        formats.append(endian + _NUMPY_OF_FIELD[f.datatype])
        offsets.append(f.offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                      "itemsize": msg.point_step})
    rec = np.frombuffer(msg.data, dtype=dtype, count=n)
    return np.stack([rec["x"], rec["y"], rec["z"]], axis=1).astype(np.float64)


def matrix_to_pose(t):
    """geometry_msgs/Pose of a 4x4 transform."""
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in t[:3, 3])
    q = matrix_to_quaternion(t[:3, :3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
        float(v) for v in q)
    return pose


def pose_to_matrix(pose):
    """4x4 transform of a geometry_msgs/Pose; raises ValueError on non-finite or zero quaternions."""
    p, o = pose.position, pose.orientation
    values = np.array([p.x, p.y, p.z, o.x, o.y, o.z, o.w], dtype=float)
    if not np.all(np.isfinite(values)):
        raise ValueError("pose has non-finite values")
    if np.linalg.norm(values[3:]) < 1e-6:
        raise ValueError("pose has a zero quaternion")
    return make_transform(quaternion_to_matrix(values[3:]), values[:3])


def transform_to_matrix(tf):
    """4x4 transform of a geometry_msgs/Transform."""
    t, r = tf.translation, tf.rotation
    return make_transform(quaternion_to_matrix([r.x, r.y, r.z, r.w]), [t.x, t.y, t.z])


def matrix_to_transform_stamped(t, stamp, parent, child):
    """geometry_msgs/TransformStamped parent -> child of a 4x4 transform."""
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    msg.transform = Transform()
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = (
        float(v) for v in t[:3, 3])
    q = matrix_to_quaternion(t[:3, :3])
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = (float(v) for v in q)
    return msg
