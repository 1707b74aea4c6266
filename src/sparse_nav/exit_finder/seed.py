"""The exit finder of seed 000, steps 4-8, and its alternatives (ROS-free).

Every function works on normalised planar points (cloud radii, see
:class:`sparse_nav.exit_finder.cloud.CloudFrame`) and takes its thresholds from an
:class:`~sparse_nav.exit_finder.config.ExitFinderConfig`.

Seed steps: (4) six RANSAC lines, each found on the points left after removing the points near
the lines before it; then the points are restored to the IPCL output for everything that follows;
(5) a score per line (RPCL of its near points by default), the best four kept; (6) the four lines,
taken in angular order around the cloud centre, intersect into a quadrilateral; (7) evenly spaced
perimeter samples, of which those with too many cloud points near them are dropped; (8) the
samples left are counted per side, and the corner whose two sides sum highest is the exit.
"""
import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from sparse_nav.exit_finder import cloud as cloudlib
from sparse_nav.exit_finder import geometry as geo
from sparse_nav.exit_finder.result import ExitFinderError


@dataclasses.dataclass
class Room:
    """The seed's room model in normalised coordinates.

    Attributes:
        lines: the lines found by RANSAC (in the order found).
        scores: their scores (seed step 5).
        near: (n_lines, N) bool, the IPCL points near each line.
        sides: indices into ``lines`` of the four room sides, in angular order; side i of
            ``corners`` (vertex i -> vertex i+1) lies on line ``sides[i]``.
        corners: (4, 2) quadrilateral vertices, vertex i = sides[i-1] x sides[i].
        centre: (2,) centre the sides were ordered around (mean of the IPCL points).
    """

    lines: list
    scores: np.ndarray
    near: np.ndarray
    sides: list
    corners: np.ndarray
    centre: np.ndarray


# ------------------------------------------------------------------------------ step 4: RANSAC


def ransac_line(q, rng, iterations, near_dist, max_eval_points=None, refit=True):
    """RANSAC line: of ``iterations`` lines through two random points, the one with the most
    points within ``near_dist``.

    Hypotheses are counted on at most ``max_eval_points`` points drawn at random (the full set
    when smaller), which keeps a 20k-point cloud fast; the winner's inliers are then taken from
    all of q. With ``refit`` the winner is refitted by least squares to its inliers and the refit
    kept if it has at least as many.

    Returns:
        (Line, inlier mask over q), or None when q has no two distinct points.
    """
    n = len(q)
    if n < 2:
        return None
    evaluate = q
    if max_eval_points is not None and n > max_eval_points:
        evaluate = q[rng.choice(n, size=max_eval_points, replace=False)]
    i = rng.integers(n, size=iterations)
    j = rng.integers(n, size=iterations)
    a, b = q[i], q[j]
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    valid = length > 1e-12
    if not valid.any():
        return None
    a, d, length = a[valid], d[valid], length[valid]
    normals = np.column_stack([-d[:, 1], d[:, 0]]) / length[:, None]
    dist = np.abs(evaluate @ normals.T - np.sum(a * normals, axis=1))
    best = int(np.argmax(np.count_nonzero(dist <= near_dist, axis=0)))
    line = geo.Line(point=a[best], direction=d[best] / length[best])
    inliers = line.distances(q) <= near_dist
    if refit and np.count_nonzero(inliers) >= 2:
        fitted = geo.Line.fit(q[inliers])
        fitted_inliers = fitted.distances(q) <= near_dist
        if np.count_nonzero(fitted_inliers) >= np.count_nonzero(inliers):
            line, inliers = fitted, fitted_inliers
    return line, inliers


def sequential_lines(q, n_lines, rng, iterations, near_dist, max_eval_points=None, refit=True):
    """Seed step 4: ``n_lines`` RANSAC lines, each on the points left after removing the points
    near the lines found before it. The caller keeps q itself: that is the seed's "restore to
    the points from the stage before" for the steps that follow.

    Returns the lines found (fewer when the points run out).
    """
    remaining = q
    lines = []
    for _ in range(n_lines):
        found = ransac_line(remaining, rng, iterations, near_dist, max_eval_points, refit)
        if found is None:
            break
        line, inliers = found
        lines.append(line)
        remaining = remaining[~inliers]
    return lines


# ------------------------------------------------------------------------------ step 5: scores


def line_score(near_points, line, kind, rpcl_radius=0.02, rpcl_min_neighbours=8):
    """Seed step 5: the score of one line from the points near it.

    ``"rpcl"`` (the seed's): the number of near points that RPCL keeps, i.e. that have fewer than
    ``rpcl_min_neighbours`` other near points within ``rpcl_radius``: points spread along a wall
    count, a dense blob the line merely crosses does not. ``"count"``: the number of near points.
    ``"extent"``: the distance between the two furthest near points, measured along the line
    (they all lie within the near distance of it).
    """
    if kind == "count":
        return float(len(near_points))
    if kind == "extent":
        if len(near_points) < 2:
            return 0.0
        s = line.project(near_points)
        return float(s.max() - s.min())
    if kind == "rpcl":
        return float(len(cloudlib.rpcl(near_points, rpcl_radius, rpcl_min_neighbours)))
    raise ValueError(f"unknown line score {kind!r}")


def score_lines(q, lines, cfg):
    """Scores (n_lines,) and near masks (n_lines, N) of lines over the restored points q."""
    near = np.array([line.distances(q) <= cfg.line_near_dist for line in lines],
                    dtype=bool).reshape(len(lines), len(q))
    scores = np.array([line_score(q[m], line, cfg.line_score, cfg.rpcl_radius,
                                  cfg.rpcl_min_neighbours) for line, m in zip(lines, near)])
    return scores, near


def anchor(q, line, near_mask):
    """A point on the line where its near points are: their median coordinate along it."""
    if np.any(near_mask):
        return line.at(float(np.median(line.project(q[near_mask]))))
    return line.point


def best_lines(q, lines, scores, near, cfg, count=4):
    """Indices of the ``count`` best lines by score (ties: found first).

    With ``cfg.distinct_lines`` a line is skipped when a better one already chosen is within
    ``distinct_angle_deg`` of it and passes within ``distinct_offset`` of its anchor: the two
    sides of a thick wall are one wall.
    """
    order = sorted(range(len(lines)), key=lambda k: (-scores[k], k))
    chosen = []
    for k in order:
        if cfg.distinct_lines:
            here = anchor(q, lines[k], near[k])
            if any(geo.angle_between_deg(lines[k], lines[c]) < cfg.distinct_angle_deg and
                   lines[c].distances(here[None])[0] < cfg.distinct_offset for c in chosen):
                continue
        chosen.append(k)
        if len(chosen) == count:
            break
    return chosen


# ------------------------------------------------------------------------ step 6: quadrilateral


def polygon_from_lines(q, lines, near, indices, centre, cfg):
    """Seed step 6: the lines ``indices`` in angular order of their anchors around ``centre``,
    each intersected with the next.

    Returns (sides in angular order, corners (k, 2)); vertex i = sides[i-1] x sides[i].

    Raises:
        ExitFinderError("no_room_shape"): neighbouring lines (nearly) parallel, a corner too far
            from the centre, a self-intersecting or tiny outline.
    """
    anchors = np.array([anchor(q, lines[k], near[k]) for k in indices])
    angles = np.arctan2(anchors[:, 1] - centre[1], anchors[:, 0] - centre[0])
    sides = [indices[i] for i in np.argsort(angles, kind="stable")]
    corners = []
    for i in range(len(sides)):
        a, b = lines[sides[i - 1]], lines[sides[i]]
        angle = geo.angle_between_deg(a, b)
        if angle < cfg.min_corner_angle_deg:
            raise ExitFinderError("no_room_shape", f"neighbouring room sides are nearly "
                                                   f"parallel ({angle:.1f} deg < "
                                                   f"{cfg.min_corner_angle_deg} deg)")
        corner = geo.intersect(a, b)
        if corner is None or np.hypot(*(corner - centre)) > cfg.max_corner_dist:
            raise ExitFinderError("no_room_shape", "a room corner lies implausibly far from the "
                                                   "cloud")
        corners.append(corner)
    corners = np.array(corners)
    if not geo.is_simple(corners):
        raise ExitFinderError("no_room_shape", "the room sides cross each other (self-"
                                               "intersecting outline)")
    if abs(geo.signed_area(corners)) < cfg.min_room_area:
        raise ExitFinderError("no_room_shape", f"the room outline is too small (area "
                                               f"{abs(geo.signed_area(corners)):.3g} r.u.^2)")
    return sides, corners


def fit_room(q, cfg, rng):
    """Seed steps 4-6 on the IPCL points q: lines, scores, best four, quadrilateral."""
    lines = sequential_lines(q, cfg.ransac_lines, rng, cfg.ransac_iterations,
                             cfg.line_near_dist, cfg.ransac_max_eval_points, cfg.ransac_refit)
    if len(lines) < 4:
        raise ExitFinderError("no_room_shape", f"only {len(lines)} lines found; a room needs 4")
    scores, near = score_lines(q, lines, cfg)
    chosen = best_lines(q, lines, scores, near, cfg, 4)
    if len(chosen) < 4:
        raise ExitFinderError("no_room_shape", f"only {len(chosen)} distinct walls among "
                                               f"{len(lines)} lines; a room needs 4")
    centre = q.mean(axis=0)
    sides, corners = polygon_from_lines(q, lines, near, chosen, centre, cfg)
    return Room(lines=lines, scores=scores, near=near, sides=sides, corners=corners,
                centre=centre)


# --------------------------------------------------------------------- steps 7-8: the exit corner


def empty_samples(q, poly, cfg):
    """Seed step 7: perimeter samples and whether each is kept (few cloud points near it).

    Returns (samples (n, 2), side (n,), kept (n,) bool).
    """
    samples, side = geo.perimeter_samples(poly, cfg.perimeter_samples)
    if len(q):
        counts = np.asarray(cKDTree(q).query_ball_point(samples, r=cfg.sample_radius,
                                                        return_length=True))
    else:
        counts = np.zeros(len(samples), dtype=int)
    return samples, side, counts <= cfg.sample_max_points


def corner_sums(side, kept, n_sides):
    """Seed step 8: kept samples per side, and per corner the sum of its two sides
    (vertex i joins sides i-1 and i)."""
    per_side = np.bincount(side[kept], minlength=n_sides)
    return per_side, per_side + np.roll(per_side, 1)


def seed_exit(q, room, cfg):
    """Steps 7-8 on a fitted room: corners ranked by their sum, best first.

    Returns (exits [(x, y, score)], details): score = the corner's sum / number of samples, the
    share of the perimeter found empty along the corner's two sides. Only corners with a
    positive sum are exits.
    """
    samples, side, kept = empty_samples(q, room.corners, cfg)
    per_side, sums = corner_sums(side, kept, len(room.corners))
    order = sorted(range(len(sums)), key=lambda i: (-sums[i], i))
    exits = [(float(room.corners[i][0]), float(room.corners[i][1]),
              float(sums[i]) / cfg.perimeter_samples) for i in order if sums[i] > 0]
    best = order[0]
    lines_at_exit = [room.sides[best - 1], room.sides[best]]
    on_lines = np.any(room.near[lines_at_exit], axis=0)
    details = {"samples": samples, "samples_kept": kept, "per_side": per_side,
               "line_points": q[on_lines]}
    return exits, details


# --------------------------------------------------------------------------- seed alternatives


def farthest_corner(q, room):
    """Seed alternative "by distance": corners ranked by distance from the room centre (the mean
    of the IPCL points; a recessed exit has fewer points, so the centre moves away from it).
    Score = the corner's share of the summed corner distances."""
    d = np.hypot(*(room.corners - q.mean(axis=0)).T)
    order = np.argsort(-d, kind="stable")
    total = float(d.sum())
    return [(float(room.corners[i][0]), float(room.corners[i][1]), float(d[i]) / total)
            for i in order]


def outside_points(q, poly, margin):
    """Points outside the polygon and farther than ``margin`` from its sides."""
    dist, _ = geo.boundary_distances(q, poly)
    return q[~geo.points_in_polygon(q, poly) & (dist > margin)]


def dbscan_exits(q, room, cfg):
    """Seed alternative "DBSCAN": the points inside the room or on its walls are removed, DBSCAN
    clusters the rest, and the cluster centres are the exits, largest cluster first (score = its
    share of the outside points)."""
    from sklearn.cluster import DBSCAN  # imported here: only this method needs scikit-learn

    outside = outside_points(q, room.corners, cfg.outside_margin)
    if len(outside) < cfg.dbscan_min_samples:
        return [], outside
    labels = DBSCAN(eps=cfg.dbscan_eps, min_samples=cfg.dbscan_min_samples).fit(outside).labels_
    clusters = [outside[labels == k] for k in range(labels.max() + 1)]
    clusters.sort(key=len, reverse=True)
    exits = [(float(c[:, 0].mean()), float(c[:, 1].mean()), len(c) / len(outside))
             for c in clusters]
    return exits, outside


def concave_vertices(q, cfg):
    """Seed alternative "by angles": the reflex vertices of the cloud's alpha outline (simplified
    by Douglas-Peucker), deepest first; depth = distance from the vertex to the boundary of the
    outline's convex hull. Score = the vertex's share of the summed depths.

    Returns (exits, outline polygon or None).
    """
    outline = geo.alpha_outline(q, cfg.alpha_radius)
    if outline is None:
        return [], None
    outline = geo.simplify_closed(outline, cfg.outline_simplify)
    if len(outline) < 4:
        return [], outline
    hull = geo.convex_hull(outline)
    if hull is None:
        return [], outline
    reflex = geo.reflex_vertices(outline)
    if len(reflex) == 0:
        return [], outline
    depth, _ = geo.boundary_distances(outline[reflex], hull)
    keep = depth >= cfg.min_concave_depth
    reflex, depth = reflex[keep], depth[keep]
    if len(reflex) == 0:
        return [], outline
    order = np.argsort(-depth, kind="stable")
    total = float(depth.sum())
    return [(float(outline[reflex[i]][0]), float(outline[reflex[i]][1]), float(depth[i]) / total)
            for i in order], outline
