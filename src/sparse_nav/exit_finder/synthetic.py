"""Small synthetic ORB-SLAM-like room clouds with known exits, for tests and demos (ROS-free).

A room is a polygon of walls (metres, horizontal x, y) with door gaps; a camera at ``viewpoint``
sees the walls' texture as points with depth noise along the line of sight (as a monocular map
does), and through each door a textured wall some way beyond it. No occlusion is modelled, so
keep the room visible from the viewpoint (convex, or nearly).
"""
import dataclasses

import numpy as np


@dataclasses.dataclass
class Door:
    """A door gap in wall ``side`` (from vertex side to side + 1), centred ``at_m`` from its start,
    ``width_m`` wide; the camera sees a wall ``beyond_m`` behind it."""

    side: int
    at_m: float
    width_m: float = 1.0
    beyond_m: float = 2.0


def room_cloud(outline, doors=(), viewpoint=(0.0, 0.0), points_per_m=120.0, noise=0.02,
               clutter=0, outliers=0, seed=0):
    """Horizontal points (N, 2) of a room and the door centres (K, 2), both in metres.

    Args:
        outline: (M, 2) wall polygon vertices in order.
        doors: :class:`Door` gaps.
        viewpoint: (2,) where the camera stood.
        points_per_m: wall points per metre of wall.
        noise: relative depth noise (sigma / range) along the line of sight.
        clutter: points scattered inside the room (floor, furniture).
        outliers: points scattered anywhere up to twice the room's size.
        seed: numpy Generator seed.
    """
    rng = np.random.default_rng(seed)
    poly = np.asarray(outline, dtype=float)
    view = np.asarray(viewpoint, dtype=float)
    pts, centres = [], []
    for k in range(len(poly)):
        a, b = poly[k], poly[(k + 1) % len(poly)]
        length = float(np.hypot(*(b - a)))
        d = (b - a) / length
        s = rng.uniform(0.0, length, int(points_per_m * length))
        keep = np.ones(len(s), dtype=bool)
        for door in doors:
            if door.side == k:
                keep &= np.abs(s - door.at_m) > door.width_m / 2.0
        pts.append(a + s[keep, None] * d)
    for door in doors:
        a, b = poly[door.side], poly[(door.side + 1) % len(poly)]
        d = (b - a) / np.hypot(*(b - a))
        centre = a + door.at_m * d
        centres.append(centre)
        # The wall beyond, parallel to the door, on the side away from the viewpoint.
        normal = np.array([-d[1], d[0]])
        if np.dot(centre - view, normal) < 0:
            normal = -normal
        far_a = centre + door.beyond_m * normal - 3.0 * d
        s = rng.uniform(0.0, 6.0, int(points_per_m * 6.0))
        beyond = far_a + s[:, None] * d
        # Only what the camera sees through the gap.
        t = np.dot(centre - view, normal) / np.maximum((beyond - view) @ normal, 1e-12)
        cross = view + t[:, None] * (beyond - view)
        pts.append(beyond[np.abs((cross - centre) @ d) < door.width_m / 2.0])
    wall = np.vstack(pts)
    # Depth noise along the line of sight.
    rel = wall - view
    wall = view + rel * (1.0 + noise * rng.standard_normal(len(rel)))[:, None]
    extra = []
    if clutter:
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        cand = rng.uniform(lo, hi, (clutter * 4, 2))
        extra.append(cand[_inside(cand, poly)][:clutter])
    if outliers:
        centre, size = poly.mean(axis=0), np.ptp(poly, axis=0).max()
        extra.append(centre + rng.uniform(-size, size, (outliers, 2)))
    return np.vstack([wall] + extra), np.array(centres).reshape(-1, 2)


def to_orbslam(xy, height_m=(0.2, 2.2), seed=0):
    """(N, 2) horizontal points -> (N, 3) in ORB-SLAM's camera convention (x right, y down,
    z forward), so that ``up_axis='-y'`` gives back xy as (x, z); heights are random."""
    rng = np.random.default_rng(seed)
    xy = np.asarray(xy, dtype=float)
    return np.column_stack([xy[:, 0], -rng.uniform(*height_m, len(xy)), xy[:, 1]])


def _inside(q, poly):
    x, y = q[:, 0:1], q[:, 1:2]
    xs, ys = poly[None, :, 0], poly[None, :, 1]
    xj, yj = np.roll(xs, 1, axis=1), np.roll(ys, 1, axis=1)
    dy = np.where(yj == ys, 1e-300, yj - ys)
    return np.count_nonzero(((ys > y) != (yj > y)) & (x < (xj - xs) * (y - ys) / dy + xs),
                            axis=1) % 2 == 1
