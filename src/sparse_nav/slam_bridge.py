"""ROS-free core of slam_bridge: SLAM health, map anchoring in REP-105 frames, metric scale.

The monocular SLAM world is the first camera's optical frame, in SLAM units. The bridge anchors
each SLAM map in a z-up ``map`` frame: the first map so that ``base_link`` is at the origin when
tracking first succeeds, every later map so that the robot continues from its last known pose.
When SLAM merges a map back into an earlier one, the earlier map's points reappear in the
published cloud at their own coordinates, and the pose jumps into that map's frame: either picks
the earlier anchor up again.
"""
import collections
import dataclasses
import re

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist

from sparse_nav.transforms import invert, planar, quaternion_to_matrix, scaled, yaw_of

NOT_INITIALIZED, OK, LOST, NEW_MAP = 0, 1, 2, 3
STATE_NAMES = {NOT_INITIALIZED: "NOT_INITIALIZED", OK: "OK", LOST: "LOST", NEW_MAP: "NEW_MAP"}

# ORB-SLAM3 Tracking::eTrackingState (OK_KLT exists in some forks).
ORB_SYSTEM_NOT_READY, ORB_NO_IMAGES_YET, ORB_NOT_INITIALIZED = -1, 0, 1
ORB_OK, ORB_RECENTLY_LOST, ORB_LOST, ORB_OK_KLT = 2, 3, 4, 5


@dataclasses.dataclass
class BridgeConfig:
    """Parameters of the bridge; defaults are written here once."""

    pose_timeout_s: float = 0.5          # no pose for this long: tracking is lost
    min_tracked_points: int = 15         # fewer tracked map points: tracking is lost
    relocalise_tolerance_m: float = 2.0  # an earlier map anchor is reused if it puts the robot this close
    jump_threshold_m: float = 0.5        # a pose step larger than this (metres) is a map switch
    max_pose_age_for_scale_s: float = 0.3
    merge_sample_points: int = 300       # points kept of each map's cloud to recognise it by
    merge_match_tolerance: float = 0.01  # a kept point reappears within this share of its map's size
    merge_min_share: float = 0.5         # of a map's kept points that reappear: merged into it
    merge_scale_tolerance: float = 0.08  # a merge's scale ratio is measured when the distances
                                         # between points of both clouds agree at every quantile
                                         # within this share (a similarity transform)

    def validate(self):
        for name in ("pose_timeout_s", "relocalise_tolerance_m", "jump_threshold_m",
                     "merge_sample_points", "merge_match_tolerance", "merge_scale_tolerance"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.min_tracked_points < 0:
            raise ValueError("min_tracked_points must be >= 0")
        if not 0 < self.merge_min_share <= 1:
            raise ValueError(f"merge_min_share must be in (0, 1], got {self.merge_min_share}")


class StateTracker:
    """SLAM health from the wrapper's state topic when there is one, inferred otherwise."""

    def __init__(self, config):
        self._cfg = config
        self._wrapper_code = None
        self._last_pose_s = None
        self._n_tracked = None
        self._ever_ok = False

    @property
    def source(self):
        return "wrapper" if self._wrapper_code is not None else "inferred"

    def on_wrapper_state(self, code):
        """Returns True when this state means a new map is being initialised after tracking."""
        self._wrapper_code = int(code)
        return self._initialising_new_map()

    def _initialising_new_map(self):
        return self._ever_ok and self._wrapper_code == ORB_NOT_INITIALIZED

    @property
    def map_given_up(self):
        """SLAM has given up the map it tracked in (ORB-SLAM3 LOST, or initialising a new map
        after tracking): tracking comes back only in a new map, which needs a baseline of
        motion, or by a merge. False while SLAM still relocalises in its map (RECENTLY_LOST),
        and without the wrapper's state, which alone can tell."""
        return self._wrapper_code == ORB_LOST or self._initialising_new_map()

    def on_pose(self, stamp_s):
        """Records a pose time; returns the gap (s) since the previous pose when it is longer than
        pose_timeout_s (tracking was lost in between, even if nobody looked at that moment)."""
        previous, self._last_pose_s = self._last_pose_s, stamp_s
        if previous is not None and stamp_s - previous > self._cfg.pose_timeout_s:
            return stamp_s - previous
        return None

    def on_tracked_points(self, n):
        self._n_tracked = int(n)

    @property
    def n_tracked(self):
        return self._n_tracked or 0

    def evaluate(self, now_s):
        """(state, reason) at time now_s; state is NOT_INITIALIZED, OK or LOST."""
        if self._wrapper_code is not None:
            ok, reason = self._from_wrapper()
        else:
            ok, reason = self._inferred(now_s)
        if ok:
            self._ever_ok = True
            return OK, reason
        return (LOST if self._ever_ok else NOT_INITIALIZED), reason

    def _from_wrapper(self):
        code = self._wrapper_code
        if code in (ORB_OK, ORB_OK_KLT):
            return True, "wrapper reports OK"
        names = {ORB_SYSTEM_NOT_READY: "system not ready", ORB_NO_IMAGES_YET: "no images yet",
                 ORB_NOT_INITIALIZED: "map not initialised", ORB_RECENTLY_LOST: "recently lost",
                 ORB_LOST: "lost"}
        return False, "wrapper reports " + names.get(code, f"unknown state {code}")

    def _inferred(self, now_s):
        if self._last_pose_s is None:
            return False, "no camera pose received yet"
        age = now_s - self._last_pose_s
        if age > self._cfg.pose_timeout_s:
            return False, f"no camera pose for {age:.2f} s"
        if self._n_tracked is not None and self._n_tracked < self._cfg.min_tracked_points:
            return False, (f"only {self._n_tracked} tracked points "
                           f"(< {self._cfg.min_tracked_points})")
        return True, "camera pose is fresh and enough points are tracked"


@dataclasses.dataclass
class Anchor:
    """Where one SLAM map sits in ``map``: a rigid transform and the map's metres per unit."""

    index: int
    t_map_slam: np.ndarray
    metres_per_unit: float
    # Left by a jump while tracking: SLAM merged this map into another (or re-framed it), so no
    # later pose is in its frame, and reading one through it would only fit by chance.
    retired: bool = False

    def base_pose(self, t_slam_cam, t_cam_base):
        return self.t_map_slam @ scaled(t_slam_cam, self.metres_per_unit) @ t_cam_base


class MapAnchors:
    """Keeps one anchor per SLAM map and decides which map a camera pose belongs to."""

    def __init__(self, config, t_base_cam):
        self._cfg = config
        self._t_cam_base = invert(np.asarray(t_base_cam, dtype=float))
        self.anchors = []
        self.current = None
        self.last_base = None
        self._needs_check = True
        self._new_map_expected = False
        self._accept_next = False
        self._reanchor_next = False
        self._clouds = MapClouds(config)
        self._entered_s = None  # stamp of the pose that put the robot in the current map
        self._last_t_slam_cam = None

    def tracking_lost(self):
        """The next pose may be in another map (a new one, or an earlier one after a merge)."""
        self._needs_check = True
        self._clouds.last_index = None

    def expect_new_map(self):
        """SLAM said it is initialising a new map (ORB-SLAM3 passes through NOT_INITIALIZED, and
        its map-point count collapses), so the next pose must not be taken for a relocalisation in
        the current map, which a new map's origin could otherwise happen to resemble."""
        self._needs_check = True
        self._new_map_expected = True

    def set_scale(self, metres_per_unit):
        if self.current is not None and metres_per_unit > 0:
            self.current.metres_per_unit = float(metres_per_unit)

    def rescale(self, metres_per_unit):
        """A new scale for the current map that moves the robot nowhere: the next pose re-anchors
        the map where the robot was (set_scale scales the map about its origin, which a small
        correction moves the robot little, and a merge's new scale by metres)."""
        self.set_scale(metres_per_unit)
        self._reanchor_next = self.current is not None

    def update(self, t_slam_cam, metres_per_unit, stamp_s):
        """Base pose in ``map`` for a camera pose in the SLAM frame, stamped stamp_s (s); returns
        (T_map_base, event).

        event is None, "first" (the first map), "new_map", "switched" (back to an earlier map),
        "relocalised" (tracking resumed in the same map) or "reframed" (the pose jumped while
        tracking and no earlier map explains it).
        """
        event = None
        if self.current is None:
            self.current = self._new_anchor(t_slam_cam, metres_per_unit, np.eye(4))
            event = "first"
        else:
            if self._reanchor_next and not self._needs_check:
                self._reanchor_at_last_base(t_slam_cam)
            candidate = self.current.base_pose(t_slam_cam, self._t_cam_base)
            # A jump is SLAM's: both poses read at the map's present scale, so that a new scale
            # (which moves the robot about the map's origin) is no jump. A young map's first
            # samples may triple it, and the pose, near the origin of both maps for a robot
            # scanning in place, then read as a switch back to the earlier map.
            before = self.current.base_pose(self._last_t_slam_cam, self._t_cam_base)
            step = np.linalg.norm(candidate[:3, 3] - before[:3, 3])
            jumped = step > self._cfg.jump_threshold_m and not self._accept_next
            if self._needs_check or jumped:
                left = self.current
                best = None if self._new_map_expected else self._best_anchor(t_slam_cam)
                if best is None and not self._needs_check:
                    # A jump while tracking is a merge or a loop closure, never a new map (SLAM
                    # begins one only after it lost tracking): the map goes on from where the
                    # robot was until its cloud tells which earlier map it joined (on_cloud).
                    self._reanchor_at_last_base(t_slam_cam)
                    event = "reframed"
                elif best is None:
                    self.current = self._new_anchor(t_slam_cam, metres_per_unit,
                                                    self._level_last_base())
                    event = "new_map"
                elif best is not self.current:
                    self.current = best
                    event = "switched"
                elif self._needs_check:
                    event = "relocalised"
                if self.current is not left and not self._needs_check:
                    left.retired = True
                    self._clouds.merged_from = left.index
        if self._needs_check or event in ("first", "new_map", "switched"):
            self._entered_s = stamp_s
        self._needs_check = False
        self._new_map_expected = False
        self._accept_next = False
        self._reanchor_next = False
        self.last_base = self.current.base_pose(t_slam_cam, self._t_cam_base)
        self._last_t_slam_cam = t_slam_cam
        return self.last_base, event

    def is_late(self, cloud_stamp_s):
        """Whether a cloud stamped cloud_stamp_s (s) predates the pose that put the robot in the
        current map: then it is the map before, delivered late (the bridge takes longer over a
        cloud than over a pose), and would read as a merge back into that map, or into any small
        map begun at the same place, and its points are not in the current map's frame."""
        return self._entered_s is not None and cloud_stamp_s < self._entered_s

    def on_cloud(self, points):
        """The active SLAM map's cloud (SLAM units) while tracking, not late (``is_late``).
        Returns the index of the earlier map whose points reappear in it (SLAM merged the current
        map into that one, and the next pose is read through its anchor, whatever step that
        makes), else None. ``merge`` then tells whether this is the first cloud of a merge, found
        by this cloud or by the pose.

        The map left is retired, and so is the map the previous cloud belonged to: when the pose
        jumped at the merge, a new anchor may stand between them."""
        if self.current is None:
            return None
        previous = self._clouds.last_index
        merged = self._clouds.observe(self.current.index, points)
        if merged is None:
            if self.merge is not None and self.merge.left == self.merge.into:
                self._reanchor_next = True  # its frame moved under the robot
            return None
        for left in (self.current.index, previous):
            if left is not None and left != merged:
                self.anchors[left].retired = True
        self.current = self.anchors[merged]
        self.current.retired = False
        self._accept_next = True
        return merged

    @property
    def merge(self):
        """The MapMerge the latest cloud was the first of, if any."""
        return self._clouds.merge

    def _level_last_base(self):
        return planar(*self.last_base[:3, 3], yaw_of(self.last_base))

    def _reanchor_at_last_base(self, t_slam_cam):
        """Anchors the current map so that this pose puts the base where it last was."""
        self.current.t_map_slam = self._anchor_at(t_slam_cam, self.current.metres_per_unit,
                                                  self._level_last_base())

    def _anchor_at(self, t_slam_cam, metres_per_unit, t_map_base):
        """T_map_slam that puts the base at t_map_base for this camera pose."""
        return t_map_base @ invert(scaled(t_slam_cam, metres_per_unit) @ self._t_cam_base)

    def _new_anchor(self, t_slam_cam, metres_per_unit, t_map_base):
        t_map_slam = self._anchor_at(t_slam_cam, metres_per_unit, t_map_base)
        anchor = Anchor(len(self.anchors), t_map_slam, float(metres_per_unit))
        self.anchors.append(anchor)
        return anchor

    def _best_anchor(self, t_slam_cam):
        best, best_d = None, self._cfg.relocalise_tolerance_m
        for anchor in (a for a in self.anchors if not a.retired):
            d = np.linalg.norm(anchor.base_pose(t_slam_cam, self._t_cam_base)[:3, 3]
                               - self.last_base[:3, 3])
            if d <= best_d:
                best, best_d = anchor, d
        return best


MapMerge = collections.namedtuple("MapMerge", "left into units_ratios")
MapMerge.__doc__ = """SLAM merged map ``left`` into map ``into``. ``units_ratios`` maps each
earlier map whose last cloud this merged cloud matches in shape to the number of ``into``'s units
one of its units became: the map left, or a map merged on the way (SLAM merges one map after
another within a frame, faster than the pose tells). ``left == into``: the current map's points
moved into a frame the bridge does not know (see ``MapClouds.observe``); the map goes on in it."""

# Points of each map kept to compare map sizes: distance quantiles within about 1 %.
_SIZE_SAMPLE_POINTS = 1000
_SIZE_QUANTILES = (0.1, 0.25, 0.5, 0.75, 0.9)
# A merged cloud holds every point of each map merged into it, but for the few SLAM culls or
# fuses with a point of the other map; a cloud with fewer does not hold that map.
_MERGED_KEEPS_SHARE = 0.8
# A map whose points all moved was merged into another frame; a young map's points, refined
# between two clouds, keep more than this share where they were (5.5 % and up in the simulator).
_MOVED_MAX_SHARE = 0.03


class MapClouds:
    """Recognises a SLAM map by its points. ORB-SLAM3 welds a map into the earlier one it
    recognises, in the earlier map's frame: the earlier map's points reappear in the active map's
    cloud at their own coordinates, while the merged map's own points move. The pose alone misses
    such merges for a robot scanning in place, which stays near the origin of every map it begins
    there: the pose moves by centimetres and turns by the angle between the two frames.

    Keeps a sample of each map's latest cloud (SLAM units, as published) and finds which earlier
    map's sample a new cloud contains. At a merge it also measures the scale between the two
    maps, which SLAM gives the merged map from the map merged into (see ``_units_ratios``).
    """

    def __init__(self, config, seed=0):
        self._cfg = config
        self._rng = np.random.default_rng(seed)  # which points are kept; seeded, so repeatable
        self._samples = {}       # map index -> (sample points, match radius in SLAM units)
        self._sizes = {}         # map index -> (points in its latest cloud, their size sample)
        self.last_index = None   # the map whose sample the latest cloud was kept as
        self.merged_from = None  # the map the pose left into the current one while tracking
        self.merge = None        # the MapMerge the latest cloud was the first of, if any

    def observe(self, current_index, points):
        """The earlier map whose kept points reappear in this cloud of the active map while the
        current map's own do not (None when none does); keeps the cloud as the sample of the map
        it belongs to."""
        self.merge = None
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(points) == 0:
            return None
        # One map known (every run without a loss): nothing it could have merged into.
        merged, tree, own_share = None, None, 1.0
        if any(k != current_index for k in self._samples):
            tree = cKDTree(points)
            own_share = self._share_in(current_index, tree)
            if own_share < self._cfg.merge_min_share:
                merged = self._merged_into(current_index, tree)
        into = current_index if merged is None else merged
        left = current_index if merged is not None else self.merged_from
        self.merged_from = None
        # A late cloud of the map the pose left, which still holds its points where they were,
        # is no merged cloud.
        if left is not None and left != into and (
                merged is not None or self._share_in(left, tree) < self._cfg.merge_min_share):
            self.merge = MapMerge(left, into, self._units_ratios(into, points))
            self._sizes.pop(left, None)  # its points are the merged map's now
        elif left is None and merged is None and current_index in self._samples \
                and own_share < _MOVED_MAX_SHARE:
            # None of the current map's points is where it was and no known map's points are in
            # the cloud: SLAM merged it into a map whose points moved too (a young map's,
            # refined as SLAM tracks in it again) or that no cloud showed. The cloud is in that
            # map's frame.
            self.merge = MapMerge(current_index, current_index, self._units_ratios(None, points))
        self._keep(into, points)
        return merged

    def _units_ratios(self, into, points):
        """Units of ``into`` per unit of each earlier map this first cloud after a merge into it
        may hold: a similarity transform scales every distance between points alike, so the
        distances in this cloud against those in a map's last one give the ratio, when that map
        had more points than ``into`` (the cloud is mostly its points), at least half as many as
        this cloud, no more than it can hold, and the two agree at every quantile. The count
        matters: rooms look alike in their distances, and a sparse map of the room matched the
        measured map of the whole room at a ratio of 0.6 for a true 3.5 (scale 4.7 times off).
        ``into`` None: the cloud is in a frame no known map has, and every map is tried."""
        n_into = self._sizes.get(into, (0, None))[0]
        quantiles = None
        ratios = {}
        for k, (n_k, _) in self._sizes.items():
            if k == into or n_k <= n_into:
                continue
            if quantiles is None:
                quantiles = self._distance_quantiles(points)
            ratio = self._units_ratio(k, points, quantiles)
            if ratio is not None:
                ratios[k] = ratio
        return ratios

    def _units_ratio(self, k, points, quantiles):
        """Units of the cloud ``points`` (distance quantiles ``quantiles``) per unit of map k, if
        the cloud is mostly k's points and holds them all (see ``_units_ratios``), else None."""
        n_k, sample = self._sizes[k]
        if n_k < max(50, 0.5 * len(points)) or len(points) < _MERGED_KEEPS_SHARE * n_k:
            return None
        r = quantiles / self._distance_quantiles(sample)
        if np.all(np.isfinite(r)) and np.min(r) > 0 \
                and np.max(r) <= (1.0 + self._cfg.merge_scale_tolerance) * np.min(r):
            return float(np.median(r))
        return None

    def _distance_quantiles(self, points):
        if len(points) > _SIZE_SAMPLE_POINTS:
            points = points[self._rng.choice(len(points), _SIZE_SAMPLE_POINTS, replace=False)]
        return np.quantile(pdist(points), _SIZE_QUANTILES)

    def _merged_into(self, current_index, tree):
        """The earlier map whose kept points reappear in the cloud of tree, if any (asked when
        the current map's own do not)."""
        shares = {k: self._share_in(k, tree) for k in self._samples if k != current_index}
        best = max(shares, key=shares.get)
        return best if shares[best] >= self._cfg.merge_min_share else None

    def _share_in(self, index, tree):
        kept = self._samples.get(index)
        if kept is None or tree is None:
            return 0.0
        sample, radius = kept
        distances, _ = tree.query(sample, distance_upper_bound=radius)
        return float(np.mean(np.isfinite(distances)))

    def _keep(self, index, points):
        n = min(len(points), max(self._cfg.merge_sample_points, _SIZE_SAMPLE_POINTS))
        chosen = points[self._rng.choice(len(points), n, replace=False)]  # in random order
        size = float(np.median(np.linalg.norm(points - np.median(points, axis=0), axis=1)))
        self._samples[index] = (chosen[:self._cfg.merge_sample_points],
                                max(size, 1e-9) * self._cfg.merge_match_tolerance)
        self._sizes[index] = (len(points), chosen[:_SIZE_SAMPLE_POINTS])
        self.last_index = index


def odometry_camera_position(base_position, base_quaternion, t_base_cam):
    """Where the camera is (m, odometry frame) for a base pose from wheel odometry: SLAM tracks
    the camera, and a camera ahead of the turning axis moves when the base turns on the spot, so
    base displacements against camera displacements bias the scale (35 % low with turns on the
    spot in the ground robot's scan)."""
    rot = quaternion_to_matrix(base_quaternion)
    return np.asarray(base_position, dtype=float) + rot @ np.asarray(t_base_cam)[:3, 3]


class ScaleEstimator:
    """Metres per SLAM unit from pairs (SLAM distance, metric distance), robust to outliers."""

    def __init__(self, prior_metres_per_unit=1.0, min_metric_m=0.15, max_samples=50):
        self._prior = float(prior_metres_per_unit)
        self._min_metric_m = float(min_metric_m)
        self._ratios = []
        self._max = int(max_samples)

    def add(self, slam_units, metric_m):
        """Adds one measured motion; returns False when it is too short or degenerate to use."""
        if not (np.isfinite(slam_units) and np.isfinite(metric_m)):
            return False
        if metric_m < self._min_metric_m or slam_units <= 1e-9:
            return False
        self._ratios.append(metric_m / slam_units)
        del self._ratios[:-self._max]
        return True

    def fresh(self):
        """An estimator for a new SLAM map, which has its own scale: no samples, this one's value
        as its prior."""
        return ScaleEstimator(self.estimate()[0], self._min_metric_m, self._max)

    def absorbing(self, other, factor):
        """This map's estimator after SLAM merged the map of ``other`` into it: other's samples
        times ``factor`` (the merge's ratio of the two maps' metres per unit), then this one's
        own, which the sample limit keeps first."""
        merged = ScaleEstimator(self._prior, self._min_metric_m, self._max)
        merged._ratios = ([r * factor for r in other._ratios] + self._ratios)[-self._max:]
        return merged

    def estimate(self):
        """(metres_per_unit, confidence in [0, 1], n_samples)."""
        n = len(self._ratios)
        if n == 0:
            return self._prior, 0.0, 0
        r = np.sort(self._ratios)
        # The lower median: with two samples the median is their mean, and one move read short
        # (a stale end pose: ratios of 30 against 3) made the map ten times too large, every
        # step then looked like a map switch and the bridge started a new map every 2 s.
        med = float(r[(n - 1) // 2])
        spread = float(np.median(np.abs(r - med))) / med if med > 0 else 1.0
        confidence = (n / (n + 3.0)) * max(0.0, 1.0 - 5.0 * spread)
        return med, float(confidence), n


class MapScales:
    """One ScaleEstimator per SLAM map, following MapAnchors' events. A map SLAM merges back
    into keeps its own samples; one estimator shared by all maps restarted there from a single
    sample (16 % off after merges in the stressed drone runs)."""

    def __init__(self, prior_metres_per_unit=1.0):
        self.current = ScaleEstimator(prior_metres_per_unit)
        self._by_map = {}

    def on_map_event(self, index, event):
        """The anchor event of MapAnchors.update for the map ``index`` (None: no change). Every
        map switched to began with a "first" or "new_map" event."""
        if event == "new_map":
            self.current = self.current.fresh()
        if event in ("first", "new_map"):
            self._by_map[index] = self.current
        elif event == "switched":
            self.current = self._by_map[index]

    def on_merge(self, merge):
        """SLAM merged map ``merge.left`` into ``merge.into``, which keeps its frame and scale.
        The scale samples of the best measured map the merged cloud holds carry over, converted
        by the measured ratio of units, when it has more than the merged map: a map begun in a
        loss and never measured, into which SLAM merged the map measured all along, kept the
        scale guessed at its start (a ground robot finds no floor in a cloud scaled 50 % wrong,
        and so never measured it again). Returns the map whose samples carried over, or None.

        When the map's points moved into a frame the bridge does not know (``left == into``), its
        own samples are in units it no longer has: the best measured map's converted samples
        replace them (its own, when the cloud matches its last one), or none do when no ratio
        was measured."""
        into = self._by_map.get(merge.into)
        if into is None:
            return None
        counts = {k: self._by_map[k].estimate()[2] for k in merge.units_ratios
                  if k in self._by_map}
        source = max(counts, key=counts.get) if counts else None
        if merge.left == merge.into:
            base = into.fresh()
        elif source is None or counts[source] <= into.estimate()[2]:
            return None
        else:
            base = into
        if source is not None:
            base = base.absorbing(self._by_map[source], 1.0 / merge.units_ratios[source])
        self._by_map[merge.into] = base
        if self.current is into:
            self.current = base
        return source


_MOVE = re.compile(r"^\s*(forward|back|left|right|up|down)\s+(\d+)\s*$")


class DroneMoveScale:
    """Pairs Tello move commands with their answers to measure SLAM units per commanded metre.

    The drone executes commands one after another, so a command starts when the previous one
    answered (or when it is sent to an idle drone) and ends at its own answer. The move's end is
    the first camera pose after the answer: the pose at hand when the answer arrives may still
    be on its way along the move (up to a camera frame late, 10 % of a 0.3 m move). Commands and
    answers travel on two topics, so an answer can overtake its own command; such an answer is
    kept and closes the next command, so that later answers still pair with their own commands.
    An answer with no command before it may also answer a command this node never heard (sent
    before it subscribed). Then a second answer comes before the next command, and it is the
    answer of the command thought answered: taking it as such puts the pairing back in step.
    """

    def __init__(self):
        self._pending = []
        self._start_pose = None
        self._early_answers = 0
        self._open_move = None  # (start position, metres) awaiting the pose after its answer
        self._settling = False  # an answer came: the next pose is where the drone stopped
        self._thought_answered = None  # (command, start) closed by an early answer, until the next

    def on_command(self, text, current_position):
        if self._early_answers:
            self._early_answers -= 1  # answered already, unless another answer comes first
            self._start_pose = current_position
            self._thought_answered = (text.strip(), current_position)
            return
        self._thought_answered = None
        self._pending.append(text.strip())
        if len(self._pending) == 1:
            self._start_pose = current_position

    def invalidate(self):
        """Tracking was lost or the map changed: the running command's start pose is unusable."""
        self._start_pose = None
        self._open_move = None
        self._settling = False
        self._thought_answered = None

    def on_response(self, response, current_position):
        """Notes the answer; a successful move with a known start waits for on_pose."""
        if self._pending:
            command = self._pending.pop(0)
            start = self._start_pose
        elif self._thought_answered is not None:
            (command, start), self._thought_answered = self._thought_answered, None
        else:
            self._early_answers += 1
            return
        self._start_pose = current_position
        self._settling = True
        match = _MOVE.match(command)
        self._open_move = None
        if match and response.strip().lower() == "ok" and start is not None:
            self._open_move = (np.asarray(start, dtype=float), int(match.group(2)) / 100.0)

    def on_pose(self, position):
        """Returns (slam_units, metric_m) when this pose ends an answered move, else None."""
        if not self._settling or position is None:
            return None
        self._settling = False
        if self._pending:
            self._start_pose = position  # the next command started from here
        if self._open_move is None:
            return None
        (start, metric), self._open_move = self._open_move, None
        return float(np.linalg.norm(np.asarray(position, dtype=float) - start)), metric