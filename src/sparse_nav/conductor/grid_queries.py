"""What the conductor asks of the occupancy grid (ROS-free): free room along a bearing, the cell
under the robot, the way out of an obstacle, whether an exit candidate leads out of the room, and
whether walls surround the robot (another room) or not (outside)."""
import dataclasses
import math

import numpy as np

from sparse_nav.exit_finder.geometry import boundary_distances
from sparse_nav.scanning import Step


@dataclasses.dataclass
class GridView:
    """An occupancy grid as nav_msgs has it: cells[row, col], row 0 at origin_y, -1 unknown."""

    cells: np.ndarray
    resolution_m: float
    origin_xy: tuple

    def cell(self, x, y):
        col = int(math.floor((x - self.origin_xy[0]) / self.resolution_m))
        row = int(math.floor((y - self.origin_xy[1]) / self.resolution_m))
        if 0 <= row < self.cells.shape[0] and 0 <= col < self.cells.shape[1]:
            return int(self.cells[row, col])
        return None  # off the map

    def free_distance(self, x, y, heading_rad, max_m=10.0, occupied_at=50, off_map_free=False):
        """Metres from (x, y) along heading to the first occupied or off-map cell (unknown cells
        count as free: the seed drives until it meets the wall), capped at max_m. off_map_free:
        off-map cells count as unknown, not as the end (a SLAM map seconds old has a small grid)."""
        step = self.resolution_m / 2.0
        d = 0.0
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        while d < max_m:
            value = self.cell(x + d * c, y + d * s)
            if value is None and off_map_free:
                value = -1  # unknown
            if value is None or value >= occupied_at:
                return d
            d += step
        return max_m

    def in_obstacle(self, x, y, occupied_at=50):
        value = self.cell(x, y)
        return value is not None and value >= occupied_at

    def free_cells_near(self, x, y, radius_m):
        """Free cells within radius_m of (x, y)."""
        r = int(math.ceil(radius_m / self.resolution_m))
        col = int(math.floor((x - self.origin_xy[0]) / self.resolution_m))
        row = int(math.floor((y - self.origin_xy[1]) / self.resolution_m))
        window = self.cells[max(0, row - r):row + r + 1, max(0, col - r):col + r + 1]
        return int(np.count_nonzero(window == 0))

    def nearest_free(self, x, y, max_m, occupied_at=50):
        """Centre (x, y) of the known-free cell nearest to (x, y) within max_m, or None."""
        r = int(math.ceil(max_m / self.resolution_m))
        col = int(math.floor((x - self.origin_xy[0]) / self.resolution_m))
        row = int(math.floor((y - self.origin_xy[1]) / self.resolution_m))
        row0, col0 = max(0, row - r), max(0, col - r)
        window = self.cells[row0:row + r + 1, col0:col + r + 1]
        rows, cols = np.nonzero((window >= 0) & (window < occupied_at))
        if rows.size == 0:
            return None
        cx = self.origin_xy[0] + (col0 + cols + 0.5) * self.resolution_m
        cy = self.origin_xy[1] + (row0 + rows + 0.5) * self.resolution_m
        d = np.hypot(cx - x, cy - y)
        best = int(np.argmin(d))
        return (float(cx[best]), float(cy[best])) if d[best] <= max_m else None

    def walls_around(self, x, y, max_m, n_rays=72, occupied_at=50):
        """(n_rays,) bool: along each bearing 2*pi*k/n_rays (counter-clockwise from the map's x
        axis), an occupied cell within max_m of (x, y). Unknown cells are passed through, like
        free ones: what the camera never saw is no wall."""
        bearings = 2.0 * math.pi * np.arange(n_rays) / n_rays
        distances = np.arange(0.0, max_m, self.resolution_m / 2.0)
        xs = x + np.outer(np.cos(bearings), distances)
        ys = y + np.outer(np.sin(bearings), distances)
        return np.any(self.values_at(xs, ys) >= occupied_at, axis=1)

    def values_at(self, xs, ys):
        """Cell values at the points (xs, ys) (arrays of one shape); -1 (unknown) off the map."""
        cols = np.floor((xs - self.origin_xy[0]) / self.resolution_m).astype(int)
        rows = np.floor((ys - self.origin_xy[1]) / self.resolution_m).astype(int)
        on_map = (rows >= 0) & (rows < self.cells.shape[0]) & \
            (cols >= 0) & (cols < self.cells.shape[1])
        values = np.full(np.shape(xs), -1, dtype=int)
        values[on_map] = self.cells[rows[on_map], cols[on_map]]
        return values

    def side_walls_beyond_m(self, outline, door_xy, near_m=0.5, far_m=4.0, tolerance_m=0.4,
                            occupied_at=50):
        """Metres of wall the map shows along the room's side walls carried on past the wall of
        the door door_xy, the longer of the two sides: the outline edges on either side of the
        door's edge, continued from near_m to far_m beyond its corners, with occupied cells
        within tolerance_m of the line. A partition's door leads on between the building's walls;
        past an outer wall they turn at the corners, and a wall standing beyond crosses the line
        over a few cells only. None without an outline (fewer than three vertices) or a door."""
        poly = np.asarray(outline, dtype=float).reshape(-1, 2)
        if len(poly) < 3 or door_xy is None:
            return None
        n = len(poly)
        door = np.asarray(door_xy, dtype=float)
        k = int(boundary_distances(door, poly)[1][0])
        step = self.resolution_m / 2.0
        along = np.arange(near_m, far_m + 1e-9, step)
        across = np.arange(-tolerance_m, tolerance_m + 1e-9, step)
        best = 0.0
        # Edge k runs from corner poly[k] to poly[k + 1]; each side edge ends at one of them.
        for corner, before in ((poly[k], poly[k - 1]), (poly[(k + 1) % n], poly[(k + 2) % n])):
            direction = corner - before
            length = float(np.hypot(*direction))
            if length < 1e-9:
                continue
            u = direction / length
            normal = np.array([-u[1], u[0]])
            # (along, across, 2): a band of points around the continued edge.
            pts = corner + along[:, None, None] * u + across[None, :, None] * normal
            walled = np.any(self.values_at(pts[..., 0], pts[..., 1]) >= occupied_at, axis=1)
            best = max(best, float(np.count_nonzero(walled)) * step)
        return best

    def free_share_beyond(self, exit_xy, from_xy, near_m, far_m, occupied_at=50):
        """Share of the cells from near_m to far_m beyond exit_xy, on the line from from_xy
        through it, that the map knows to be free. The map's free space comes from rays to the
        points the camera saw, so it reaches beyond a door but not beyond a wall or a box."""
        dx, dy = exit_xy[0] - from_xy[0], exit_xy[1] - from_xy[1]
        norm = math.hypot(dx, dy)
        if norm < 1e-9 or far_m <= near_m:
            return 0.0
        c, s = dx / norm, dy / norm
        distances = np.arange(near_m, far_m + 1e-9, self.resolution_m / 2.0)
        values = [self.cell(exit_xy[0] + d * c, exit_xy[1] + d * s) for d in distances]
        free = sum(1 for v in values if v is not None and 0 <= v < occupied_at)
        return free / len(values)


def widest_opening_deg(walls, skip_bearing_rad=None):
    """The widest run of bearings without a wall (degrees) in a :meth:`GridView.walls_around`
    answer, leaving out the run that holds skip_bearing_rad (the door the robot came through).
    360 when no bearing has a wall, 0 when every one has."""
    walls = np.asarray(walls, dtype=bool)
    n = len(walls)
    if n == 0 or not walls.any():
        return 360.0
    skip = None if skip_bearing_rad is None else \
        int(round(skip_bearing_rad / (2.0 * math.pi) * n)) % n
    start = int(np.flatnonzero(walls)[0])  # runs are read from a wall on, so none wraps
    widest, run, run_has_skip = 0, 0, False
    for k in range(start, start + n + 1):
        i = k % n
        if k < start + n and not walls[i]:
            run += 1
            run_has_skip = run_has_skip or i == skip
            continue
        if not run_has_skip:
            widest = max(widest, run)
        run, run_has_skip = 0, False
    return 360.0 * widest / n


def order_exits(candidates, grid, from_xy, near_m, far_m, min_free_share):
    """(ordered, any_leads_out): the finder's ranked exits, those the map shows free space beyond
    (free_share_beyond >= min_free_share) first, each group in the finder's order: a wall, a box
    or furniture is not a way out, however door-like its outline. Exits off the map are left out
    (a room's exit lies in its walls, which are on the map; one far off comes from stray points).
    Without a grid or a start, the finder's order, taken as leading out."""
    if grid is None or from_xy is None:
        return list(candidates), True
    candidates = [c for c in candidates if grid.cell(*c) is not None]
    leads_out = [grid.free_share_beyond(c, from_xy, near_m, far_m) >= min_free_share
                 for c in candidates]
    ordered = [c for c, ok in zip(candidates, leads_out) if ok] + \
        [c for c, ok in zip(candidates, leads_out) if not ok]
    return ordered, any(leads_out)


def steps_out_of_obstacle(grid, pose, search_m=1.0, min_move_m=0.2):
    """Steps that take a robot the map puts inside an obstacle to the nearest free cell: turn to
    face it, then move one cell past its centre (at least min_move_m, the Tello's shortest move).
    None when no free cell lies within search_m. A move that ended where it began (a sway) would
    leave the robot in the same cell, and the conductor recovering from it again and again."""
    x, y, yaw = pose
    target = grid.nearest_free(x, y, search_m)
    if target is None:
        return None
    bearing = math.atan2(target[1] - y, target[0] - x)
    turn_deg = math.degrees(math.atan2(math.sin(bearing - yaw), math.cos(bearing - yaw)))
    distance = max(min_move_m, math.hypot(target[0] - x, target[1] - y) + grid.resolution_m)
    return [Step(ccw_deg=round(turn_deg)), Step(forward_m=distance)]
