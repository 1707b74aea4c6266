"""``find_exit``: one entry point for every exit finder method (ROS-free).

Methods (``METHODS``):

* ``seed``: seed 000 steps 1-8 as written (line score RPCL), see :mod:`.seed`.
* ``seed_count``, ``seed_extent``: the seed with the other line scores it mentions (plain count
  of near points; distance of the two furthest near points).
* ``dbscan``: seed alternative, DBSCAN cluster centres of the points outside the seed's room.
* ``farthest_corner``: seed alternative, the seed room's corner farthest from the cloud centre.
* ``concave_vertex``: seed alternative, the deepest reflex vertex of the cloud's alpha outline.
* ``gaps``: door gaps anywhere on a room outline of any number of sides, confirmed by the points
  seen through them, ranked with a hand-made confidence, fused with the feature extractor's door
  gaps when given; see :mod:`.gaps`. When the given viewpoint shows no exit it looks once more
  from the viewpoint the cloud suggests (a camera that moved while mapping saw the door from
  elsewhere). 78.7 % of the benchmark's door-visible rooms (75.0 % of those its defaults were
  not tuned on).
* ``ranked``: the candidates of several door detectors (the notches of ``gaps`` at three
  bearing resolutions, gaps in straight walls) described by scale-free features and ranked by
  the probability a learned model gives them (:mod:`.doors`, :mod:`.ranker`); the same
  viewpoint fallback and door gap fusion as ``gaps``; candidates the model rates below
  ``rank_min_probability`` are not reported, so a closed room gives "no exit". The default: it
  wins the simulator benchmark (bench/bench_exit_finder.py), whose rooms it was not trained on.
* ``auto``: per cloud, ``ranked`` when its best exit has a probability >=
  ``auto_min_confidence``, else the seed's corner when the seed finds a room with an empty
  corner, else the deepest concave vertex; the result's method names the choice
  (``auto:ranked``).

Every method first runs seed steps 1-3 (:func:`prepare`): drop the vertical axis, drop non-finite
rows, normalise to cloud radii, round to ``round_decimals`` and de-duplicate, IPCL.
"""
import dataclasses
import time

import numpy as np

from sparse_nav.exit_finder import cloud as cloudlib
from sparse_nav.exit_finder import doors as doorslib
from sparse_nav.exit_finder import gaps as gapslib
from sparse_nav.exit_finder import geometry as geo
from sparse_nav.exit_finder import seed as seedlib
from sparse_nav.exit_finder.config import ExitFinderConfig
from sparse_nav.exit_finder.geometry import Line
from sparse_nav.exit_finder.ranker import RankerModelError, load_ranker
from sparse_nav.exit_finder.result import (STATUS_NO_EXIT, STATUS_OK, ExitFinderError,
                                           ExitResult)

METHODS = ("seed", "seed_count", "seed_extent", "dbscan", "farthest_corner", "concave_vertex",
           "gaps", "ranked", "auto")
DEFAULT_METHOD = "ranked"


@dataclasses.dataclass
class Prepared:
    """Seed steps 1-3 done: the normalised frame and the points every method starts from.

    Attributes:
        frame: the :class:`~.cloud.CloudFrame` (input units <-> r.u.).
        rounded: (M, 2) r.u., rounded and de-duplicated (seed step 2).
        q: (K, 2) r.u., after IPCL (seed step 3): the points the methods use.
        n_in: rows given; n_dropped: non-finite rows dropped.
    """

    frame: cloudlib.CloudFrame
    rounded: np.ndarray
    q: np.ndarray
    n_in: int
    n_dropped: int


def prepare(points, up_axis, cfg):
    """Seed steps 1-3. Raises ExitFinderError for clouds that cannot hold a room."""
    n_in = len(points) if hasattr(points, "__len__") else 0
    xy, n_dropped = cloudlib.planar_points(points, up_axis, cfg.drop_non_finite)
    cloudlib.check_spread(xy, cfg.min_points, cfg.collinear_ratio, n_in, "finite")
    frame = cloudlib.CloudFrame.of(xy, cfg.scale_percentile)
    if not frame.scale > 0:
        raise ExitFinderError("collinear", f"more than {100 - cfg.scale_percentile:g}% of the "
                                           f"points coincide: the cloud has no extent", n_in)
    rounded = cloudlib.round_dedup(frame.to_norm(xy), cfg.round_decimals)
    q = cloudlib.ipcl(rounded, cfg.ipcl_radius, cfg.ipcl_min_neighbours, cfg.ipcl_rounds)
    cloudlib.check_spread(q, cfg.min_points, cfg.collinear_ratio, n_in,
                          "dense (after de-duplication and IPCL)")
    return Prepared(frame=frame, rounded=rounded, q=q, n_in=n_in, n_dropped=n_dropped)


@dataclasses.dataclass
class _Answer:
    """A method's answer in r.u., before mapping back to input units."""

    exits: list
    corners: np.ndarray
    reason: str
    details: dict


def _seed_family(prep, cfg, rng, method):
    if method in ("seed_count", "seed_extent"):
        cfg = dataclasses.replace(cfg, line_score=method.split("_")[1])
    room = seedlib.fit_room(prep.q, cfg, rng)
    details = {"room_lines": [room.lines[k] for k in room.sides]}
    if method in ("seed", "seed_count", "seed_extent"):
        exits, more = seedlib.seed_exit(prep.q, room, cfg)
        details.update(more)
        reason = "corner whose two sides have the most empty perimeter samples"
    elif method == "farthest_corner":
        exits = seedlib.farthest_corner(prep.q, room)
        reason = "room corner farthest from the cloud centre"
    else:
        exits, outside = seedlib.dbscan_exits(prep.q, room, cfg)
        details["outside_points"] = outside
        reason = "centre of the largest cluster of points outside the room"
    return _Answer(exits=exits, corners=room.corners, reason=reason, details=details)


def _concave(prep, cfg):
    exits, outline = seedlib.concave_vertices(prep.q, cfg)
    if outline is None:
        raise ExitFinderError("no_room_shape", "no alpha outline: the points are too sparse for "
                                               f"alpha_radius {cfg.alpha_radius} r.u.")
    return _Answer(exits=exits, corners=outline, reason="deepest reflex vertex of the cloud's "
                                                        "alpha outline", details={})


def _viewpoint(prep, cfg, viewpoint):
    """The viewpoint in r.u. for the gap method, or None to let it estimate one.

    An explicit viewpoint (input units) wins. ``gap_viewpoint == "origin"`` takes the input
    frame's origin, which for an ORB-SLAM map is the first camera pose, when it lies inside the
    convex hull of the points; elsewhere the map was not seen from there.
    """
    if viewpoint is not None:
        return prep.frame.to_norm(np.asarray(viewpoint, dtype=float).reshape(2))
    if cfg.gap_viewpoint != "origin":
        return None
    origin = prep.frame.to_norm(np.zeros(2))
    hull = geo.convex_hull(prep.q)
    if hull is not None and geo.points_in_polygon(origin[None], hull)[0]:
        return origin
    return None


def _gaps(prep, cfg, rng, door_gaps, viewpoint=None):
    given = _viewpoint(prep, cfg, viewpoint)
    found = gapslib.find_gaps(prep.q, cfg, rng, door_gaps, given)
    reason = "door gaps in the room outline with points seen through them"
    if not found.exits and given is not None:
        # A camera that moved while mapping saw the door from elsewhere: the viewpoint the cloud
        # itself suggests may show it (a recessed door in a corner, in live one_room runs).
        estimated = gapslib.find_gaps(prep.q, cfg, rng, door_gaps, None)
        if estimated.exits:
            found = estimated
            reason += " (from the viewpoint the cloud suggests; none from the given one)"
    return _Answer(exits=found.exits, corners=found.outline, reason=reason, details=found.details)


def ranked_candidates(prep, cfg, rng, centre=None):
    """The ``ranked`` method's candidates seen from ``centre`` (r.u.; None: from where the method
    looks first without a given viewpoint): (scene, doors, feature matrix). The ranker's training
    script calls this too, so that it learns on exactly what the method sees."""
    if centre is None:
        centre = gapslib.choose_viewpoint(prep.q, cfg, rng, _viewpoint(prep, cfg, None))
    scene = doorslib.Scene(prep.q, centre, cfg)
    doors = doorslib.candidates(scene, rng)
    return scene, doors, doorslib.feature_matrix(scene, doors)


def _rank(prep, cfg, rng, door_gaps, centre):
    """Candidates from ``centre`` scored by the ranker, fused with external door gaps, merged
    (a candidate within ``rank_merge_radius`` of a better one is the same door) and cut to
    ``gap_max_exits`` and ``rank_min_probability``: (exits, scene, candidates, best candidate or
    None)."""
    try:
        ranker = load_ranker(cfg.rank_model)
    except RankerModelError as exc:
        raise ExitFinderError("bad_input", str(exc), prep.n_in) from None
    scene, doors, x = ranked_candidates(prep, cfg, rng, centre)
    prob = ranker.probability(x)
    cands = [[d.centre, float(p), None, None] for d, p in zip(doors, prob)]
    cands = gapslib.fuse_external(cands, door_gaps, scene.profile, cfg)
    order = sorted(range(len(cands)), key=lambda i: -cands[i][1])
    kept = []
    for i in order:
        if cands[i][1] < cfg.rank_min_probability or len(kept) == cfg.gap_max_exits:
            break
        if all(np.hypot(*(cands[i][0] - cands[k][0])) > cfg.rank_merge_radius for k in kept):
            kept.append(i)
    exits = [(float(cands[i][0][0]), float(cands[i][0][1]), cands[i][1]) for i in kept]
    best = doors[kept[0]] if kept and kept[0] < len(doors) else None
    return exits, scene, doors, best


def _ranked(prep, cfg, rng, door_gaps, viewpoint=None):
    given = _viewpoint(prep, cfg, viewpoint)
    centre = gapslib.choose_viewpoint(prep.q, cfg, rng, given)
    exits, scene, doors, best = _rank(prep, cfg, rng, door_gaps, centre)
    reason = "door candidates of several detectors ranked by the learned model"
    if not exits and given is not None:
        # As for gaps: a camera that moved while mapping may have seen the door from elsewhere.
        estimated = gapslib.estimate_viewpoint(prep.q, cfg, rng)
        exits, scene, doors, best = _rank(prep, cfg, rng, door_gaps, estimated)
        reason += " (from the viewpoint the cloud suggests; none from the given one)"
    first = doorslib.SOURCES[0]
    notches = [d.jambs for d in doors if d.source == first]
    outline = gapslib.outline_from_profile(scene.profile, notches, scene.profile_cfg)
    if outline is None:
        outline = geo.convex_hull(prep.q)
    details = {"profile": scene.profile.points()}
    if best is not None:
        details["line_points"] = doorslib.jamb_points(scene, best)
    return _Answer(exits=exits, corners=outline, reason=reason, details=details)


def _auto(prep, cfg, rng, door_gaps, viewpoint=None):
    """Per cloud: ``ranked`` when its best exit has probability >= auto_min_confidence; else the
    seed's corner when the seed finds a four-sided room with an empty corner; else the deepest
    concave vertex of the outline; else what ``ranked`` had (no exit)."""
    error = None
    try:
        answer = _ranked(prep, cfg, rng, door_gaps, viewpoint)
    except ExitFinderError as exc:
        answer, error = None, exc
    if answer is not None and answer.exits and answer.exits[0][2] >= cfg.auto_min_confidence:
        return "ranked", answer
    for name in ("seed", "concave_vertex"):
        try:
            if name == "seed":
                other = _seed_family(prep, cfg, np.random.default_rng(cfg.seed), "seed")
            else:
                other = _concave(prep, cfg)
        except ExitFinderError:
            continue
        if other.exits:
            return name, other
    if answer is None:
        raise error
    return "ranked", answer


def find_exit(points, method=DEFAULT_METHOD, config=None, up_axis="-y", seed=None,
              door_gaps=None, viewpoint=None):
    """Find the room's exit in a sparse point cloud.

    Args:
        points: (N, 3) array in a frame whose vertical axis is ``up_axis`` (ORB-SLAM's map
            points: ``'-y'``), or (N, 2) horizontal points with ``up_axis=None``. Any units.
        method: one of :data:`METHODS`.
        config: an :class:`ExitFinderConfig` (validated here); defaults when None.
        up_axis: the input's vertical axis (``'x'``, ``'-x'``, ``'y'``, ``'-y'``, ``'z'``,
            ``'-z'``), dropped in seed step 1; None for (N, 2) input.
        seed: seed of the random draws (RANSAC); None uses ``config.seed``. Same seed, same
            input: same answer.
        door_gaps: optional door gaps from the feature extractor, ``[(x, y, width), ...]`` in the
            same horizontal axes and units as the result; fused by ``gaps`` and ``auto``, ignored
            by the other methods.
        viewpoint: optional (x, y) in the same axes and units: where the map was seen from
            (e.g. the mean camera position of the scan). Used by ``gaps`` and ``auto``; when
            None, ``config.gap_viewpoint`` decides (default: the input's origin, an ORB-SLAM
            map's first camera pose).

    Returns:
        :class:`ExitResult` in the two horizontal axes of the input, in its units (for
        ``'±y'``: x and z). ``status`` is ``"ok"`` with exits, or ``"no_exit"`` with none when a
        room was found but nothing marks an exit.

    Raises:
        ExitFinderError: bad input, too few points, collinear points or no room shape.
        ValueError: unknown method or invalid config.
    """
    start = time.perf_counter()
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    cfg = dataclasses.replace(config) if config is not None else ExitFinderConfig()
    if seed is not None:
        cfg.seed = int(seed)
    cfg.validate()
    prep = prepare(points, up_axis, cfg)
    ext = _normalise_gaps(door_gaps, prep.frame, prep.n_in)
    rng = np.random.default_rng(cfg.seed)
    try:
        if method == "auto":
            chosen, answer = _auto(prep, cfg, rng, ext, viewpoint)
            name = f"auto:{chosen}"
        elif method == "gaps":
            answer, name = _gaps(prep, cfg, rng, ext, viewpoint), method
        elif method == "ranked":
            answer, name = _ranked(prep, cfg, rng, ext, viewpoint), method
        elif method == "concave_vertex":
            answer, name = _concave(prep, cfg), method
        else:
            answer, name = _seed_family(prep, cfg, rng, method), method
    except ExitFinderError as exc:
        exc.n_points_in = prep.n_in
        raise
    frame = prep.frame
    exits = [(*map(float, frame.from_norm([x, y])), float(np.clip(s, 0.0, 1.0)))
             for x, y, s in answer.exits]
    details = {k: _to_input(v, frame) for k, v in answer.details.items()}
    details["cloud"] = frame.from_norm(prep.q)
    return ExitResult(
        exits=exits, method=name,
        room_corners=[tuple(map(float, c)) for c in frame.from_norm(answer.corners)],
        n_points_in=prep.n_in, n_points_used=len(prep.q),
        runtime_s=time.perf_counter() - start,
        status=STATUS_OK if exits else STATUS_NO_EXIT,
        reason=answer.reason if exits else "a room was found but nothing marks an exit",
        n_dropped_non_finite=prep.n_dropped, details=details)


def _normalise_gaps(door_gaps, frame, n_in):
    """External door gaps (x, y, width) in input units -> (K, 3) r.u.; validated."""
    if door_gaps is None:
        return None
    try:
        arr = np.asarray(door_gaps, dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        raise ExitFinderError("bad_input", "door_gaps must be a list of (x, y, width)",
                              n_in) from None
    if not np.isfinite(arr).all() or np.any(arr[:, 2] <= 0):
        raise ExitFinderError("bad_input", "door_gaps need finite x, y and a width > 0", n_in)
    out = arr.copy()
    out[:, :2] = frame.to_norm(arr[:, :2])
    out[:, 2] = arr[:, 2] / frame.scale
    return out


def _to_input(value, frame):
    """Map a details entry back to input units: (N, 2) arrays are points, lists of Lines are
    lines; anything else (counts, masks) passes through unchanged."""
    if isinstance(value, np.ndarray) and value.ndim == 2 and value.shape[1] == 2:
        return frame.from_norm(value)
    if isinstance(value, list) and value and all(isinstance(v, Line) for v in value):
        return [Line(point=frame.from_norm(v.point), direction=v.direction) for v in value]
    return value
