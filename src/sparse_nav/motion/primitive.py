"""Seed 000's navigation primitive and a look-ahead path follower built on it (ROS-free).

Seed 000: with S the robot, P a point it looks at (S + heading) and T the target, the angle to
turn is arccos(SP . ST / (|SP| |ST|)) and the sign of the cross product SP x ST says which way:
positive turns counter-clockwise. Poses are (x, y, yaw) in the map frame (m, rad, REP-103).
"""
import dataclasses
import math

import numpy as np


def signed_angle(direction, to_target):
    """Angle (rad) from ``direction`` to ``to_target`` (2D): |angle| by the dot product, its sign
    (counter-clockwise positive) by the cross product. Equal to seed 001's atan2(det, dot)."""
    ax, ay = float(direction[0]), float(direction[1])
    bx, by = float(to_target[0]), float(to_target[1])
    na, nb = math.hypot(ax, ay), math.hypot(bx, by)
    if not (na > 1e-12 and nb > 1e-12):
        raise ValueError("signed_angle needs two non-zero vectors")
    cos_theta = max(-1.0, min(1.0, (ax * bx + ay * by) / (na * nb)))
    theta = math.acos(cos_theta)
    return theta if ax * by - ay * bx >= 0.0 else -theta


@dataclasses.dataclass
class Target:
    """Where the follower heads now."""

    point: np.ndarray          # look-ahead point (m, map frame)
    heading_error: float       # rad, counter-clockwise positive
    distance: float            # m from the robot to the look-ahead point
    remaining_m: float         # m along the path from the robot's projection to the end
    to_end_m: float            # m straight from the robot to the last point
    is_end: bool               # the look-ahead point is the path's last point
    reached: bool              # within goal_tolerance_m of the last point


class PathFollower:
    """Follows a 2D polyline with a look-ahead point; progress along it never goes backwards.

    The robot is projected onto the path within a window ahead of its previous progress (a path
    that passes near itself cannot make it skip a loop), and the look-ahead point lies
    ``lookahead_m`` further along the path from that projection. A path republished unchanged
    keeps the progress; a new one is first projected over its whole length.
    """

    def __init__(self, lookahead_m, goal_tolerance_m):
        if not lookahead_m > 0 or not goal_tolerance_m > 0:
            raise ValueError("lookahead_m and goal_tolerance_m must be > 0")
        self.lookahead_m = lookahead_m
        self.goal_tolerance_m = goal_tolerance_m
        self.points = None
        self._cum = None
        self._progress_m = 0.0
        self._global_projection = True
        self._shift = None           # (centre xy, radius_m, offset_m): see shift()

    def set_path(self, points):
        """Follow ``points`` (N, 2) m from its start; returns False when it is the path already
        followed (republished), True for a new one. Raises ValueError if malformed."""
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
            raise ValueError(f"path must be (N >= 1, 2), got shape {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("path contains NaN or Inf")
        keep = np.concatenate([[True], np.any(np.abs(np.diff(pts, axis=0)) > 1e-9, axis=1)])
        pts = pts[keep]
        if self.points is not None and pts.shape == self.points.shape \
                and np.allclose(pts, self.points, rtol=0.0, atol=1e-6):
            return False   # the same path republished: keep the progress along it
        self.points = pts
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        self._cum = np.concatenate([[0.0], np.cumsum(seg)])
        self._progress_m = 0.0
        # A new path (a replan) may start behind the robot: the first projection searches it all.
        self._global_projection = True
        return True

    def clear(self):
        self.points = None

    def shift(self, centre_xy, radius_m, offset_m):
        """Aim ``offset_m`` to the left of the path (negative: right) wherever the look-ahead
        point lies within ``radius_m`` of ``centre_xy``. Anchored in the map rather than on one
        path, so a replanned path around the same spot is shifted too; ``offset_m`` 0 ends it."""
        self._shift = None if offset_m == 0 else (np.asarray(centre_xy, float), radius_m, offset_m)

    def side_of(self, xy):
        """Which side of the path the robot at ``xy`` has strayed to or the path bends toward
        (+1 left, -1 right, 0 neither): the side a corner-cutting robot meets first."""
        if self.points is None or len(self.points) < 2:
            return 0
        s = self._progress_m
        here = self._point_at(s)
        tangent = self._tangent_at(s)
        lateral = float(tangent[0] * (xy[1] - here[1]) - tangent[1] * (xy[0] - here[0]))
        if abs(lateral) > 0.03:
            return 1 if lateral > 0 else -1
        before = self._tangent_at(s - self.lookahead_m)
        after = self._tangent_at(s + self.lookahead_m)
        bend = float(before[0] * after[1] - before[1] * after[0])
        if abs(bend) > math.sin(math.radians(10.0)):
            return 1 if bend > 0 else -1
        return 0

    def _tangent_at(self, s):
        i, _ = self._segment_at(s)
        d = self.points[i + 1] - self.points[i]
        return d / np.linalg.norm(d)

    @property
    def length_m(self):
        return float(self._cum[-1]) if self.points is not None else 0.0

    def _segment_at(self, s):
        """(segment index, fraction along it) of arc length ``s``, clamped to the path."""
        s = min(max(s, 0.0), self._cum[-1])
        i = int(np.searchsorted(self._cum, s, side="right")) - 1
        i = min(max(i, 0), len(self.points) - 2)
        span = self._cum[i + 1] - self._cum[i]
        return i, 0.0 if span <= 0 else (s - self._cum[i]) / span

    def _point_at(self, s):
        i, t = self._segment_at(s)
        return self.points[i] + t * (self.points[i + 1] - self.points[i])

    def _project(self, xy):
        """Arc length of the path point nearest ``xy`` within the window ahead of the progress."""
        window_end = self._progress_m + max(2.0 * self.lookahead_m, 1.0)
        if self._global_projection:
            window_end = self._cum[-1]
            self._global_projection = False
        best_s, best_d = self._progress_m, math.inf
        for i in range(len(self.points) - 1):
            if self._cum[i + 1] < self._progress_m or self._cum[i] > window_end:
                continue
            a, b = self.points[i], self.points[i + 1]
            ab = b - a
            t = float(np.clip(np.dot(xy - a, ab) / np.dot(ab, ab), 0.0, 1.0))
            s = self._cum[i] + t * (self._cum[i + 1] - self._cum[i])
            s = min(max(s, self._progress_m), window_end)
            d = float(np.linalg.norm(self._point_at(s) - xy))
            if d < best_d:
                best_s, best_d = s, d
        return best_s

    def target(self, x, y, yaw):
        """The Target for a robot at (x, y) heading ``yaw``; None without a path."""
        if self.points is None:
            return None
        xy = np.array([x, y], dtype=float)
        end = self.points[-1]
        to_end = float(np.linalg.norm(end - xy))
        if len(self.points) > 1:
            self._progress_m = self._project(xy)
        remaining = self.length_m - self._progress_m
        if len(self.points) == 1 or to_end <= self.lookahead_m:
            point, is_end = end, True
        else:
            s_ahead = self._progress_m + self.lookahead_m
            point = self._point_at(s_ahead)
            is_end = s_ahead >= self.length_m
            if self._shift is not None and not is_end:
                centre, radius, offset = self._shift
                if np.linalg.norm(point - centre) <= radius:
                    t = self._tangent_at(s_ahead)
                    point = point + offset * np.array([-t[1], t[0]])
        delta = point - xy
        distance = float(np.linalg.norm(delta))
        reached = to_end <= self.goal_tolerance_m and remaining <= self.lookahead_m
        heading_error = 0.0
        if distance > 1e-9:
            heading_error = signed_angle((math.cos(yaw), math.sin(yaw)), delta)
        return Target(point, heading_error, distance, remaining, to_end, is_end, reached)
