"""Emulation of ORB-SLAM3 monocular tracking and mapping on simulated feature detections.

What it reproduces (DESIGN.md section 5):
  * Initialisation needs baseline: NOT_INITIALIZED until the camera has moved far enough from a
    reference frame relative to the depth of the features both frames see; rotation alone does
    not initialise.
  * The SLAM world frame of a map is the optical frame of that map's reference camera, with an
    unknown scale (SLAM units per metre) drawn per map, drifting as a random walk with distance.
  * Map points appear once a feature has been seen from two views with enough parallax; their
    positions carry depth-dependent noise, and a few are spurious outliers.
  * Tracking is lost with too few tracked map points or too fast a turn: RECENTLY_LOST
    (relocalisation in the same map still possible), then LOST, then a new map with a new id,
    origin and scale, which merges back into an earlier map when it sees enough of its points.

Frames and units: world frame in metres (z up); a map's SLAM frame p_slam = s * R_o^T (p_w - t_o)
+ b, where (R_o, t_o) is the map's origin camera pose in the world, s its current scale (SLAM
units per metre) and b the offset accumulated by scale drift (zero at initialisation).
"""
import dataclasses
import enum
import math

import numpy as np


class TrackingState(enum.IntEnum):
    """ORB-SLAM3's Tracking::eTrackingState values."""

    SYSTEM_NOT_READY = -1
    NO_IMAGES_YET = 0
    NOT_INITIALIZED = 1
    OK = 2
    RECENTLY_LOST = 3
    LOST = 4


@dataclasses.dataclass
class SlamOutput:
    """What ORB-SLAM3 reports after one camera frame.

    Attributes:
      stamp_s: simulation time of the frame (s).
      state: tracking state.
      map_id: id of the active map (0, 1, 2, ...; after a merge, the id merged into).
      T_slam_camera: 4x4 pose of the camera optical frame in the SLAM world frame (translation in
        SLAM units), or None when not tracking (state != OK).
      all_points: (N, 3) float32 points of the active map, SLAM frame and units (read-only).
      tracked_points: (M, 3) float32 map points matched in this frame, SLAM frame and units.
      n_tracked: number of map points matched in this frame (M).
      merged: True on the frame a map merge happened.
    """

    stamp_s: float
    state: TrackingState
    map_id: int
    T_slam_camera: object
    all_points: np.ndarray
    tracked_points: np.ndarray
    n_tracked: int
    merged: bool = False


_EMPTY = np.zeros((0, 3), dtype=np.float32)
_EMPTY.setflags(write=False)


class SlamMap:
    """One ORB-SLAM map of the atlas: its ground-truth frame and its points.

    Attributes:
      map_id: id of the map.
      T_world_origin: 4x4 pose (m) of the reference camera optical frame in the world.
      scale: current SLAM units per metre (drifts while tracking).
      offset: (3,) SLAM-unit offset accumulated by scale drift.
      points: (N_features, 3) SLAM-frame position of each feature's map point (NaN if none).
      has_point: (N_features,) bool, the feature is a map point of this map.
      first_seen: (N_features, 3) world camera centre (m) where the feature was first seen
        while this map was active (NaN if not yet); the first view of a triangulation pair.
      noise: (N_features, 4) standard-normal draws of each point's error (along the ray,
        lateral x, y, z), kept so that refining a point shrinks its error instead of redrawing.
      sigma_px: (N_features,) image noise of each point's keypoint (px).
      parallax: (N_features,) triangulation angle (rad) of each point's current estimate.
      outlier: (N_features,) bool, the point is a spurious match (never refined).
      created_s: time of initialisation (s).
    """

    def __init__(self, map_id, n_features, T_world_origin, scale, created_s):
        self.map_id = map_id
        self.T_world_origin = np.array(T_world_origin, dtype=float)
        self.scale = float(scale)
        self.offset = np.zeros(3)
        self.points = np.full((n_features, 3), np.nan)
        self.has_point = np.zeros(n_features, dtype=bool)
        self.first_seen = np.full((n_features, 3), np.nan)
        self.noise = np.zeros((n_features, 4))
        self.sigma_px = np.zeros(n_features)
        self.parallax = np.zeros(n_features)
        self.outlier = np.zeros(n_features, dtype=bool)
        self.created_s = created_s
        self._cache = None

    @property
    def _rot(self):
        return self.T_world_origin[:3, :3]

    @property
    def _trans(self):
        return self.T_world_origin[:3, 3]

    def to_slam(self, p_world):
        """World points (..., 3) in metres -> this map's SLAM frame (units), current scale."""
        return self.scale * ((np.asarray(p_world) - self._trans) @ self._rot) + self.offset

    def to_world(self, p_slam):
        """This map's SLAM points (..., 3) -> world frame (m), current scale and offset."""
        return ((np.asarray(p_slam) - self.offset) / self.scale) @ self._rot.T + self._trans

    def camera_pose(self, T_world_camera):
        """4x4 pose of a camera in this map's SLAM frame (translation in SLAM units)."""
        t = np.eye(4)
        t[:3, :3] = self._rot.T @ T_world_camera[:3, :3]
        t[:3, 3] = self.to_slam(T_world_camera[:3, 3])
        return t

    def drift(self, camera_xyz, factor):
        """Change the scale by ``factor`` while keeping the camera's SLAM position continuous."""
        before = self.to_slam(camera_xyz)
        self.scale *= factor
        self.offset += before - self.to_slam(camera_xyz)

    def add_points(self, idx, p_slam):
        """Make features idx map points at the given SLAM positions."""
        if len(idx):
            self.points[idx] = p_slam
            self.has_point[idx] = True
            self._cache = None

    def take_points(self, other, idx):
        """Copy map points idx from another map into this one (a merge), re-expressed from the
        other map's SLAM frame into this one's through the world frame."""
        if len(idx):
            self.add_points(idx, self.to_slam(other.to_world(other.points[idx])))
            for name in ("noise", "sigma_px", "parallax", "outlier"):
                getattr(self, name)[idx] = getattr(other, name)[idx]

    def all_points(self):
        """All points of the map, (N, 3) float32 read-only array in SLAM units."""
        if self._cache is None:
            pts = self.points[self.has_point].astype(np.float32)
            pts.setflags(write=False)
            self._cache = pts
        return self._cache


class MonocularSlam:
    """Frame-by-frame ORB-SLAM3 monocular emulator.

    Args:
      features: (N, 3) world-frame feature positions (m); feature i is map point i when mapped.
      config: a SimConfig (reads the ``slam_*`` fields and ``force_loss_at_s``).
      rng: numpy Generator for scales, drift, noise, outliers and pose jitter.
    """

    def __init__(self, features, config, rng):
        self.features = np.asarray(features, dtype=float)
        self.cfg = config
        self.rng = rng
        self.state = TrackingState.NO_IMAGES_YET
        self.active = None                  # SlamMap being tracked/initialised, or None
        self.old_maps = {}                  # map_id -> SlamMap, candidates for merging
        self.map_id = 0                     # id of the active (or initialising) map
        self._next_id = 1
        self._reference = None              # (T_world_camera, visible ids) of the init reference
        self._last_centre = None            # last tracked camera centre (m), for drift
        self._lost_since_s = None
        self._lost_frames = 0
        self._pending_losses = sorted(float(t) for t in config.force_loss_at_s)
        self._blind_until_s = -math.inf
        self.tracking_losses = 0
        self.last_loss_cause = ""           # why tracking was last lost, in words (diagnostics)

    # -- ground truth -------------------------------------------------------------------------

    def true_scale_m_per_unit(self):
        """Metres per SLAM unit of the active map, NaN before it is initialised."""
        return math.nan if self.active is None else 1.0 / self.active.scale

    def origin_world(self):
        """4x4 T_world_slamWorld of the active map, None before it is initialised."""
        return None if self.active is None else self.active.T_world_origin.copy()

    # -- per-frame update ---------------------------------------------------------------------

    def process_frame(self, stamp_s, T_world_camera, visible, turn_rate_rad_s):
        """Update with one camera frame and return its :class:`SlamOutput`.

        Args:
          stamp_s: frame time (s).
          T_world_camera: true 4x4 camera optical pose in the world (m).
          visible: sorted int array of detected feature indices.
          turn_rate_rad_s: camera rotation rate since the previous frame (rad/s).
        """
        # A forced loss waits until there is tracking to lose (a test that forces one mid-scan
        # must get one even when the map initialised late).
        forced = False
        tracking = self.state in (TrackingState.OK, TrackingState.RECENTLY_LOST)
        while tracking and self._pending_losses and self._pending_losses[0] <= stamp_s + 1e-9:
            self._pending_losses.pop(0)
            forced = True
        fast_turn = turn_rate_rad_s > self.cfg.slam_max_turn_rate_rad_s
        centre = T_world_camera[:3, 3]
        visible = np.asarray(visible, dtype=np.int64)

        if self.state == TrackingState.NO_IMAGES_YET:
            self.state = TrackingState.NOT_INITIALIZED
        if forced:
            # A forced loss blinds the camera for a while (covered lens, motion blur), so that the
            # loss is seen by every consumer rather than relocalised within a frame or two.
            self._blind_until_s = stamp_s + self.cfg.force_loss_duration_s
        if forced and self.state in (TrackingState.OK, TrackingState.RECENTLY_LOST):
            return self._enter_lost(stamp_s)
        if stamp_s < self._blind_until_s:
            self._reference = None  # nothing to match while blind: initialisation restarts
            return self._output(stamp_s, TrackingState.LOST)

        if self.state == TrackingState.NOT_INITIALIZED:
            return self._initialise(stamp_s, T_world_camera, visible, fast_turn)
        if self.state == TrackingState.LOST:
            return self._lost_frame(stamp_s)
        if self.state == TrackingState.RECENTLY_LOST:
            n = int(np.count_nonzero(self.active.has_point[visible]))
            if n >= self.cfg.slam_reloc_min_tracked and not fast_turn:
                self.state = TrackingState.OK      # relocalised in the same map
                self._last_centre = centre.copy()
            elif stamp_s - self._lost_since_s > self.cfg.slam_recently_lost_s:
                self.state = TrackingState.LOST
                self._lost_frames = 0
                return self._lost_frame(stamp_s)
            else:
                return self._output(stamp_s, TrackingState.RECENTLY_LOST)
        return self._track(stamp_s, T_world_camera, visible, fast_turn, turn_rate_rad_s)

    def _initialise(self, stamp_s, T_world_camera, visible, fast_turn):
        cfg = self.cfg
        centre = T_world_camera[:3, 3]
        if self._reference is None:
            if len(visible) >= cfg.slam_init_min_shared:
                self._reference = (T_world_camera.copy(), visible)
            return self._output(stamp_s, TrackingState.NOT_INITIALIZED)
        T_ref, ref_vis = self._reference
        shared = np.intersect1d(ref_vis, visible, assume_unique=True)
        if len(shared) < cfg.slam_init_min_shared:
            # Too few matches with the reference: ORB-SLAM restarts the initialiser here.
            self._reference = (T_world_camera.copy(), visible) \
                if len(visible) >= cfg.slam_init_min_shared else None
            return self._output(stamp_s, TrackingState.NOT_INITIALIZED)
        ref_centre = T_ref[:3, 3]
        depth = np.median(np.linalg.norm(self.features[shared] - ref_centre, axis=1))
        parallax = np.linalg.norm(centre - ref_centre) / max(depth, 1e-9)
        if parallax < cfg.slam_init_min_parallax or fast_turn:
            return self._output(stamp_s, TrackingState.NOT_INITIALIZED)
        lo, hi = cfg.slam_scale_range_m_per_unit
        m_per_unit = math.exp(self.rng.uniform(math.log(lo), math.log(hi)))
        slam_map = SlamMap(self.map_id, len(self.features), T_ref, 1.0 / m_per_unit, stamp_s)
        slam_map.first_seen[ref_vis] = ref_centre
        slam_map.first_seen[visible[np.isnan(slam_map.first_seen[visible, 0])]] = centre
        slam_map.add_points(shared, self._triangulate(
            slam_map, shared, centre, _ray_angles(self.features[shared], ref_centre, centre)))
        self.active = slam_map
        self._reference = None
        self._last_centre = centre.copy()
        self.state = TrackingState.OK
        tracked = shared
        return self._output(stamp_s, TrackingState.OK, T_world_camera, tracked)

    def _track(self, stamp_s, T_world_camera, visible, fast_turn, turn_rate_rad_s):
        cfg = self.cfg
        m = self.active
        centre = T_world_camera[:3, 3]
        travelled = float(np.linalg.norm(centre - self._last_centre))
        if travelled > 0 and cfg.slam_scale_drift_per_sqrt_m > 0:
            m.drift(centre, math.exp(cfg.slam_scale_drift_per_sqrt_m * math.sqrt(travelled)
                                     * self.rng.standard_normal()))
        self._last_centre = centre.copy()
        tracked = visible[m.has_point[visible]]
        if len(tracked) < cfg.slam_min_tracked or fast_turn:
            self.last_loss_cause = (
                f"turn at {math.degrees(turn_rate_rad_s):.0f} deg/s" if fast_turn
                else f"{len(tracked)} map points among {len(visible)} features in view")
            self.tracking_losses += 1
            pose_lost = len(tracked) < cfg.slam_pose_min_tracked or fast_turn
            if pose_lost and stamp_s - m.created_s < cfg.slam_young_map_s:
                # ORB-SLAM3: a frame whose pose is not found relocalises only in a map of more
                # than 10 keyframes; one whose pose is found but too few points confirm it
                # (TrackLocalMap) is recently lost in any map.
                self.state = TrackingState.LOST
                self._lost_frames = 0
                return self._lost_frame(stamp_s)
            self.state = TrackingState.RECENTLY_LOST
            self._lost_since_s = stamp_s
            return self._output(stamp_s, TrackingState.RECENTLY_LOST)
        # New map points: features seen before in this map from a view with enough parallax.
        cand = visible[~m.has_point[visible]]
        first = m.first_seen[cand]
        unseen = np.isnan(first[:, 0])
        m.first_seen[cand[unseen]] = centre
        cand, first = cand[~unseen], first[~unseen]
        if len(cand):
            angles = _ray_angles(self.features[cand], first, centre)
            ok = angles > math.radians(cfg.slam_new_point_min_parallax_deg)
            m.add_points(cand[ok], self._triangulate(m, cand[ok], centre, angles[ok]))
        self._refine(m, tracked, centre)
        merged = self._maybe_merge(stamp_s, visible, centre)
        m = self.active
        tracked = visible[m.has_point[visible]]
        return self._output(stamp_s, TrackingState.OK, T_world_camera, tracked, merged)

    def _maybe_merge(self, stamp_s, visible, centre):
        """Merge the active map into the earlier map it sees most of, if enough (place
        recognition); the merged map keeps the earlier map's id, frame and scale."""
        cfg = self.cfg
        m = self.active
        if not self.old_maps or stamp_s - m.created_s < cfg.slam_merge_min_map_age_s:
            return False
        counts = {k: int(np.count_nonzero(old.has_point[visible]))
                  for k, old in self.old_maps.items()}
        best = max(counts, key=lambda k: (counts[k], -k))
        if counts[best] < cfg.slam_merge_min_shared:
            return False
        old = self.old_maps.pop(best)
        # Sim(3) from the active map to the old one, at both maps' current scales.
        old.take_points(m, np.flatnonzero(m.has_point & ~old.has_point))
        fill = np.isnan(old.first_seen[:, 0]) & ~np.isnan(m.first_seen[:, 0])
        old.first_seen[fill] = m.first_seen[fill]
        self.active = old
        self.map_id = old.map_id
        self._last_centre = centre.copy()
        return True

    def _enter_lost(self, stamp_s):
        if self.state == TrackingState.OK:
            self.tracking_losses += 1
            self.last_loss_cause = "forced"
        self.state = TrackingState.LOST
        self._lost_frames = 0
        return self._lost_frame(stamp_s)

    def _lost_frame(self, stamp_s):
        """One LOST frame; after enough of them the atlas starts a new, empty map."""
        self._lost_frames += 1
        out = self._output(stamp_s, TrackingState.LOST)
        if self._lost_frames >= self.cfg.slam_lost_frames_before_new_map:
            # A map too small to ever be merged into is dropped (ORB-SLAM3 resets such maps).
            if self.active is not None and np.count_nonzero(
                    self.active.has_point) >= self.cfg.slam_merge_min_shared:
                self.old_maps[self.active.map_id] = self.active
            self.active = None
            self.map_id = self._next_id
            self._next_id += 1
            self._reference = None
            self.state = TrackingState.NOT_INITIALIZED
        return out

    def _triangulate(self, slam_map, idx, centre, parallax_rad):
        """SLAM positions of new map points for features idx, seen from camera centre (m) after
        a triangulation angle parallax_rad (rad) between two views. Draws and stores each
        point's noise (see :meth:`_estimate`); a few points are spurious outliers anywhere along
        the ray, some far behind the surface."""
        cfg = self.cfg
        n = len(idx)
        if n == 0:
            return np.zeros((0, 3))
        slam_map.noise[idx] = self.rng.standard_normal((n, 4))
        # ORB keypoints come from an 8-level pyramid (factor 1.2): coarser levels, larger noise.
        slam_map.sigma_px[idx] = cfg.slam_depth_noise_px * 1.2 ** self.rng.integers(0, 8, n)
        slam_map.parallax[idx] = parallax_rad
        out = self.rng.random(n) < cfg.slam_outlier_fraction
        slam_map.outlier[idx] = out
        p_world = self._estimate(slam_map, idx, centre)
        if np.any(out):
            far = self.rng.random(n) < cfg.slam_outlier_far_fraction
            factor = np.where(far, np.exp(self.rng.uniform(math.log(1.6), math.log(8.0), n)),
                              np.exp(self.rng.uniform(math.log(0.2), math.log(1.6), n)))
            p_world[out] = centre + (self.features[idx[out]] - centre) * factor[out, None]
        return slam_map.to_slam(p_world)

    def _estimate(self, slam_map, idx, centre):
        """World position (m) of map points idx as triangulated from camera centre (m).

        Triangulation with image noise sigma_px on a focal length f (px) and parallax angle a
        has a depth error sigma = depth * sigma_px / (f * a) = depth^2 * sigma_px /
        (f * baseline): it grows with depth^2 for a given baseline. Its floor stands for what
        two-view geometry leaves out (pose error, motion blur, duplicate points of one
        feature). Lateral error is small.
        """
        cfg = self.cfg
        true = self.features[idx]
        ray = true - centre
        depth = np.linalg.norm(ray, axis=1)
        unit = ray / np.maximum(depth, 1e-9)[:, None]
        focal_px = cfg.camera_width_px / 2.0 / math.tan(math.radians(cfg.camera_hfov_deg) / 2.0)
        rel = np.clip(slam_map.sigma_px[idx] / (focal_px * np.maximum(
            slam_map.parallax[idx], 1e-6)), cfg.slam_min_relative_depth_noise,
            cfg.slam_max_relative_depth_noise)
        noise = slam_map.noise[idx]
        along = np.maximum(rel * noise[:, 0], -0.8)       # never through the camera
        return (true + unit * (depth * along)[:, None]
                + noise[:, 1:] * (cfg.slam_lateral_noise_rad * depth)[:, None])

    def _refine(self, slam_map, tracked, centre):
        """Local bundle adjustment, emulated: a tracked point whose views now span a much wider
        angle than when it was triangulated is re-estimated with that angle (less noise)."""
        idx = tracked[~slam_map.outlier[tracked]]
        if len(idx) == 0:
            return
        angles = _ray_angles(self.features[idx], slam_map.first_seen[idx], centre)
        better = angles > self.cfg.slam_refine_parallax_factor * slam_map.parallax[idx]
        idx = idx[better]
        if len(idx):
            slam_map.parallax[idx] = angles[better]
            slam_map.add_points(idx, slam_map.to_slam(self._estimate(slam_map, idx, centre)))

    def _output(self, stamp_s, state, T_world_camera=None, tracked=None, merged=False):
        m = self.active
        all_pts = m.all_points() if m is not None else _EMPTY
        if state != TrackingState.OK:
            return SlamOutput(stamp_s, state, self.map_id, None, all_pts, _EMPTY, 0, merged)
        pose = m.camera_pose(T_world_camera)
        cfg = self.cfg
        if cfg.slam_pose_noise_m > 0 or cfg.slam_pose_noise_deg > 0:
            pose[:3, 3] += self.rng.standard_normal(3) * cfg.slam_pose_noise_m * m.scale
            pose[:3, :3] = pose[:3, :3] @ _small_rotation(
                self.rng.standard_normal(3) * math.radians(cfg.slam_pose_noise_deg))
        tracked_pts = m.points[tracked].astype(np.float32)
        return SlamOutput(stamp_s, state, self.map_id, pose, all_pts, tracked_pts,
                          int(len(tracked)), merged)


def _ray_angles(points, centre_a, centre_b):
    """Angles (rad) at each point (N, 3) between the rays to two camera centres ((3,) or
    (N, 3), m): the triangulation parallax."""
    a = points - centre_a
    b = points - centre_b
    cos = np.einsum("ij,ij->i", a, b) / np.maximum(
        np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-12)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _small_rotation(rotvec):
    """Rotation matrix of a rotation vector (rad), Rodrigues' formula."""
    theta = float(np.linalg.norm(rotvec))
    if theta < 1e-12:
        return np.eye(3)
    k = rotvec / theta
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(theta) * kx + (1 - math.cos(theta)) * kx @ kx
