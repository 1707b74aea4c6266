"""Map-switch bookkeeping of the cartographer (seed 004): one fragment per SLAM map.

ORB-SLAM3 keeps an atlas: after a tracking loss it starts a new map, and it merges a map back into
an earlier one when it recognises the place. The cartographer follows ``slam/state``: the map
being built is the current fragment (the latest point cloud of that SLAM map, which the wrapper
publishes whole); on a new map the old fragment is saved and kept, on a merge the current fragment
is combined into the earlier one. Fragments are saved as they change (at most every
``save_period_s``) and on every switch, never only at shutdown. Fragment names carry a session
number so a restart (with a fresh SLAM atlas) never overwrites an earlier run's maps.
"""
import dataclasses
import re

import numpy as np

from sparse_nav.cartographer.store import FragmentError, FragmentStore, validate_name
from sparse_nav.slam_bridge import NEW_MAP, OK

_AUTO_NAME = re.compile(r"s(\d{3,})_map(\d{3,})")


def auto_name(session, map_index):
    """Name of the automatic fragment of SLAM map ``map_index`` in ``session``."""
    return f"s{session:03d}_map{map_index:03d}"


@dataclasses.dataclass
class CartographerConfig:
    """Parameters of the cartographer; defaults are written here once."""

    map_dir: str = "~/.ros/sparse_nav/maps"
    save_period_s: float = 5.0       # a changed fragment is written at most this often (s)
    merge_voxel_m: float = 0.05      # merged fragments keep one point per voxel of this size (m)
    max_points: int = 5000000        # larger clouds are refused
    frame: str = "map"               # frame of the stored points (recorded in each file)

    def validate(self):
        if not self.save_period_s > 0:
            raise ValueError(f"save_period_s must be > 0, got {self.save_period_s}")
        if not self.merge_voxel_m > 0:
            raise ValueError(f"merge_voxel_m must be > 0, got {self.merge_voxel_m}")
        if self.max_points < 1:
            raise ValueError(f"max_points must be >= 1, got {self.max_points}")


@dataclasses.dataclass
class Fragment:
    """The points (m, in ``frame``) of one SLAM map of this session.

    ``latest`` is the map's latest whole cloud; ``absorbed`` holds the points of the maps merged
    into it, which the wrapper's cloud of this map need not contain.
    """

    name: str
    map_index: int
    latest: np.ndarray
    absorbed: np.ndarray = dataclasses.field(default_factory=lambda: np.empty((0, 3)))
    merged_from: list = dataclasses.field(default_factory=list)
    stamp_s: float = 0.0
    dirty: bool = False
    voxel_m: float = 0.05

    @property
    def points(self):
        if len(self.absorbed) == 0:
            return self.latest
        return voxel_unique(np.vstack([self.absorbed, self.latest]), self.voxel_m)


def voxel_unique(points, voxel_m):
    """``points`` with one point kept per cubic voxel of edge ``voxel_m`` (first one wins)."""
    if len(points) == 0:
        return points
    keys = np.floor(points / voxel_m).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return points[np.sort(first)]


class Cartographer:
    """Follows SLAM map switches and keeps the fragments of each map on disk."""

    def __init__(self, config=None):
        self.cfg = config or CartographerConfig()
        self.cfg.validate()
        self.store = FragmentStore(self.cfg.map_dir)
        self.removed_temporaries = self.store.remove_stale_temporaries()
        self.library = {}          # name -> (points, meta) of the fragments loaded from disk
        self.load_errors = {}      # name -> why it was refused
        self.session = 1
        self.fragments = {}        # map_index -> Fragment of this session
        self.current = None
        self.switch_stamp_s = float("-inf")
        self.last_save_s = None

    def reload(self):
        """Load every fragment in map_dir; corrupt ones are reported in load_errors and skipped.

        Returns the names loaded. The next session number follows the highest one on disk.
        """
        self.library.clear()
        self.load_errors.clear()
        highest = 0
        for name in self.store.names():
            match = _AUTO_NAME.fullmatch(name)
            if match:
                highest = max(highest, int(match.group(1)))
            try:
                self.library[name] = self.store.load(name)
            except FragmentError as exc:
                self.load_errors[name] = str(exc)
        self.session = highest + 1
        return sorted(self.library)

    def on_slam_state(self, state, map_index, stamp_s):
        """Follow a ``slam/state`` message; returns a list of what happened (text)."""
        # slam_bridge numbers its maps from 0, so index 0 is the first map, not "none".
        if state not in (OK, NEW_MAP) or map_index < 0:
            return []
        if self.current is None:
            self.current = self._fragment(map_index)
            self.switch_stamp_s = stamp_s
            return [f"following SLAM map {map_index} as {self.current.name}"]
        if map_index == self.current.map_index:
            return []
        events = []
        old = self.current
        self.switch_stamp_s = stamp_s
        if map_index in self.fragments:
            target = self.fragments[map_index]
            if len(old.points):
                target.absorbed = voxel_unique(np.vstack([target.absorbed, old.points]),
                                               self.cfg.merge_voxel_m)
                target.merged_from = sorted(set(target.merged_from + old.merged_from
                                                + [old.name]))
                target.stamp_s = max(target.stamp_s, old.stamp_s)
                target.dirty = True
            # The combined fragment is durable before the merged one disappears.
            self._save(target, stamp_s)
            self.store.delete(old.name)
            del self.fragments[old.map_index]
            events.append(f"SLAM merged map {old.map_index} into map {map_index}: "
                          f"{old.name} combined into {target.name} ({len(target.points)} points)")
            self.current = target
        else:
            if old.dirty:
                self._save(old, stamp_s)
            events.append(f"SLAM started map {map_index}: kept {old.name} "
                          f"({len(old.points)} points)")
            self.current = self._fragment(map_index)
        return events

    def on_cloud(self, points, stamp_s):
        """Take the latest whole cloud of the current SLAM map (N, 3 m in ``frame``).

        Returns False (and changes nothing) when there is no current map yet or the cloud is
        older than the last map switch. Raises FragmentError for a malformed cloud.
        """
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise FragmentError(f"cloud must be (N, 3), got shape {pts.shape}")
        if len(pts) > self.cfg.max_points:
            raise FragmentError(f"cloud of {len(pts)} points exceeds max_points "
                                f"{self.cfg.max_points}")
        if not np.all(np.isfinite(pts)):
            raise FragmentError("cloud contains NaN or Inf points")
        if self.current is None or stamp_s < self.switch_stamp_s:
            return False
        self.current.latest = pts
        self.current.stamp_s = stamp_s
        self.current.dirty = True
        return True

    def save_due(self, now_s):
        """Save the changed fragments if save_period_s has passed since the last save."""
        if self.last_save_s is not None and now_s - self.last_save_s < self.cfg.save_period_s:
            return []
        return self.flush(now_s)

    def flush(self, now_s):
        """Save every changed fragment now; returns their names."""
        saved = []
        for fragment in self.fragments.values():
            if fragment.dirty:
                self._save(fragment, now_s)
                saved.append(fragment.name)
        return saved

    def save_as(self, name, now_s):
        """Write the current fragment also under ``name``; returns its point count."""
        validate_name(name)
        points = self.current.points if self.current is not None else np.empty((0, 3))
        if len(points) == 0:
            raise FragmentError("no current map to save yet")
        meta = self._meta(self.current, now_s)
        self.store.save(name, points, meta)
        self.library[name] = (points, meta)
        return len(points)

    def load(self, name):
        """(points, meta) of fragment ``name`` read and verified from disk."""
        points, meta = self.store.load(name)
        self.library[name] = (points, meta)
        self.load_errors.pop(name, None)
        return points, meta

    def list(self):
        """[(name, n_points or None, error or "")] of every fragment file, each verified."""
        out = []
        for name in self.store.names():
            try:
                points, _ = self.store.load(name)
                out.append((name, len(points), ""))
            except FragmentError as exc:
                out.append((name, None, str(exc)))
        return out

    def _fragment(self, map_index):
        fragment = Fragment(auto_name(self.session, map_index), map_index, np.empty((0, 3)),
                            voxel_m=self.cfg.merge_voxel_m)
        self.fragments[map_index] = fragment
        return fragment

    def _meta(self, fragment, now_s):
        return {"session": self.session, "map_index": fragment.map_index,
                "frame": self.cfg.frame, "stamp_s": fragment.stamp_s, "saved_at_s": now_s,
                "merged_from": list(fragment.merged_from)}

    def _save(self, fragment, now_s):
        points, meta = fragment.points, self._meta(fragment, now_s)
        self.store.save(fragment.name, points, meta)
        self.library[fragment.name] = (points, meta)
        fragment.dirty = False
        self.last_save_s = now_s
