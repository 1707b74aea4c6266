"""Door gaps anywhere on a room outline of any shape, confirmed by what is seen through them
(ROS-free).

Beyond seed 000, which assumes a four-sided room with its exit recessed at a corner. A monocular
map of a room is made from (nearly) one place, and its depth noise runs along the lines of sight,
so walls come out thick in range but sharp in bearing. The method therefore looks at the cloud in
bearing around the *viewpoint* ``c``, where the map was seen from: given by the caller, or the
input's origin (an ORB-SLAM map's first camera pose) when it lies inside the cloud, or estimated
as the place around which the fewest points hide behind the nearest surface
(:func:`estimate_viewpoint`), or the mean of the points (``gap_viewpoint``).

1. Surface profile: for each of ``gap_angle_bins`` bearings (pooled over ``gap_pool_bins`` on
   each side) a histogram of log-range, smoothed; the *surface* of a bearing is the nearest peak
   holding at least ``gap_surface_share`` of the bearing's highest peak and about
   ``gap_min_surface_points`` points; bearings without one are *unknown* (a blank wall, nothing
   mapped). Log-range bins make the noise band of every wall equally wide in bins.
2. Doors are outward notches of that profile (:func:`find_notches`): after a *jamb* bearing L
   that ends a wall, the surface leaves the wall's extension (by more than ``gap_jump`` of the
   range) or becomes unknown, and at a later jamb bearing R it jumps back; the bearings in
   between lie beyond the straight *bridge* from the surface point of L to that of R, or are
   unknown. The bridge is the door (``gap_min_width`` to ``gap_max_width`` wide); its centre is
   the exit, on the mean bearing of the points seen through it. A wall in front of a farther one
   (an L-shaped room's inner corner, a box) is an inward notch and never a door, and a jamb with
   a wall seen behind it is a box or a wall end, not a door frame; a recessed door (seed 000's
   exit) and a door next to a corner are notches like any other.
3. Confidence (:func:`door_confidence`): the points seen *through* the bridge (beyond it by more
   than ``gap_beyond_margin`` of the range) make it a door rather than a blank stretch of wall,
   a door is about as wide as a door, and an exit shows what stands outside across its whole
   width (:func:`through_coverage`), where an inner door often shows a few objects of the far
   room in part of it, or the far room's walls at many depths (:func:`through_depth_spread`).
   Overlapping notches keep the best.
4. Door gaps from the feature extractor, when given, raise the confidence of the candidate they
   match (within ``external_match``) by ``external_weight`` (probabilistic or), or become
   candidates of their own, scored by the points seen through them.

The room outline reported is the surface profile, median-filtered, with notches bridged and
unknown bearings interpolated, simplified by Douglas-Peucker: any number of sides. Coordinates
are normalised (cloud radii); see :mod:`sparse_nav.exit_finder.config`.
"""
import dataclasses
import warnings

import numpy as np
from scipy.ndimage import gaussian_filter1d

from sparse_nav.exit_finder import geometry as geo


@dataclasses.dataclass
class GapResult:
    """Exits [(x, y, confidence)] best first, the outline (M, 2), details for plots."""

    exits: list
    outline: np.ndarray
    details: dict


@dataclasses.dataclass
class Profile:
    """The surface profile around ``centre``.

    Attributes:
        centre: (2,) r.u.
        angles: (B,) bearing of each bin centre (rad).
        ranges: (B,) surface range per bearing (r.u.), NaN where unknown.
        bearing: (N,) bearing bin of each point; radius: (N,) its range (r.u.).
    """

    centre: np.ndarray
    angles: np.ndarray
    ranges: np.ndarray
    bearing: np.ndarray
    radius: np.ndarray

    def point(self, i, r=None):
        """Surface point of bearing i (circular), or the point at range r along it."""
        i = i % len(self.angles)
        r = self.ranges[i] if r is None else r
        return self.centre + r * np.array([np.cos(self.angles[i]), np.sin(self.angles[i])])

    def points(self):
        """(B, 2) surface point of every bearing, NaN where unknown."""
        return self.centre + self.ranges[:, None] * np.column_stack(
            [np.cos(self.angles), np.sin(self.angles)])


def bearing_bins(theta, n_bins):
    """The bearing bin (of ``n_bins`` from -pi) of each bearing theta (rad)."""
    return np.floor((np.asarray(theta) + np.pi) / (2 * np.pi) * n_bins).astype(int) % n_bins


def surface_profile(q, centre, cfg, n_bins=None):
    """Step 1: the nearest dense surface in every bearing (``n_bins`` bearings, default
    ``gap_angle_bins``)."""
    n_bins = cfg.gap_angle_bins if n_bins is None else n_bins
    rel = q - centre
    radius = np.hypot(rel[:, 0], rel[:, 1])
    theta = np.arctan2(rel[:, 1], rel[:, 0])
    bearing = bearing_bins(theta, n_bins)
    angles = (np.arange(n_bins) + 0.5) * (2 * np.pi / n_bins) - np.pi
    lo, hi = np.log(cfg.gap_min_range), np.log(cfg.gap_max_range)
    n_r = max(2, int(np.ceil((hi - lo) / cfg.gap_log_bin)))
    use = (radius > cfg.gap_min_range) & (radius < cfg.gap_max_range)
    k = np.clip(((np.log(radius[use]) - lo) / cfg.gap_log_bin).astype(int), 0, n_r - 1)
    hist = np.bincount(bearing[use] * n_r + k, minlength=n_bins * n_r)
    hist = hist.reshape(n_bins, n_r).astype(float)
    pooled = hist.copy()
    for shift in range(1, cfg.gap_pool_bins + 1):
        pooled += np.roll(hist, shift, axis=0) + np.roll(hist, -shift, axis=0)
    smooth = gaussian_filter1d(pooled, cfg.gap_log_smooth, axis=1, mode="constant")
    # A smoothed peak of height h holds about h * sqrt(2 pi) * sigma points.
    to_points = np.sqrt(2 * np.pi) * cfg.gap_log_smooth
    peak = smooth.max(axis=1)
    dense = (smooth >= cfg.gap_surface_share * peak[:, None]) & \
        (smooth * to_points >= cfg.gap_min_surface_points)
    known = dense.any(axis=1)
    first = np.argmax(dense, axis=1)
    # Climb from the first dense bin to the top of its peak.
    falling = np.concatenate([smooth[:, 1:] <= smooth[:, :-1],
                              np.ones((n_bins, 1), dtype=bool)], axis=1)
    top = np.argmax(falling & (np.arange(n_r)[None, :] >= first[:, None]), axis=1)
    ranges = np.where(known, np.exp(lo + (top + 0.5) * cfg.gap_log_bin), np.nan)
    return Profile(centre=np.asarray(centre, dtype=float), angles=angles, ranges=ranges,
                   bearing=bearing, radius=radius)


def hidden_points(profile, margin):
    """Points the profile does not explain: behind the surface of their bearing by more than
    ``margin`` of its range, or in a bearing without a surface. Seen from the true viewpoint,
    almost nothing hides behind the nearest wall."""
    r_surf = profile.ranges[profile.bearing]
    known = np.isfinite(r_surf)
    return int(np.count_nonzero(~known) +
               np.count_nonzero(known & (profile.radius > r_surf * (1 + margin))))


def estimate_viewpoint(q, cfg, rng):
    """Where the map was seen from: the place around which the profile leaves the fewest points
    unexplained (:func:`hidden_points`; a coarse-to-fine grid search from the mean of the
    points).

    A monocular map is built by a camera that stayed near one place (seed 000's initial scan);
    from anywhere else the points seen through a door appear to lie behind walls. The search
    uses at most ``gap_viewpoint_points`` points and ``gap_viewpoint_bins`` bearings.
    """
    pts = q
    if len(q) > cfg.gap_viewpoint_points:
        pts = q[rng.choice(len(q), size=cfg.gap_viewpoint_points, replace=False)]
    best_v = q.mean(axis=0)
    best = hidden_points(surface_profile(pts, best_v, cfg, cfg.gap_viewpoint_bins),
                         cfg.gap_beyond_margin)
    step = cfg.gap_viewpoint_step
    offsets = np.array([(dx, dy) for dx in (-2, -1, 0, 1, 2) for dy in (-2, -1, 0, 1, 2)
                        if dx or dy], dtype=float)
    for _ in range(cfg.gap_viewpoint_levels):
        centre = best_v
        for off in offsets:
            v = centre + off * step
            hidden = hidden_points(surface_profile(pts, v, cfg, cfg.gap_viewpoint_bins),
                                   cfg.gap_beyond_margin)
            if hidden < best:
                best, best_v = hidden, v
        step /= 2.5
    return best_v


def _bridge_ranges(profile, left, right):
    """Indices of the bearings strictly between left and right (modulo B), and the ranges
    along them of the straight bridge from the surface point of left to that of right (NaN
    where a bearing does not meet it ahead)."""
    a, b = profile.point(left), profile.point(right)
    idx = np.arange(left + 1, right) % len(profile.angles)
    d = np.column_stack([np.cos(profile.angles[idx]), np.sin(profile.angles[idx])])
    ab = b - a
    denom = d[:, 0] * ab[1] - d[:, 1] * ab[0]
    diff = a - profile.centre
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (diff[0] * ab[1] - diff[1] * ab[0]) / denom
    return idx, np.where(np.isfinite(t) & (t > 0), t, np.nan)


def find_notches(profile, cfg):
    """Step 2: outward notches [(left jamb bin, right jamb bin)] of the surface profile.

    A left jamb L ends a wall (its surface runs on for ``gap_jamb_bins`` bearings before it);
    the wall is extended past L as the least-squares line through the surface points of the
    ``gap_extension_bins`` bearings up to L. A right jamb R is one of the first
    ``gap_max_rights`` bearings after L where the surface jumps back inwards (by ``gap_jump``)
    onto that extension, to the range of L or nearer, or anywhere when the wall is seen nearly
    edge-on (``gap_grazing``); the surface must not come back to the extension without such a
    jump (that is a wall, not an opening), and R must start a wall itself. The first jump back
    is not always the door's far jamb (a stray cluster in the opening, a wall seen obliquely);
    the confidence and the overlap suppression choose among the pairs. The bearings between
    must be unknown or beyond the bridge L-R for at least ``gap_notch_share`` of them (noise
    leaves stray surfaces in an opening).
    Bin indices may exceed the number of bins (the circle wraps); use them modulo B.
    """
    r = profile.ranges
    n = len(r)
    known = np.isfinite(r)
    if not np.any(known):
        return []
    dirs = np.column_stack([np.cos(profile.angles), np.sin(profile.angles)])
    pts = profile.centre + np.where(known, r, 0.0)[:, None] * dirs
    step = 2 * np.pi / n
    max_span = max(2, int(np.ceil(np.radians(cfg.gap_max_span_deg) / step)))
    grow = 1.0 + cfg.gap_jump
    notches = []
    behind = _behind_counts(profile, cfg)
    for left in np.flatnonzero(known):
        ahead = np.arange(left + 1, left + max_span + 1) % n
        ext = _extension_ranges(profile, pts, known, left, cfg.gap_extension_bins, dirs[ahead])
        # An opening starts within the next bearings (the pooled profile smears a jamb's jump
        # over a bearing or two): the surface leaves the wall's extension, or disappears.
        steps = min(cfg.gap_jamb_bins, max_span)
        soon = r[ahead[:steps]]
        if not np.any(~np.isfinite(soon) | (soon > ext[:steps] * grow)):
            continue                       # the wall goes on: no opening after this bearing
        if not _on_wall(r, left, -1, cfg):
            continue
        rights = []
        for k in range(1, max_span):
            j = left + 1 + k
            rj = r[j % n]
            if not np.isfinite(rj):
                continue
            back_on_wall = rj <= ext[k] * grow
            before = r[np.arange(j - min(k, cfg.gap_jamb_bins), j) % n]
            inward = not np.all(np.isfinite(before)) or before.max() > rj * grow
            if inward and (back_on_wall or rj <= r[left] * grow or
                           ext[k] > cfg.gap_grazing * r[left]):
                rights.append(j)           # the surface jumps back: a candidate other jamb
                if len(rights) == cfg.gap_max_rights:
                    break
                continue
            if back_on_wall and ext[k] <= r[left] * grow:
                # Back on the wall without a jamb: no opening. Where the extension has run far
                # beyond the jamb (a wall seen obliquely) it meets the surface behind an opening,
                # which says nothing about the wall.
                break
        for right in rights:
            if _is_notch(profile, pts, behind, left, right, cfg):
                notches.append((int(left), int(right)))
    return notches


def _is_notch(profile, pts, behind, left, right, cfg):
    """The checks of a jamb pair (left, right) that make it an opening (:func:`find_notches`)."""
    r = profile.ranges
    n = len(r)
    if not _on_wall(r, right, 1, cfg):
        return False
    # Seen past the opening's edge, a jamb's bearings are a door frame's wall: nothing dense
    # behind it. A box or a wall end in front of the room's wall has that wall behind it.
    side = cfg.gap_occluder_offset + np.arange(cfg.gap_jamb_bins + 1)
    if _occluder(behind, left - side, cfg) or _occluder(behind, right + side, cfg):
        return False
    width = float(np.hypot(*(pts[right % n] - pts[left])))
    if not cfg.gap_min_width <= width <= cfg.gap_max_width:
        return False
    idx, bridge = _bridge_ranges(profile, left, right)
    beyond = ~np.isfinite(r[idx]) | (r[idx] > bridge * (1.0 + cfg.gap_jump))
    return bool(np.all(np.isfinite(bridge)) and np.mean(beyond) >= cfg.gap_notch_share)


def _extension_ranges(profile, pts, known, left, back, dirs):
    """Ranges along the bearings ``dirs`` (M, 2) of the wall ending at bearing ``left``,
    extended past it: the least-squares line through the surface points of the known bearings
    left-back .. left (inf where a bearing does not meet it ahead, or with too few points)."""
    n = len(known)
    bins = (left - np.arange(back + 1)) % n
    bins = bins[known[bins]]
    if len(bins) < 2:
        return np.full(len(dirs), np.inf)
    line = geo.Line.fit(pts[bins])
    denom = dirs @ line.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = float((line.point - profile.centre) @ line.normal) / denom
    return np.where(np.isfinite(t) & (t > 0), t, np.inf)


def _behind_counts(profile, cfg):
    """Per bearing (unpooled): (points on the surface within gap_jump of its range, points
    farther behind it)."""
    n = len(profile.angles)
    r_surf = profile.ranges[profile.bearing]
    known = np.isfinite(r_surf)
    on = known & (np.abs(profile.radius - r_surf) <= cfg.gap_jump * r_surf)
    far = known & (profile.radius > r_surf * (1.0 + cfg.gap_jump))
    return (np.bincount(profile.bearing[on], minlength=n),
            np.bincount(profile.bearing[far], minlength=n))


def _occluder(behind, bins, cfg):
    """True when the surface at these bearings has a dense surface seen behind it: a box or a
    wall end standing in front of the room's wall, not the jamb of a door in that wall."""
    on, far = behind
    bins = np.asarray(bins) % len(on)
    total = on[bins].sum() + far[bins].sum()
    return total > 0 and far[bins].sum() > cfg.gap_occluder_share * total


def _on_wall(r, i, direction, cfg):
    """True if the surface continues from bearing i for ``gap_jamb_bins`` bearings in
    ``direction`` (-1 or +1), no farther than ``gap_jump`` beyond its range: a jamb is the end of
    a wall, not a lone cluster of points in the room. Nearer is allowed: a wall seen obliquely
    comes nearer quickly away from the opening."""
    n = len(r)
    ri = r[i % n]
    for k in range(1, cfg.gap_jamb_bins + 1):
        rk = r[(i + direction * k) % n]
        if not np.isfinite(rk) or rk - ri > cfg.gap_jump * ri:
            return False
    return True


def through_mask(profile, left, right, cfg):
    """Step 3: the points in the bearings strictly between the jambs that lie beyond the
    bridge, (N,) bool."""
    idx, bridge = _bridge_ranges(profile, left, right)
    if not len(idx):
        return np.zeros(len(profile.radius), dtype=bool)
    limit = np.full(len(profile.angles), np.inf)
    limit[idx] = bridge * (1.0 + cfg.gap_beyond_margin)
    return profile.radius > limit[profile.bearing]


def through_count(profile, left, right, cfg):
    """Step 3: how many points are seen through the opening (:func:`through_mask`)."""
    return int(np.count_nonzero(through_mask(profile, left, right, cfg)))


def through_coverage(profile, left, right, through, cfg):
    """Step 3: the share of the bearings strictly between the jambs through which at least
    ``gap_min_surface_points`` points are seen (0 when there are none)."""
    idx = np.arange(left + 1, right) % len(profile.angles)
    if not len(idx):
        return 0.0
    counts = np.bincount(profile.bearing[through], minlength=len(profile.angles))
    return float(np.mean(counts[idx] >= max(cfg.gap_min_surface_points, 1.0)))


def door_centre(profile, q, left, right, through, cfg):
    """Where on the bridge between the jambs the door is: along the mean bearing of the points
    seen through it, which only the door's own aperture lets through (a jamb found a little off
    the door's edge widens the bridge, not that bundle of bearings); the bridge's middle when
    fewer than ``gap_centre_min_points`` were seen."""
    a, b = profile.point(left), profile.point(right)
    if cfg.gap_centre_min_points <= 0 or np.count_nonzero(through) < cfg.gap_centre_min_points:
        return 0.5 * (a + b)
    rel = q[through] - profile.centre
    unit = rel / np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)[:, None]
    d = unit.mean(axis=0)
    ab = b - a
    denom = d[0] * ab[1] - d[1] * ab[0]
    if abs(denom) < 1e-12:
        return 0.5 * (a + b)
    diff = a - profile.centre
    # Solve centre + t d = a + s ab for s, the position along the bridge.
    s = (diff[0] * d[1] - diff[1] * d[0]) / denom
    return a + float(np.clip(s, 0.0, 1.0)) * ab


def outline_from_profile(profile, notches, cfg):
    """The room outline: surface points with notches bridged and unknown bearings interpolated
    (in Cartesian space, between the known neighbours), simplified."""
    r = _median_ranges(profile.ranges, cfg.gap_outline_smooth)
    n = len(r)
    for left, right in notches:
        idx, bridge = _bridge_ranges(profile, left, right)
        r[idx] = bridge
    known = np.flatnonzero(np.isfinite(r))
    if len(known) < 3:
        return None
    pts = np.array([profile.point(i, r[i]) if np.isfinite(r[i]) else [np.nan, np.nan]
                    for i in range(n)])
    missing = np.flatnonzero(~np.isfinite(r))
    for i in missing:
        # Bridge straight between the nearest known bearings on each side.
        before = known[known < i]
        after = known[known > i]
        lft = before[-1] if len(before) else known[-1] - n
        rgt = after[0] if len(after) else known[0] + n
        f = (i - lft) / (rgt - lft)
        pts[i] = (1 - f) * pts[lft % n] + f * pts[rgt % n]
    return geo.simplify_closed(pts, cfg.outline_simplify)


def _median_ranges(ranges, half):
    """Circular running median of the known ranges over 2 * half + 1 bearings (a bearing stays
    unknown when it was): the outline should follow walls, not each bearing's noise."""
    if half <= 0:
        return ranges.copy()
    n = len(ranges)
    idx = (np.arange(n)[:, None] + np.arange(-half, half + 1)[None, :]) % n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # all-NaN windows stay NaN
        med = np.nanmedian(ranges[idx], axis=1)
    return np.where(np.isfinite(ranges), med, np.nan)


def choose_viewpoint(q, cfg, rng=None, viewpoint=None):
    """Where the map was seen from (r.u.): ``viewpoint`` when given; else as ``gap_viewpoint``
    says (``"centroid"``: the mean of the points; otherwise :func:`estimate_viewpoint`, whose
    point subset ``rng`` draws)."""
    if viewpoint is not None:
        return np.asarray(viewpoint, dtype=float)
    if cfg.gap_viewpoint == "centroid":
        return q.mean(axis=0)
    return estimate_viewpoint(q, cfg, rng if rng is not None else np.random.default_rng(cfg.seed))


def find_gaps(q, cfg, rng=None, external=None, viewpoint=None):
    """Steps 1-4 on IPCL points q (r.u.); external door gaps as (K, 3) r.u. or None;
    ``viewpoint`` as :func:`choose_viewpoint` takes it."""
    centre = choose_viewpoint(q, cfg, rng, viewpoint)
    profile = surface_profile(q, centre, cfg)
    notches = find_notches(profile, cfg)
    cands = []
    for left, right in notches:
        through = through_mask(profile, left, right, cfg)
        a, b = profile.point(left), profile.point(right)
        width = float(np.hypot(*(b - a)))
        coverage = through_coverage(profile, left, right, through, cfg)
        centre_xy = door_centre(profile, q, left, right, through, cfg)
        spread = through_depth_spread(profile, through, float(np.hypot(*(centre_xy - centre))))
        cands.append([centre_xy,
                      door_confidence(int(np.count_nonzero(through)), width, cfg, coverage,
                                      spread),
                      left, right])
    cands = _suppress_overlaps(cands, len(profile.angles))
    cands = fuse_external(cands, external, profile, cfg)
    cands.sort(key=lambda c: -c[1])
    cands = cands[:cfg.gap_max_exits]
    outline = outline_from_profile(profile, notches, cfg)
    if outline is None:
        outline = geo.convex_hull(q)
    exits = [(float(c[0][0]), float(c[0][1]), float(c[1])) for c in cands]
    details = {"profile": profile.points()}
    if cands:
        details["line_points"] = _jamb_wall_points(q, profile, cands[0], cfg)
    return GapResult(exits=exits, outline=outline, details=details)


def through_depth_spread(profile, through, door_range):
    """Step 3: how far in depth the points seen through an opening spread, as the range between
    their 10th and 90th percentile over the door's range (0 with fewer than ten points)."""
    if np.count_nonzero(through) < 10 or door_range <= 0:
        return 0.0
    lo, hi = np.quantile(profile.radius[through], [0.1, 0.9])
    return float((hi - lo) / door_range)


def door_confidence(seen, width, cfg, coverage=1.0, spread=0.0):
    """Step 3's confidence in (0, 1): the evidence of the points seen through the opening,
    ``(seen + 1) / (seen + 1 + gap_beyond_points)`` (an opening with nothing seen through it is
    still a gap in the wall, but a weak one), times a width prior
    ``exp(-ln(width / gap_door_width)^2 / (2 gap_door_width_sigma^2))``: doors are about a
    metre wide and rooms a few metres, so a door is about ``gap_door_width`` cloud radii wide;
    much narrower or wider openings are more likely texture holes, blank walls or the open
    side of an L. Times ``1 - gap_cover_weight * (1 - coverage)``, the share of the door's
    bearings with a surface seen through them (:func:`through_coverage`): an exit shows the
    nearest outside surface across its whole width, while an opening into more building
    shows a few objects in part of it, its far walls being out of the camera's reach. Times
    ``1 / (1 + gap_spread_weight * max(0, spread - gap_spread_free))``: what is seen through an
    exit stands at about one depth, a room beyond an inner door spreads over many."""
    evidence = (seen + 1.0) / (seen + 1.0 + cfg.gap_beyond_points)
    prior = np.exp(-0.5 * (np.log(max(width, 1e-9) / cfg.gap_door_width) /
                           cfg.gap_door_width_sigma) ** 2)
    deep = 1.0 / (1.0 + cfg.gap_spread_weight * max(0.0, spread - cfg.gap_spread_free))
    return float(evidence * prior * (1.0 - cfg.gap_cover_weight * (1.0 - coverage)) * deep)


def _suppress_overlaps(cands, n_bins):
    """Of notches sharing bearings, keep the most confident."""
    cands = sorted(cands, key=lambda c: -c[1])
    kept, taken = [], np.zeros(n_bins, dtype=bool)
    for c in cands:
        idx = np.arange(c[2], c[3] + 1) % n_bins
        if np.any(taken[idx]):
            continue
        taken[idx] = True
        kept.append(c)
    return kept


def _jamb_wall_points(q, profile, cand, cfg):
    """Wall points next to a door: near the surface in the bearings beside its two jambs."""
    n = len(profile.angles)
    span = max(1, (cand[3] - cand[2]))
    side = np.concatenate([np.arange(cand[2] - span, cand[2] + 1),
                           np.arange(cand[3], cand[3] + span + 1)]) % n
    mask = np.isin(profile.bearing, side)
    r_surf = profile.ranges[profile.bearing]
    near = np.isfinite(r_surf) & (np.abs(profile.radius - r_surf) <= cfg.gap_jump * r_surf)
    return q[mask & near]


def fuse_external(cands, external, profile, cfg):
    """Step 4: merge door gaps from the feature extractor into the candidates, a list of
    ``[centre, confidence, left bin, right bin]`` (the bins of an external gap of its own)."""
    if external is None or not len(external):
        return cands
    n = len(profile.angles)
    for x, y, width in external:
        p = np.array([x, y])
        match = None
        for c in cands:
            if np.hypot(*(c[0] - p)) <= max(cfg.external_match, width / 2.0):
                if match is None or c[1] > match[1]:
                    match = c
        if match is not None:
            match[1] = 1.0 - (1.0 - match[1]) * (1.0 - cfg.external_weight)
            continue
        # Own evidence at the external gap: points beyond it within its bearings.
        rel = p - profile.centre
        dist = float(np.hypot(*rel))
        half = np.arctan2(width / 2.0, max(dist, 1e-9))
        bearing = np.arctan2(rel[1], rel[0])
        step = 2 * np.pi / n
        b0 = int(np.floor((bearing - half + np.pi) / step))
        b1 = int(np.floor((bearing + half + np.pi) / step))
        idx = np.arange(b0, b1 + 1) % n
        seen = int(np.count_nonzero(np.isin(profile.bearing, idx) &
                                    (profile.radius > dist * (1.0 + cfg.gap_beyond_margin))))
        own = door_confidence(seen, width, cfg)
        conf = 1.0 - (1.0 - own) * (1.0 - cfg.external_weight)
        cands.append([p, conf, b0, b1])
    return cands
