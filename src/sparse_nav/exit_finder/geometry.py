"""2D geometry for the exit finder: lines, polygons, perimeter samples, alpha outlines (ROS-free).

Everything works on plain float arrays in whatever planar frame the caller uses (the finder uses
its normalised frame, see :class:`sparse_nav.exit_finder.cloud.CloudFrame`). A line is a
:class:`Line` (a point and a unit direction); a polygon is an (M, 2) array of vertices in order,
closed implicitly (the last vertex connects to the first).
"""
import dataclasses
import math

import numpy as np
from scipy.spatial import ConvexHull, Delaunay, QhullError

_PARALLEL_EPS = 1e-9


@dataclasses.dataclass(frozen=True)
class Line:
    """An infinite 2D line through ``point`` with unit ``direction``."""

    point: np.ndarray
    direction: np.ndarray

    @classmethod
    def through(cls, a, b):
        """The line through a and b (distinct points)."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        d = b - a
        return cls(point=a, direction=d / np.hypot(*d))

    @classmethod
    def fit(cls, q):
        """Total least squares line of points q (N >= 2): through the mean, along the major
        principal axis."""
        centre = q.mean(axis=0)
        _, _, vt = np.linalg.svd(q - centre, full_matrices=False)
        return cls(point=centre, direction=vt[0] / np.hypot(*vt[0]))

    @property
    def normal(self):
        """Unit normal, the direction turned +90 degrees."""
        return np.array([-self.direction[1], self.direction[0]])

    def distances(self, q):
        """Unsigned distances of points q (N, 2) from the line."""
        return np.abs(self.signed(q))

    def signed(self, q):
        """Signed distances along :attr:`normal`."""
        return (np.asarray(q, dtype=float) - self.point) @ self.normal

    def project(self, q):
        """Coordinates of points q along the line (from :attr:`point`, along the direction)."""
        return (np.asarray(q, dtype=float) - self.point) @ self.direction

    def at(self, s):
        """Points at coordinates s along the line."""
        return self.point + np.multiply.outer(np.asarray(s, dtype=float), self.direction)


def angle_between_deg(a, b):
    """Angle between two lines in [0, 90] degrees."""
    c = abs(float(np.dot(a.direction, b.direction)))
    return math.degrees(math.acos(min(1.0, c)))


def intersect(a, b):
    """Intersection point of two lines, None when they are parallel."""
    cross = a.direction[0] * b.direction[1] - a.direction[1] * b.direction[0]
    if abs(cross) < _PARALLEL_EPS:
        return None
    diff = b.point - a.point
    t = (diff[0] * b.direction[1] - diff[1] * b.direction[0]) / cross
    return a.point + t * a.direction


def signed_area(poly):
    """Signed area of a polygon (positive when counter-clockwise)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def points_in_polygon(q, poly):
    """Boolean mask: points q (N, 2) inside the polygon (even-odd rule)."""
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    x, y = q[:, 0:1], q[:, 1:2]
    xs, ys = poly[None, :, 0], poly[None, :, 1]
    xj, yj = np.roll(xs, 1, axis=1), np.roll(ys, 1, axis=1)
    dy = np.where(yj == ys, 1e-300, yj - ys)
    crosses = ((ys > y) != (yj > y)) & (x < (xj - xs) * (y - ys) / dy + xs)
    return np.count_nonzero(crosses, axis=1) % 2 == 1


def segment_distances(q, seg_a, seg_b):
    """Distances (N, K) from points q (N, 2) to segments seg_a[k] -> seg_b[k] (K, 2)."""
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    ab = seg_b - seg_a
    ap = q[:, None, :] - seg_a[None, :, :]
    denom = np.maximum(np.sum(ab * ab, axis=1), 1e-300)
    t = np.clip(np.sum(ap * ab[None], axis=2) / denom[None], 0.0, 1.0)
    d = ap - t[:, :, None] * ab[None]
    return np.hypot(d[..., 0], d[..., 1])


def boundary_distances(q, poly):
    """Distance (N,) from each point to the polygon's boundary, and the nearest side (N,)."""
    d = segment_distances(q, poly, np.roll(poly, -1, axis=0))
    side = np.argmin(d, axis=1)
    return d[np.arange(len(d)), side], side


def _segments_intersect(p1, p2, p3, p4):
    """True if closed segments p1-p2 and p3-p4 properly cross or touch."""
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    d1, d2 = orient(p3, p4, p1), orient(p3, p4, p2)
    d3, d4 = orient(p1, p2, p3), orient(p1, p2, p4)
    return (d1 * d2 <= 0) and (d3 * d4 <= 0)


def is_simple(poly):
    """True if no two non-adjacent sides of the polygon meet and no side has zero length."""
    n = len(poly)
    if n < 3:
        return False
    sides = np.roll(poly, -1, axis=0) - poly
    if np.any(np.hypot(sides[:, 0], sides[:, 1]) <= 1e-12):
        return False
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # adjacent through the closing side
            if _segments_intersect(poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]):
                return False
    return True


def perimeter_samples(poly, n):
    """Seed step 7: n points evenly spaced along the closed perimeter.

    Returns (samples (n, 2), side (n,)): sample k lies at arc length (k + 0.5) * L / n from the
    first vertex, on side ``side[k]`` (from vertex side[k] to vertex side[k] + 1).
    """
    nxt = np.roll(poly, -1, axis=0)
    lengths = np.hypot(*(nxt - poly).T)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    s = (np.arange(n) + 0.5) * cum[-1] / n
    side = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(poly) - 1)
    t = (s - cum[side]) / np.maximum(lengths[side], 1e-300)
    samples = poly[side] + t[:, None] * (nxt[side] - poly[side])
    return samples, side


def convex_hull(q):
    """Counter-clockwise convex hull vertices of q, or None when q spans no area."""
    try:
        hull = ConvexHull(q)
    except (QhullError, ValueError):
        return None
    return q[hull.vertices]


def simplify_closed(poly, tolerance):
    """Douglas-Peucker simplification of a closed polygon (keeps its two farthest vertices)."""
    n = len(poly)
    if n <= 3:
        return poly
    start = int(np.argmax(np.hypot(*(poly - poly[0]).T)))
    far = int(np.argmax(np.hypot(*(poly - poly[start]).T)))
    order = np.roll(np.arange(n), -start)
    split = int(np.flatnonzero(order == far)[0])
    first = _douglas_peucker(poly[order[:split + 1]], tolerance)
    second = _douglas_peucker(poly[np.concatenate([order[split:], order[:1]])], tolerance)
    out = np.vstack([first[:-1], second[:-1]])
    return out if len(out) >= 3 else poly


def _douglas_peucker(chain, tolerance):
    """Douglas-Peucker on an open chain (first and last kept), iterative."""
    keep = np.zeros(len(chain), dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(chain) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = chain[i], chain[j]
        ab = b - a
        length = np.hypot(*ab)
        mid = chain[i + 1:j]
        if length <= 1e-300:
            d = np.hypot(*(mid - a).T)
        else:
            d = np.abs((mid - a) @ np.array([-ab[1], ab[0]])) / length
        k = int(np.argmax(d))
        if d[k] > tolerance:
            keep[i + 1 + k] = True
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return chain[keep]


def alpha_outline(q, alpha):
    """Outer boundary of the alpha shape of points q: the Delaunay triangles whose circumradius
    is below ``alpha`` are kept, and the boundary loop enclosing the largest area is returned as
    a counter-clockwise polygon (M, 2); None when no triangle survives."""
    if len(q) < 3:
        return None
    try:
        tri = Delaunay(q)
    except (QhullError, ValueError):
        return None
    p = q[tri.simplices]
    a = np.hypot(*(p[:, 1] - p[:, 2]).T)
    b = np.hypot(*(p[:, 0] - p[:, 2]).T)
    c = np.hypot(*(p[:, 0] - p[:, 1]).T)
    cross = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - \
        (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
    area2 = np.abs(cross)
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = a * b * c / (2.0 * area2)
    kept = tri.simplices[np.isfinite(radius) & (radius < alpha)]
    if len(kept) == 0:
        return None
    edges = np.sort(np.vstack([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = uniq[counts == 1]
    loops = _edge_loops(boundary)
    best = None
    for loop in loops:
        poly = q[loop]
        area = abs(signed_area(poly))
        if best is None or area > best[0]:
            best = (area, poly)
    if best is None or best[0] <= 0:
        return None
    poly = best[1]
    return poly if signed_area(poly) > 0 else poly[::-1]


def _edge_loops(edges):
    """Closed vertex loops from undirected boundary edges (a vertex may join several loops)."""
    adjacency = {}
    for k, (i, j) in enumerate(edges):
        adjacency.setdefault(int(i), []).append((int(j), k))
        adjacency.setdefault(int(j), []).append((int(i), k))
    used = np.zeros(len(edges), dtype=bool)
    loops = []
    for k0 in range(len(edges)):
        if used[k0]:
            continue
        used[k0] = True
        start, current = int(edges[k0][0]), int(edges[k0][1])
        loop = [start]
        while current != start:
            loop.append(current)
            step = next(((v, k) for v, k in adjacency[current] if not used[k]), None)
            if step is None:
                break
            used[step[1]] = True
            current = step[0]
        if current == start and len(loop) >= 3:
            loops.append(loop)
    return loops


def reflex_vertices(poly):
    """Indices of the reflex (concave) vertices of a simple polygon, any orientation."""
    prev = np.roll(poly, 1, axis=0)
    nxt = np.roll(poly, -1, axis=0)
    d1, d2 = poly - prev, nxt - poly
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    orientation = 1.0 if signed_area(poly) > 0 else -1.0
    return np.flatnonzero(cross * orientation < 0)


def ray_crossings(origin, targets, seg_a, seg_b):
    """For rays origin -> targets[i], the ray parameter t (0 at origin, 1 at the target) and the
    segment parameter u (0 at seg_a, 1 at seg_b) where each ray meets each segment's line.

    Returns (t, u), both (N, K); entries are NaN where a ray is parallel to a segment.
    """
    r = np.asarray(targets, dtype=float) - origin           # (N, 2)
    s = seg_b - seg_a                                       # (K, 2)
    denom = r[:, None, 0] * s[None, :, 1] - r[:, None, 1] * s[None, :, 0]
    diff = seg_a[None, :, :] - origin                       # (1, K, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (diff[..., 0] * s[None, :, 1] - diff[..., 1] * s[None, :, 0]) / denom
        u = (diff[..., 0] * r[:, None, 1] - diff[..., 1] * r[:, None, 0]) / denom
    bad = np.abs(denom) < 1e-300
    t[bad] = np.nan
    u[bad] = np.nan
    return t, u
