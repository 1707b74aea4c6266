"""What the conductor asks of the occupancy grid (ROS-free): free room along a bearing, the cell
under the robot."""
import dataclasses
import math

import numpy as np


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

    def free_distance(self, x, y, heading_rad, max_m=10.0, occupied_at=50):
        """Metres from (x, y) along heading to the first occupied or off-map cell (unknown cells
        count as free: the seed drives until it meets the wall), capped at max_m."""
        step = self.resolution_m / 2.0
        d = 0.0
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        while d < max_m:
            value = self.cell(x + d * c, y + d * s)
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
