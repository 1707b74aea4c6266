"""Pinhole camera visibility of world features: frustum, range, facing and occlusion.

Frames: ``T_world_camera`` is the 4x4 pose of the camera *optical* frame in the world frame
(optical: x right, y down, z forward). Points and segments are in metres, world frame.
Occluders are vertical 2D segments with a height: walls (full height, door gaps are simply
missing segments) and box footprint edges (a box hides what lies behind it below its top).
"""
import math

import numpy as np

# A feature lying on an occluder (its own wall or box face) must not be hidden by it: the
# intersection has to be this far (m, horizontally) in front of the feature to count.
_OCCLUSION_MARGIN_M = 0.005
# Detection fades out for surfaces seen at grazing incidence (ORB needs texture that is
# not foreshortened to a line): full probability below this incidence, linear to zero at 90 deg.
_GRAZING_START_DEG = 65.0


def frustum_mask(points, T_world_camera, hfov_deg, vfov_deg, min_range_m, max_range_m):
    """Boolean mask (N,) of points (N, 3) inside the camera's field of view and range limits.

    The range is the Euclidean distance from the optical centre (m).
    """
    rot = T_world_camera[:3, :3]
    centre = T_world_camera[:3, 3]
    pc = (points - centre) @ rot  # rows: R^T (p - c), camera optical coordinates
    z = pc[:, 2]
    rng2 = np.einsum("ij,ij->i", pc, pc)
    tan_h = math.tan(math.radians(hfov_deg) / 2.0)
    tan_v = math.tan(math.radians(vfov_deg) / 2.0)
    return ((z > 1e-6) & (np.abs(pc[:, 0]) <= z * tan_h) & (np.abs(pc[:, 1]) <= z * tan_v)
            & (rng2 >= min_range_m ** 2) & (rng2 <= max_range_m ** 2))


def occluded_mask(camera_xyz, points, segments, heights):
    """Boolean mask (M,) of points (M, 3) hidden from camera_xyz (3,) by vertical segments.

    A segment (x1, y1, x2, y2) of height h hides a point when the 2D ray from the camera to the
    point crosses it (strictly before the point) at a height below h. Vectorised over M x K.
    """
    m = len(points)
    if m == 0 or len(segments) == 0:
        return np.zeros(m, dtype=bool)
    px, py = float(camera_xyz[0]), float(camera_xyz[1])
    rx = points[:, 0] - px                       # (M,)
    ry = points[:, 1] - py
    qx = segments[:, 0] - px                     # (K,)
    qy = segments[:, 1] - py
    sx = segments[:, 2] - segments[:, 0]
    sy = segments[:, 3] - segments[:, 1]
    denom = rx[:, None] * sy[None, :] - ry[:, None] * sx[None, :]   # r x s, (M, K)
    ok = np.abs(denom) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, denom, 1.0), 0.0)
    t = (qx * sy - qy * sx)[None, :] * inv                          # along the ray
    u = (qx[None, :] * ry[:, None] - qy[None, :] * rx[:, None]) * inv  # along the segment
    ray_len = np.hypot(rx, ry)
    t_max = 1.0 - _OCCLUSION_MARGIN_M / np.maximum(ray_len, 1e-9)
    hit = ok & (t > 1e-9) & (t < t_max[:, None]) & (u >= 0.0) & (u <= 1.0)
    if np.all(np.isinf(heights)):
        return hit.any(axis=1)
    z = camera_xyz[2] + t * (points[:, 2] - camera_xyz[2])[:, None]
    return (hit & (z < heights[None, :])).any(axis=1)


def facing_cosine(camera_xyz, points, normals):
    """Cosine (N,) between each feature's surface normal and the direction to the camera.

    Negative means the feature's surface faces away (its back side), which hides it. A zero
    normal marks a small object seen alike from every side: cosine 1.
    """
    v = camera_xyz[None, :] - points
    norm = np.maximum(np.linalg.norm(v, axis=1), 1e-9)
    cos = np.einsum("ij,ij->i", v, normals) / norm
    return np.where(np.any(normals != 0.0, axis=1), cos, 1.0)


class Camera:
    """A monocular pinhole camera that reports which world features it detects in a frame.

    Args:
      points, normals: (N, 3) world-frame features and their surface normals (m).
      segments, heights: occluders, (K, 4) vertical segments (m) and their heights (m).
      hfov_deg, vfov_deg: horizontal/vertical field of view (deg).
      min_range_m, max_range_m: detection range limits (m).
      detection_prob: probability that a visible, well-facing feature is detected in a frame.
      rng: numpy Generator for the per-frame detection draws.
    """

    def __init__(self, points, normals, segments, heights, hfov_deg, vfov_deg, min_range_m,
                 max_range_m, detection_prob, rng):
        self.points = np.asarray(points, dtype=float)
        self.normals = np.asarray(normals, dtype=float)
        self.segments = np.asarray(segments, dtype=float).reshape(-1, 4)
        self.heights = np.asarray(heights, dtype=float)
        self.hfov_deg = hfov_deg
        self.vfov_deg = vfov_deg
        self.min_range_m = min_range_m
        self.max_range_m = max_range_m
        self.detection_prob = detection_prob
        self._rng = rng
        self._cos_grazing = math.cos(math.radians(_GRAZING_START_DEG))

    def geometric_visible(self, T_world_camera):
        """Indices (sorted) of features in view, facing the camera and not occluded."""
        centre = T_world_camera[:3, 3]
        idx = np.flatnonzero(frustum_mask(self.points, T_world_camera, self.hfov_deg,
                                          self.vfov_deg, self.min_range_m, self.max_range_m))
        if len(idx) == 0:
            return idx
        cosines = facing_cosine(centre, self.points[idx], self.normals[idx])
        idx = idx[cosines > 0.0]
        segs, heights = self._nearby_occluders(centre)
        hidden = occluded_mask(centre, self.points[idx], segs, heights)
        return idx[~hidden]

    def detect(self, T_world_camera):
        """Indices (sorted) of features detected in one frame: visible ones, each kept with
        ``detection_prob``, fading out at grazing incidence."""
        idx = self.geometric_visible(T_world_camera)
        if len(idx) == 0:
            return idx
        cosines = facing_cosine(T_world_camera[:3, 3], self.points[idx], self.normals[idx])
        p = self.detection_prob * np.clip(cosines / self._cos_grazing, 0.0, 1.0)
        return idx[self._rng.random(len(idx)) < p]

    def _nearby_occluders(self, centre):
        """Occluders that can intersect a ray no longer than the max range."""
        if len(self.segments) == 0:
            return self.segments, self.heights
        a = self.segments[:, :2]
        ab = self.segments[:, 2:] - a
        denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
        t = np.clip(np.einsum("ij,ij->i", centre[None, :2] - a, ab) / denom, 0.0, 1.0)
        d = np.hypot(*(a + t[:, None] * ab - centre[None, :2]).T)
        keep = d <= self.max_range_m
        return self.segments[keep], self.heights[keep]
