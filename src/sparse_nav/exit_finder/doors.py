"""Door candidates from several detectors, each described by scale-free features (ROS-free).

The ``ranked`` method (see :mod:`sparse_nav.exit_finder.ranker`) scores these candidates with a
model learned on simulator rooms. No single detector finds every door: the outward notches of
:mod:`sparse_nav.exit_finder.gaps` depend on the bearing resolution (a door seen obliquely spans
two or three bearings, a near one forty), and a wall seen edge-on has no notch at all. So the
candidates are the union of

* ``notch360``, ``notch720``, ``notch180``: the notches of the surface profile at 1, 0.5 and 2
  degree bearings (:data:`NOTCH_PROFILES`), every right jamb up to :data:`NOTCH_MAX_RIGHTS`
  kept, centred by :func:`~sparse_nav.exit_finder.gaps.door_centre`;
* ``wall_gap``: gaps of door width between the points of straight walls, found by sequential
  RANSAC on the points on the surface (:func:`wall_gaps`), centred between the gap's ends.

A candidate is a segment ``a``-``b`` across the opening and a centre on it. :func:`features`
describes it by what is seen through it, its width and range against the room's, how straight
the walls on both sides run past it, what stands in front of it or behind its jambs, and how
much of the map lies past the wall line it is in (little past an outer wall's door, a whole room
past an inner door or a box's side) and how deep inside the cloud's convex hull it is, all
in cloud radii, ratios or angles, so that the description does not depend on the monocular
map's scale, position or heading; counts of points are divided by the *wall density*, the median
number of points on the surface per degree of bearing, so that it does not depend on how many
points the map holds either.
"""
import dataclasses
import warnings

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from sparse_nav.exit_finder import gaps as gapslib
from sparse_nav.exit_finder import geometry as geo
from sparse_nav.exit_finder.seed import ransac_line

# (name, bearings, bearings pooled on each side, jamb bearings) of each notch detector.
NOTCH_PROFILES = (("notch360", 360, 1, 2), ("notch720", 720, 2, 4), ("notch180", 180, 1, 1))
NOTCH_MAX_RIGHTS = 4            # right jambs tried per left jamb
WALL_LINES = 10                 # RANSAC walls looked for, one after another
WALL_BAND = 0.025               # r.u.: a point within this of a wall is on it
WALL_MIN_POINTS = 25            # a wall holds at least this many points
WALL_ITERATIONS = 200           # RANSAC hypotheses per wall
WALL_EVAL_POINTS = 3000         # hypotheses are counted on at most this many points
WALL_SIDE = 0.1                 # r.u.: a gap needs WALL_SIDE_POINTS wall points this close on
WALL_SIDE_POINTS = 5            # each side (a wall goes on past it, not a stray point)
WIDE_BEARINGS = (5, 15)         # half-windows (bearings) of the walls' median range around a door
BEYOND_MARGIN = 0.05            # share of the door's range: a point this far past its line is beyond
BEYOND_NEAR_WIDTHS = 2.0        # beyond_near_share counts points this many widths past either jamb
BEYOND_EXTENT_MIN_POINTS = 5    # beyond_extent needs this many points beyond the line (else 0)
SOURCES = tuple(p[0] for p in NOTCH_PROFILES) + ("wall_gap",)

FEATURE_NAMES = (
    "through_log",          # log(1 + points seen through the opening / wall density)
    "through_coverage",     # share of its 1-degree bearings with a surface seen through them
    "through_spread",       # 10-90 % depth spread of those points over the door's range
    "width_log",            # log(width / gap_door_width)
    "width_log_sq",         # its square: doors are about a door wide, either way
    "range_log",            # log(door range / median wall range)
    "span_share",           # bearings the opening spans, as a share of the full turn
    "through_depth_log",    # log(median range seen through / door range)
    "through_beyond",       # (median range seen through - door range) / median wall range
    "incidence",            # |sin| of the angle between the opening and the line of sight
    "jamb_angle",           # angle between the walls on either side / 90 degrees
    "jamb_offset_log",      # log(1e-3 + how far each side's wall misses the other jamb / range)
    "jamb_scatter_log",     # log(1e-3 + median distance of the left wall from the opening / range)
    "occluded_left",        # share of the points beside each jamb far behind it (a box, a wall
    "occluded_right",       # end), not a frame in a wall
    "in_front_share",       # share of the points in the opening's bearings in front of it
    "through_range_log",    # log(median range seen through / median wall range)
    "through_density_log",  # log(1 + points seen through per 1-degree bearing / wall density)
    "in_cone_log",          # log(1 + points in the opening's bearings / wall density)
    "range_vs_walls_5",     # log(door range / median wall range within 5 bearings)
    "range_vs_walls_15",    # ... within 15 bearings
    "beyond_share",         # share of the cloud beyond the opening's line, away from the viewpoint
    "beyond_surface_share",  # share of the surface's bearings beyond that line
    "beyond_near_share",    # beyond_share of the points within two widths of the opening along it
    "beyond_extent",        # 90 % distance past the line of the points beyond it / door range
    "hull_depth",           # distance from the centre to the cloud's convex hull / median range
) + tuple(f"source_{s}" for s in SOURCES) + (
    "through_vs_best",      # through_log less the largest through_log of the room's candidates
)


@dataclasses.dataclass
class Candidate:
    """A door candidate: the segment a-b across the opening and its centre (r.u.); a notch also
    keeps its jamb bearings (left, right) in its detector's profile."""

    a: np.ndarray
    b: np.ndarray
    centre: np.ndarray
    source: str
    jambs: tuple = None


def notch_config(cfg, profile_index):
    """The configuration of detector NOTCH_PROFILES[profile_index]: cfg with its bearings."""
    _, bins, pool, jamb = NOTCH_PROFILES[profile_index]
    return dataclasses.replace(cfg, gap_angle_bins=bins, gap_pool_bins=pool, gap_jamb_bins=jamb,
                               gap_max_rights=NOTCH_MAX_RIGHTS)


class Scene:
    """The cloud seen from the viewpoint: the polar coordinates of every point, the walls'
    surface profile (:func:`~sparse_nav.exit_finder.gaps.surface_profile` at the first
    detector's bearings, :func:`notch_config`) and its points, the median wall range around each
    bearing, the wall density (points on the surface per degree) and the cloud's convex hull,
    computed once for every candidate."""

    def __init__(self, q, viewpoint, cfg):
        self.q = q
        self.viewpoint = np.asarray(viewpoint, dtype=float)
        self.cfg = cfg
        self.profile_cfg = notch_config(cfg, 0)
        self.profile = gapslib.surface_profile(q, self.viewpoint, self.profile_cfg)
        rel = q - self.viewpoint
        self.radius = self.profile.radius
        self.theta = np.arctan2(rel[:, 1], rel[:, 0])
        self.unit = rel / np.maximum(self.radius, 1e-12)[:, None]
        surface = self.profile.ranges[self.profile.bearing]
        self.on_surface = np.isfinite(surface) & \
            (np.abs(self.radius - surface) <= cfg.gap_jump * surface)
        ranges = self.profile.ranges
        self.median_range = float(np.nanmedian(ranges)) if np.any(np.isfinite(ranges)) else 1.0
        n = len(ranges)
        # Points on the surface per degree, the median over the bearings that have one.
        per_bearing = np.bincount(self.profile.bearing[self.on_surface], minlength=n)
        known = np.isfinite(ranges)
        median = float(np.median(per_bearing[known])) if np.any(known) else 1.0
        self.wall_density = max(median * n / 360.0, 1e-3)
        self.surface_points = self.profile.points()[known]
        try:
            self.hull_equations = ConvexHull(q).equations
        except (QhullError, ValueError):    # no area (as geo.convex_hull): no depth to measure
            self.hull_equations = None
        self.wall_range = {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # all-NaN windows stay NaN
            for half in WIDE_BEARINGS:
                idx = (np.arange(n)[:, None] + np.arange(-half, half + 1)[None, :]) % n
                self.wall_range[half] = np.nanmedian(ranges[idx], axis=1)

    def bearing_bin(self, p):
        """The profile bearing of point p."""
        rel = np.asarray(p, dtype=float) - self.viewpoint
        return int(gapslib.bearing_bins(np.arctan2(rel[1], rel[0]), len(self.profile.angles)))


def candidates(scene, rng):
    """Every detector's candidates, in :data:`SOURCES` order."""
    out = []
    for k, (name, _, _, _) in enumerate(NOTCH_PROFILES):
        cfg = notch_config(scene.cfg, k)
        profile = scene.profile if k == 0 else \
            gapslib.surface_profile(scene.q, scene.viewpoint, cfg)
        out += notches(scene.q, profile, cfg, name)
    out += wall_gaps(scene, rng)
    return out


def notches(q, profile, cfg, source):
    """The outward notches of a surface profile (:func:`~sparse_nav.exit_finder.gaps.
    find_notches`) as doors from jamb to jamb, centred where the points seen through them pass."""
    out = []
    for left, right in gapslib.find_notches(profile, cfg):
        through = gapslib.through_mask(profile, left, right, cfg)
        out.append(Candidate(a=profile.point(left), b=profile.point(right),
                             centre=gapslib.door_centre(profile, q, left, right, through, cfg),
                             source=source, jambs=(left, right)))
    return out


def wall_gaps(scene, rng):
    """Gaps between door width bounds (``gap_min_width``, ``gap_max_width``) in straight walls:
    RANSAC walls through the points on the surface, one after another on the points left, each
    cut where two consecutive points along it lie that far apart with the wall going on past
    both ends. Found in Cartesian space, so a door seen obliquely is as wide as any other."""
    cfg = scene.cfg
    remaining = scene.q[scene.on_surface]
    out = []
    for _ in range(WALL_LINES):
        if len(remaining) < WALL_MIN_POINTS:
            break
        found = ransac_line(remaining, rng, WALL_ITERATIONS, WALL_BAND, WALL_EVAL_POINTS)
        if found is None or np.count_nonzero(found[1]) < WALL_MIN_POINTS:
            break
        line, inliers = found
        t = np.sort(line.project(remaining[inliers]))
        remaining = remaining[~inliers]
        step = np.diff(t)
        for i in np.flatnonzero((step >= cfg.gap_min_width) & (step <= cfg.gap_max_width)):
            lo, hi = t[i], t[i + 1]
            if np.count_nonzero((t >= lo - WALL_SIDE) & (t <= lo)) < WALL_SIDE_POINTS or \
                    np.count_nonzero((t >= hi) & (t <= hi + WALL_SIDE)) < WALL_SIDE_POINTS:
                continue
            a, b = line.at(lo), line.at(hi)
            out.append(Candidate(a=a, b=b, centre=0.5 * (a + b), source="wall_gap"))
    return out


def _within(theta, start, end):
    """True where the bearings theta lie on the counter-clockwise arc from start to end."""
    return ((theta - start) % (2 * np.pi)) < ((end - start) % (2 * np.pi))


def _ranges_to(scene, units, a, b):
    """Ranges from the viewpoint along the unit directions (M, 2) to the line a-b (NaN where a
    direction does not meet it ahead)."""
    ab = b - a
    denom = units[:, 0] * ab[1] - units[:, 1] * ab[0]
    diff = a - scene.viewpoint
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (diff[0] * ab[1] - diff[1] * ab[0]) / denom
    return np.where(np.isfinite(t) & (t > 0), t, np.nan)


def _oriented(scene, door):
    """(a, b, start, end, span): the door's ends ordered counter-clockwise as seen from the
    viewpoint, their bearings and the bearing span between them (rad)."""
    a, b = door.a, door.b
    start = np.arctan2(*(a - scene.viewpoint)[::-1])
    end = np.arctan2(*(b - scene.viewpoint)[::-1])
    if (end - start) % (2 * np.pi) > np.pi:
        start, end, a, b = end, start, b, a
    return a, b, start, end, (end - start) % (2 * np.pi)


def _jamb_cones(start, end, span):
    """Bearing arcs beside the opening, as wide as it and at least 3 degrees: (left, right)."""
    side = max(span, np.radians(3.0))
    return (start - side, start), (end, end + side)


def jamb_points(scene, door):
    """The points on the surface beside the door's jambs (:func:`_jamb_cones`): its walls."""
    _, _, start, end, span = _oriented(scene, door)
    cones = _jamb_cones(start, end, span)
    mask = scene.on_surface & (_within(scene.theta, *cones[0]) | _within(scene.theta, *cones[1]))
    return scene.q[mask]


def features(scene, door):
    """The feature vector of one candidate, in :data:`FEATURE_NAMES` order less the last
    (``through_vs_best``, which needs the room's other candidates: :func:`feature_matrix`)."""
    cfg, view, q = scene.cfg, scene.viewpoint, scene.q
    a, b, start, end, span = _oriented(scene, door)
    centre = door.centre
    width = float(np.hypot(*(b - a)))
    door_range = max(float(np.hypot(*(centre - view))), 1e-9)
    in_cone = _within(scene.theta, start, end)
    crossing = np.full(len(q), np.nan)
    crossing[in_cone] = _ranges_to(scene, scene.unit[in_cone], a, b)
    ahead = in_cone & np.isfinite(crossing)
    through = ahead & (scene.radius > crossing * (1.0 + cfg.gap_beyond_margin))
    in_front = ahead & (scene.radius < crossing * (1.0 - cfg.gap_beyond_margin))
    n_through, n_cone = int(np.count_nonzero(through)), int(np.count_nonzero(in_cone))
    n_bins = max(1, int(np.ceil(span / np.radians(1.0))))
    if n_through:
        k = np.minimum(((scene.theta[through] - start) % (2 * np.pi) / max(span, 1e-12) *
                        n_bins).astype(int), n_bins - 1)
        coverage = float(np.mean(np.bincount(k, minlength=n_bins) >= cfg.gap_min_surface_points))
        lo, hi = np.quantile(scene.radius[through], [0.1, 0.9])
        spread = float((hi - lo) / door_range)
        seen_range = float(np.median(scene.radius[through]))
        depth = np.log(seen_range / door_range)
        beyond = (seen_range - door_range) / scene.median_range
        through_range = np.log(seen_range / scene.median_range)
    else:
        coverage = spread = depth = beyond = through_range = 0.0
    width_log = np.log(max(width, 1e-9) / cfg.gap_door_width)
    along = (b - a) / max(width, 1e-9)
    sight = (centre - view) / door_range
    incidence = abs(float(along[0] * sight[1] - along[1] * sight[0]))
    jamb_angle, jamb_offset, jamb_scatter, occluded_left, occluded_right = _jambs(
        scene, a, b, start, end, span, door_range)
    centre_bin = scene.bearing_bin(centre)
    vs_walls = []
    for half in WIDE_BEARINGS:
        wall = scene.wall_range[half][centre_bin]
        vs_walls.append(float(np.log(door_range / wall)) if np.isfinite(wall) else 0.0)
    source = [float(door.source == s) for s in SOURCES]
    past_line = _beyond(scene, a, b, width, door_range)
    density = scene.wall_density
    return np.array([np.log1p(n_through / density), coverage, spread, width_log, width_log ** 2,
                     np.log(door_range / scene.median_range), span / (2 * np.pi), depth, beyond,
                     incidence, jamb_angle, jamb_offset, jamb_scatter, occluded_left,
                     occluded_right, np.count_nonzero(in_front) / max(n_cone, 1), through_range,
                     np.log1p(n_through / n_bins / density), np.log1p(n_cone / density)] +
                    vs_walls + past_line + [_hull_depth(scene, centre)] + source,
                    dtype=float)


def _beyond(scene, a, b, width, door_range):
    """What lies past the line through the opening, on the side away from the viewpoint:
    [beyond_share, beyond_surface_share, beyond_near_share, beyond_extent]
    (:data:`FEATURE_NAMES`)."""
    along = (b - a) / max(width, 1e-9)
    normal = np.array([-along[1], along[0]])
    if np.dot(scene.viewpoint - a, normal) > 0:
        normal = -normal
    margin = BEYOND_MARGIN * door_range
    past = (scene.q - a) @ normal
    beyond = past > margin
    t = (scene.q - a) @ along
    near = (t > -BEYOND_NEAR_WIDTHS * width) & (t < (1.0 + BEYOND_NEAR_WIDTHS) * width)
    surface = (scene.surface_points - a) @ normal > margin
    extent = float(np.quantile(past[beyond], 0.9)) / door_range \
        if np.count_nonzero(beyond) >= BEYOND_EXTENT_MIN_POINTS else 0.0
    return [float(np.mean(beyond)), float(np.mean(surface)) if len(surface) else 0.0,
            float(np.mean(beyond[near])) if np.any(near) else 0.0, extent]


def _hull_depth(scene, p):
    """Distance from point p to the boundary of the cloud's convex hull / the median wall
    range (0 outside it or without a hull)."""
    if scene.hull_equations is None:
        return 0.0
    eq = scene.hull_equations
    return max(0.0, -float(np.max(eq[:, :2] @ p + eq[:, 2]))) / scene.median_range


def _jambs(scene, a, b, start, end, span, door_range):
    """What the walls beside the opening say, from the points on the surface in the cones of
    :func:`_jamb_cones`: the angle between the two walls / 90 deg, log(1e-3 + how far each
    wall's line misses the other jamb / range), log(1e-3 + the median distance of the left
    wall's points from the opening's line / range), and per side the share of the cone's points
    far behind its wall (:func:`_occluded`)."""
    cfg = scene.cfg
    left_cone, right_cone = _jamb_cones(start, end, span)
    left = scene.on_surface & _within(scene.theta, *left_cone)
    right = scene.on_surface & _within(scene.theta, *right_cone)
    angle, offset, scatter = 1.0, 1.0, 1.0
    if np.count_nonzero(left) >= 3 and np.count_nonzero(right) >= 3:
        left_wall, right_wall = geo.Line.fit(scene.q[left]), geo.Line.fit(scene.q[right])
        angle = geo.angle_between_deg(left_wall, right_wall) / 90.0
        offset = max(abs(float(left_wall.signed(b[None])[0])),
                     abs(float(right_wall.signed(a[None])[0]))) / door_range
        if np.hypot(*(b - a)) > 0:
            scatter = float(np.median(geo.Line.through(a, b).distances(scene.q[left]))) / \
                door_range
    return (angle, float(np.log(offset + 1e-3)), float(np.log(scatter + 1e-3)),
            _occluded(scene, left, *left_cone, cfg), _occluded(scene, right, *right_cone, cfg))


def _occluded(scene, wall, start, end, cfg):
    """Share of the points in the bearings start..end lying beyond the median range of that
    cone's wall points by more than gap_jump of it (0 without wall points)."""
    if not np.any(wall):
        return 0.0
    cone = _within(scene.theta, start, end)
    total = np.count_nonzero(cone)
    far = cone & (scene.radius > np.median(scene.radius[wall]) * (1.0 + cfg.gap_jump))
    return np.count_nonzero(far) / total if total else 0.0


def feature_matrix(scene, doors):
    """(len(doors), len(FEATURE_NAMES)) features of a room's candidates."""
    if not doors:
        return np.zeros((0, len(FEATURE_NAMES)))
    x = np.array([features(scene, d) for d in doors])
    return np.column_stack([x, x[:, 0] - x[:, 0].max()])
