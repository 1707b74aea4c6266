"""The navigator of seed 004, ROS-free: D* Lite on the occupancy grid with a viewing range, goal
substitution (off the map, inside an obstacle), goal persistence across SLAM losses and replanning
with hysteresis.

Frames: everything is in the map frame (metres, radians); the grid's cells follow
nav_msgs/OccupancyGrid (x = column, y = row, values 0..100 or -1 unknown).
"""
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from sparse_nav import _planning as planning
from sparse_nav.navigation.maps import GridGeometry

# Status values; sparse_nav/NavigatorStatus carries the same names in upper case.
IDLE = "idle"
PLANNING = "planning"
FOLLOWING = "following"
REACHED = "reached"
NO_PATH = "no_path"
GOAL_OFF_MAP = "goal_off_map"
GOAL_IN_OBSTACLE = "goal_in_obstacle"
LOST = "lost"
REJECTED = "rejected"

UNKNOWN_POLICIES = ("free", "costly", "blocked")


class NavigatorInputError(ValueError):
    """A map, pose or goal the navigator refuses; it keeps its last good state."""


@dataclass
class NavigatorConfig:
    robot_radius_m: float = 0.2          # cells within this distance of an obstacle are not entered
    squeeze_radius_m: float = 0.15       # no path at robot_radius_m: plan once more with this
                                         # inflation (a monocular map's walls come out thicker
                                         # than they are and narrow its doors); not below
                                         # robot_radius_m: never
    unknown_policy: str = "costly"       # unknown cells: free, costly or blocked
    unknown_cost: float = 2.0            # cost multiplier of unknown cells under "costly"
    occupied_threshold: int = 50         # OccupancyGrid values >= this are obstacles
    viewing_range_m: float = 3.0         # map changes within this range are applied at once
    goal_tolerance_m: float = 0.25       # the goal is reached within this distance
    goal_search_radius_m: float = 1.0    # goal in an obstacle: free cells this close are candidates
    replan_improvement_m: float = 0.5    # a freed shortcut replaces the path when it saves this much
    max_deviation_m: float = 0.5         # farther from the path than this: replan from the robot
    smooth_path: bool = True             # line-of-sight (string-pull) smoothing
    max_cells: int = 25000000            # larger maps are refused

    def validate(self):
        for name in ("robot_radius_m", "squeeze_radius_m", "unknown_cost", "viewing_range_m",
                     "goal_tolerance_m", "goal_search_radius_m", "replan_improvement_m",
                     "max_deviation_m"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if self.unknown_policy not in UNKNOWN_POLICIES:
            raise ValueError(f"unknown_policy must be one of {UNKNOWN_POLICIES}, "
                             f"got {self.unknown_policy!r}")
        if self.unknown_cost < 1.0:
            raise ValueError(f"unknown_cost must be >= 1, got {self.unknown_cost}")
        if not 1 <= self.occupied_threshold <= 100:
            raise ValueError(f"occupied_threshold must be in [1, 100], got {self.occupied_threshold}")
        if self.viewing_range_m <= 0:
            raise ValueError("viewing_range_m must be > 0")
        if self.max_cells < 1:
            raise ValueError("max_cells must be >= 1")


@dataclass
class Status:
    state: str
    reason: str
    path: list = field(default_factory=list)   # [(x, y), ...] in the map frame, robot first
    goal: tuple = None                         # the requested goal (x, y), None without one
    target: tuple = None                       # where the path leads (x, y), None without one
    path_length_m: float = 0.0
    plan_ms: float = 0.0                       # duration of the last search


def _compose(pose, local):
    """A point given in the frame of pose (x, y, yaw) expressed in the map frame."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return x + c * local[0] - s * local[1], y + s * local[0] + c * local[1]


def _relative(pose, point):
    """Map point expressed in the frame of pose (x, y, yaw)."""
    x, y, yaw = pose
    dx, dy = point[0] - x, point[1] - y
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


def _polyline_distance(points, p):
    """Distance from p to the polyline through points (at least one point)."""
    pts = np.asarray(points, dtype=float)
    q = np.asarray(p, dtype=float)
    if len(pts) == 1:
        return float(np.linalg.norm(pts[0] - q))
    a, b = pts[:-1], pts[1:]
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=1), 1e-18)
    t = np.clip(np.sum((q - a) * ab, axis=1) / denom, 0.0, 1.0)
    closest = a + t[:, None] * ab
    return float(np.min(np.linalg.norm(closest - q, axis=1)))


class Navigator:
    """One navigation task at a time over the latest map, following seed 004's behaviours."""

    def __init__(self, config=None):
        self.cfg = config or NavigatorConfig()
        self.cfg.validate()
        self.geometry = None
        self.latest = None       # the newest map [y, x]
        self.applied = None      # what the planner believes: latest within the viewing range
        self.pending = None      # cells where latest and applied differ
        self.grid = None         # planning grid of applied
        self.pose = None         # (x, y, yaw) of the robot in the map frame
        self.goal = None         # requested goal (x, y) in the map frame
        self.goal_relative = None    # the goal in the robot's frame at the last known pose
        self.lost = False
        self.awaiting_reanchor = False
        self.map_since_new_map = False
        self.squeezing = False   # this goal is planned with squeeze_radius_m
        self.n_replans = 0
        self._reset_task()

    def _reset_task(self):
        self.dstar = None
        self.target_cell = None
        self.target_kind = None
        self.target_reason = ""
        self.path_cells = []
        self.path_points = []    # smoothed path [(x, y)] in the map frame
        self.path_index = []     # index in path_cells of each smoothed point
        self.progress = 0
        self.needs_target = True
        self.plan_ms = 0.0

    # Inputs.

    def set_map(self, geometry, data):
        """A full map (nav_msgs/OccupancyGrid). Raises NavigatorInputError on a bad one."""
        try:
            geometry.validate(self.cfg.max_cells)
        except ValueError as exc:
            raise NavigatorInputError(f"map refused: {exc}") from None
        data = np.asarray(data, dtype=np.int8)
        if data.size != geometry.width * geometry.height:
            raise NavigatorInputError(f"map refused: {data.size} values for "
                                      f"{geometry.width} x {geometry.height} cells")
        data = data.reshape(geometry.height, geometry.width).copy()
        self.map_since_new_map = True
        if self.geometry is not None and self.geometry == geometry:
            self.latest = data
            self.pending = self.latest != self.applied
            return
        applied = data.copy()
        old = self.geometry
        if old is not None and old.resolution == geometry.resolution \
                and old.origin[2] == geometry.origin[2] == 0.0:
            sx = (old.origin[0] - geometry.origin[0]) / geometry.resolution
            sy = (old.origin[1] - geometry.origin[1]) / geometry.resolution
            if abs(sx - round(sx)) < 1e-6 and abs(sy - round(sy)) < 1e-6:
                # The same cells, moved or grown: the planner keeps its belief where the grids
                # overlap and sees the new cells as unknown; the newest values arrive through the
                # viewing range like any other change.
                sx, sy = int(round(sx)), int(round(sy))
                applied[:] = -1
                x0, y0 = max(0, sx), max(0, sy)
                x1 = min(geometry.width, sx + old.width)
                y1 = min(geometry.height, sy + old.height)
                if x0 < x1 and y0 < y1:
                    applied[y0:y1, x0:x1] = self.applied[y0 - sy:y1 - sy, x0 - sx:x1 - sx]
        self.geometry = geometry
        self.latest = data
        self.applied = applied
        self.pending = self.latest != self.applied
        self._rebuild_grid()

    def update_map(self, x, y, width, height, data):
        """A window of the map (map_msgs/OccupancyGridUpdate) on the current map's cells."""
        if self.geometry is None:
            raise NavigatorInputError("map update refused: no map yet")
        if width <= 0 or height <= 0 or x < 0 or y < 0 or x + width > self.geometry.width \
                or y + height > self.geometry.height:
            raise NavigatorInputError(f"map update refused: window x={x} y={y} {width} x {height} "
                                      f"is outside the {self.geometry.width} x "
                                      f"{self.geometry.height} map")
        data = np.asarray(data, dtype=np.int8)
        if data.size != width * height:
            raise NavigatorInputError(f"map update refused: {data.size} values for {width} x {height}")
        self.map_since_new_map = True
        window = data.reshape(height, width)
        self.latest[y:y + height, x:x + width] = window
        self.pending[y:y + height, x:x + width] = window != self.applied[y:y + height, x:x + width]

    def set_pose(self, x, y, yaw):
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise NavigatorInputError("pose refused: not finite")
        self.pose = (float(x), float(y), float(yaw))

    def set_goal(self, x, y):
        """A new goal in the map frame; replaces the current one."""
        if not (math.isfinite(x) and math.isfinite(y)):
            raise NavigatorInputError(f"goal refused: coordinates ({x}, {y}) are not finite")
        self.goal = (float(x), float(y))
        self.goal_relative = None
        self.awaiting_reanchor = False
        self._unsqueeze()
        self._reset_task()

    def cancel(self):
        self.goal = None
        self.goal_relative = None
        self.awaiting_reanchor = False
        self._unsqueeze()
        self._reset_task()

    def on_slam_lost(self):
        """Tracking lost: remember the goal relative to the last known pose."""
        if self.lost:
            return
        self.lost = True
        if self.goal is not None and self.pose is not None:
            self.goal_relative = _relative(self.pose, self.goal)
        self._reset_task()

    def on_slam_new_map(self):
        """SLAM started a new map: the old grid no longer matches the world, so it is dropped; the
        goal is re-anchored on the next map and pose."""
        self.lost = False
        self.geometry = self.latest = self.applied = self.pending = self.grid = None
        if self.goal is not None and self.goal_relative is not None:
            self.awaiting_reanchor = True
            self.map_since_new_map = False
            self.pose = None
        self._reset_task()

    def on_slam_ok(self):
        """Tracking back in the same map: the goal keeps its map coordinates."""
        if self.lost:
            self.lost = False
            if not self.awaiting_reanchor:
                self.goal_relative = None
            self._reset_task()

    # Planning.

    def update(self):
        """Applies what changed and replans when needed; returns the Status to publish."""
        if self.goal is None:
            return Status(IDLE, "no goal")
        if self.lost:
            return self._status(LOST, "SLAM tracking lost: goal kept relative to the last known "
                                      "pose, waiting for tracking", with_path=False)
        if self.awaiting_reanchor:
            if not (self.map_since_new_map and self.pose is not None):
                return self._status(LOST, "SLAM started a new map: waiting for the new map and "
                                          "pose to re-anchor the goal", with_path=False)
            self.goal = _compose(self.pose, self.goal_relative)
            self.goal_relative = None
            self.awaiting_reanchor = False
            self._reset_task()
        if self.geometry is None:
            return self._status(PLANNING, "waiting for a map", with_path=False)
        if self.pose is None:
            return self._status(PLANNING, "waiting for the robot pose", with_path=False)
        changed = self._apply_in_range()
        if math.dist(self.pose[:2], self.goal) <= self.cfg.goal_tolerance_m:
            goal = self.goal
            self.goal = None
            self._reset_task()
            return Status(REACHED, f"reached the goal within {self.cfg.goal_tolerance_m} m",
                          goal=goal)
        start, problem = self._start_cell()
        if start is None:
            self._reset_task()
            return self._status(NO_PATH, problem, with_path=False)
        if changed:
            self.needs_target = True
        if self.needs_target:
            self._choose_target(start)
        if self.target_cell is None:
            self.dstar = None
            self.path_cells = []
            if self._squeeze():
                return self.update()
            return self._status(self.target_kind, self.target_reason, with_path=False)
        if self.dstar is None or self.dstar.goal != self.target_cell:
            self.dstar = planning.DStarLite(self.grid, start, self.target_cell)
            self._search()
            self._adopt()
        elif changed or (start != self.dstar.start and self._deviates()):
            self.dstar.move_start(start)
            self._search()
            if not self.path_cells or (changed and self._should_switch()) or self._deviates():
                self._adopt()
        self._advance(start)
        if not self.path_cells and self._squeeze():
            return self.update()
        if not self.path_cells:
            kind = NO_PATH if self.target_kind == FOLLOWING else self.target_kind
            return self._status(kind, f"no path to {self._fmt(self._target_world())}"
                                + ("" if kind == NO_PATH else f" ({self.target_reason})"),
                                with_path=False)
        if self.target_kind == FOLLOWING:
            return self._status(FOLLOWING, f"following a path to the goal {self._fmt(self.goal)}"
                                + self._squeeze_note())
        if start == self.target_cell:
            return self._status(self.target_kind, self.target_reason + "; at that cell, waiting "
                                                                       "for the map to change",
                                with_path=False)
        return self._status(self.target_kind, self.target_reason + self._squeeze_note())

    def _status(self, state, reason, with_path=True):
        path = self._published_path() if with_path else []
        length = sum(math.dist(a, b) for a, b in zip(path, path[1:]))
        target = self._target_world() if self.target_cell is not None else None
        return Status(state, reason, path, self.goal, target, length, self.plan_ms)

    @staticmethod
    def _fmt(p):
        return f"({p[0]:.2f}, {p[1]:.2f})"

    def _target_world(self):
        return self.geometry.cell_to_world(*self.target_cell)

    def _planning_grid(self, cells, radius_m):
        """The planner's grid of OccupancyGrid values cells [y, x], inflated by radius_m."""
        return planning.Grid(cells, unknown_policy=self.cfg.unknown_policy,
                             unknown_cost=self.cfg.unknown_cost,
                             inflation_radius=radius_m / self.geometry.resolution,
                             occupied_threshold=self.cfg.occupied_threshold)

    def _rebuild_grid(self):
        radius_m = self.cfg.squeeze_radius_m if self.squeezing else self.cfg.robot_radius_m
        self.grid = self._planning_grid(self.applied, radius_m)
        self._reset_task()

    def _squeeze(self):
        """No way to the goal at robot_radius_m: inflate by squeeze_radius_m for the rest of this
        goal. True when that is new (the caller plans again)."""
        if self.squeezing or self.cfg.squeeze_radius_m >= self.cfg.robot_radius_m:
            return False
        self.squeezing = True
        self._rebuild_grid()
        return True

    def _unsqueeze(self):
        if self.squeezing:
            self.squeezing = False
            if self.geometry is not None:
                self._rebuild_grid()

    def _squeeze_note(self):
        return (f" (squeezing through: {self.cfg.squeeze_radius_m} m clearance, no way at "
                f"robot_radius_m {self.cfg.robot_radius_m} m)" if self.squeezing else "")

    def _apply_in_range(self):
        """Moves the pending changes within the viewing range into the planner. True if any."""
        g = self.geometry
        cx, cy = self._cell_of(self.pose)
        r = int(math.ceil(self.cfg.viewing_range_m / g.resolution))
        x0, x1 = max(0, cx - r), min(g.width, cx + r + 1)
        y0, y1 = max(0, cy - r), min(g.height, cy + r + 1)
        if x0 >= x1 or y0 >= y1:
            return False
        window = self.pending[y0:y1, x0:x1]
        if not window.any():
            return False
        ys, xs = np.nonzero(window)
        ys, xs = ys + y0, xs + x0
        near = (xs - cx) ** 2 + (ys - cy) ** 2 <= r * r
        ys, xs = ys[near], xs[near]
        if len(xs) == 0:
            return False
        values = self.latest[ys, xs]
        changes = list(zip(xs.tolist(), ys.tolist(), values.tolist()))
        self.applied[ys, xs] = values
        self.pending[ys, xs] = False
        self.grid.update_cells(changes)
        if self.dstar is not None:
            self.dstar.update_cells(changes)
        return True

    def _cell_of(self, point):
        return self.geometry.world_to_cell(point[0], point[1])

    def _start_cell(self):
        """The robot's cell, or the nearest enterable cell when only inflation covers it."""
        g = self.geometry
        cx, cy = self._cell_of(self.pose)
        if not g.in_bounds(cx, cy):
            return None, f"the robot {self._fmt(self.pose)} is outside the map"
        if self.applied[cy, cx] >= self.cfg.occupied_threshold:
            return None, f"the robot {self._fmt(self.pose)} is inside an obstacle"
        if self.grid.traversable(cx, cy):
            return (cx, cy), ""
        r = int(math.ceil(self.cfg.robot_radius_m / g.resolution)) + 1
        best, best_d = None, math.inf
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                x, y = cx + dx, cy + dy
                if g.in_bounds(x, y) and self.grid.traversable(x, y) and dx * dx + dy * dy < best_d:
                    best, best_d = (x, y), dx * dx + dy * dy
        if best is None:
            return None, (f"the robot {self._fmt(self.pose)} is closer than robot_radius_m to "
                          f"obstacles on every side")
        return best, ""

    def _choose_target(self, start):
        """The cell to plan to: the goal's, or a substitute when the goal cannot be entered."""
        self.needs_target = False
        g = self.geometry
        gx, gy = self._cell_of(self.goal)
        goal_txt = self._fmt(self.goal)
        if g.in_bounds(gx, gy) and self.grid.traversable(gx, gy):
            self._set_target((gx, gy), FOLLOWING, "")
            return
        mask = self.grid.traversable_mask()
        # 4-connected components are exactly what 8-connected moves without corner cutting reach.
        labels, _ = ndimage.label(mask)
        reachable = labels == labels[start[1], start[0]]
        off_map = not g.in_bounds(gx, gy) or self.applied[gy, gx] < 0
        if off_map:
            candidates = reachable & (self.applied >= 0) & (self.applied < self.cfg.occupied_threshold)
            kind, limit = GOAL_OFF_MAP, math.inf
            what = "outside the known map"
        else:
            candidates = reachable
            kind, limit = GOAL_IN_OBSTACLE, self.cfg.goal_search_radius_m / g.resolution
            what = "inside an obstacle"
        ys, xs = np.nonzero(candidates)
        if len(xs) == 0:
            self._set_target(None, NO_PATH, f"the goal {goal_txt} is {what} and no free cell "
                                            "is reachable")
            return
        d2 = (xs - gx) ** 2 + (ys - gy) ** 2
        k = int(np.argmin(d2))
        if d2[k] > limit * limit:
            self._set_target(None, NO_PATH, f"the goal {goal_txt} is {what} and no reachable free "
                                            f"cell is within goal_search_radius_m "
                                            f"({self.cfg.goal_search_radius_m} m)")
            return
        cell = (int(xs[k]), int(ys[k]))
        self._set_target(cell, kind, f"the goal {goal_txt} is {what}: heading for the nearest "
                                     f"reachable free cell {self._fmt(g.cell_to_world(*cell))}")

    def _set_target(self, cell, kind, reason):
        if cell != self.target_cell:
            self.dstar = None
            self.path_cells = []
        self.target_cell, self.target_kind, self.target_reason = cell, kind, reason

    def _search(self):
        t0 = time.perf_counter()
        self.dstar.plan()
        self.plan_ms = (time.perf_counter() - t0) * 1e3

    def _adopt(self):
        """Takes the planner's current path as the path to follow."""
        self.n_replans += 1
        cells = self.dstar.path()
        self.path_cells = cells
        self.progress = 0
        if not cells:
            self.path_points, self.path_index = [], []
            return
        kept = planning.smooth(self.grid, cells) if self.cfg.smooth_path else cells
        where = {c: i for i, c in enumerate(cells)}
        self.path_index = [where[c] for c in kept]
        self.path_points = [self.geometry.cell_to_world(*c) for c in kept]

    def _remaining_cost(self):
        """Cost of the followed path from the robot's progress on, on the current grid."""
        total = 0.0
        cells = self.path_cells
        for a, b in zip(cells[self.progress:], cells[self.progress + 1:]):
            total += self.grid.move_cost(a, b)
            if total == math.inf:
                break
        return total

    def _should_switch(self):
        """Hysteresis: a new path replaces the followed one only when the followed one is blocked
        or the new one is shorter by more than replan_improvement_m."""
        if not self.path_cells:
            return True
        new = self.dstar.cost()
        if not math.isfinite(new):
            return True
        current = self._remaining_cost()
        return not math.isfinite(current) or \
            new < current - self.cfg.replan_improvement_m / self.geometry.resolution

    def _deviates(self):
        if not self.path_points:
            return False
        remaining = self._remaining_points()
        return _polyline_distance(remaining, self.pose[:2]) > self.cfg.max_deviation_m

    def _remaining_points(self):
        after = [p for p, i in zip(self.path_points, self.path_index) if i > self.progress]
        before = [p for p, i in zip(self.path_points, self.path_index) if i <= self.progress]
        return ([before[-1]] if before else []) + after

    def _advance(self, start):
        """Moves the progress index to the followed path's cell nearest the robot."""
        if not self.path_cells:
            return
        ahead = np.asarray(self.path_cells[self.progress:], dtype=float)
        d2 = np.sum((ahead - start) ** 2, axis=1)
        self.progress += int(np.argmin(d2))

    def _published_path(self):
        if not self.path_points:
            return []
        after = [p for p, i in zip(self.path_points, self.path_index) if i > self.progress]
        if not after:
            after = [self.path_points[-1]]
        return [tuple(self.pose[:2])] + after

    def make_plan(self, start, goal, tolerance_m=0.0):
        """A one-off plan on the newest map (not the lazily applied one), for ~make_plan.

        Returns (path [(x, y)], reason); the path is empty with the reason when none exists.
        """
        if self.geometry is None:
            return [], "no map yet"
        if not all(math.isfinite(v) for v in (*start, *goal, tolerance_m)):
            return [], "start, goal and tolerance must be finite"
        g = self.geometry
        grid = self._planning_grid(self.latest, self.cfg.robot_radius_m)
        s, t = self._cell_of(start), self._cell_of(goal)
        if not g.in_bounds(*s) or not grid.traversable(*s):
            return [], f"the start {self._fmt(start)} is outside the map or not traversable"
        if not g.in_bounds(*t) or not grid.traversable(*t):
            mask = grid.traversable_mask()
            ys, xs = np.nonzero(mask)
            d2 = (xs - t[0]) ** 2 + (ys - t[1]) ** 2
            r = max(0.0, tolerance_m) / g.resolution
            if len(xs) == 0 or d2.min() > r * r:
                return [], (f"the goal {self._fmt(goal)} is outside the map or not traversable "
                            f"and no free cell is within the tolerance ({tolerance_m} m)")
            k = int(np.argmin(d2))
            t = (int(xs[k]), int(ys[k]))
        cells, cost = planning.astar(grid, s, t)
        if not cells:
            return [], f"no path from {self._fmt(start)} to {self._fmt(goal)}"
        kept = planning.smooth(grid, cells) if self.cfg.smooth_path else cells
        return [g.cell_to_world(*c) for c in kept], ""

