"""RRT of seed 001 on a planning grid: goal bias, fixed step, edge check by sampling, goal threshold,
restart after an iteration cap; seeded, so a run is reproducible.

Positions are continuous cell coordinates (x = column, y = row, a cell's centre at integers), the
same cells as :class:`sparse_nav._planning.Grid`. Nearest neighbours are a vectorised scan of the
tree: the iteration cap keeps a tree at a few thousand nodes, where a scan beats rebuilding a
KD-tree after every insertion.
"""
import math
from dataclasses import dataclass

import numpy as np


@dataclass
class RrtConfig:
    goal_bias: float = 0.3              # probability of sampling the goal (seed 001: 0.3)
    step_cells: float = 10.0            # extension length [cells]
    edge_sample_spacing_cells: float = 0.5   # spacing of the collision samples along an edge [cells]
    goal_threshold_cells: float = 10.0  # a node this close to the goal with a clear edge ends the search
    max_iterations: int = 1500          # iterations before the tree restarts (seed 001: 1500)
    max_restarts: int = 20              # restarts before giving up
    seed: int = 0

    def validate(self):
        if not 0.0 <= self.goal_bias <= 1.0:
            raise ValueError(f"goal_bias must be in [0, 1], got {self.goal_bias}")
        for name in ("step_cells", "edge_sample_spacing_cells", "goal_threshold_cells"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        if self.max_iterations < 1 or self.max_restarts < 0:
            raise ValueError("max_iterations must be >= 1 and max_restarts >= 0")


@dataclass
class RrtResult:
    path: list          # [(x, y), ...] floats from start to goal; empty when none was found
    length: float       # Euclidean length [cells]; inf when no path
    iterations: int     # iterations over all restarts
    restarts: int
    tree_size: int      # nodes of the last tree

    def found(self):
        return bool(self.path)


class Rrt:
    """Seed 001's RRT over a boolean traversability mask indexed [y, x]."""

    def __init__(self, traversable, config=None):
        self.cfg = config or RrtConfig()
        self.cfg.validate()
        mask = np.asarray(traversable, dtype=bool)
        if mask.ndim != 2 or mask.size == 0:
            raise ValueError("traversable must be a non-empty 2D array indexed [y, x]")
        self.mask = mask
        self.height, self.width = mask.shape

    def _free(self, points):
        """True per point when its cell is inside the grid and traversable."""
        cells = np.rint(points).astype(np.int64)
        x, y = cells[:, 0], cells[:, 1]
        inside = (x >= 0) & (y >= 0) & (x < self.width) & (y < self.height)
        out = np.zeros(len(points), dtype=bool)
        out[inside] = self.mask[y[inside], x[inside]]
        return out

    def edge_clear(self, a, b):
        """Samples the segment a-b (both ends included) at most edge_sample_spacing_cells apart."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / self.cfg.edge_sample_spacing_cells)))
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        return bool(np.all(self._free(a + t * (b - a))))

    def plan(self, start, goal):
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        if not (self._free(start[None])[0] and self._free(goal[None])[0]):
            return RrtResult([], math.inf, 0, 0, 0)
        cfg = self.cfg
        rng = np.random.default_rng(cfg.seed)
        cap = cfg.max_iterations + 2
        nodes = np.empty((cap, 2))
        parents = np.empty(cap, dtype=np.int64)
        iterations = 0
        size = 1
        for restart in range(cfg.max_restarts + 1):
            nodes[0], parents[0], size = start, -1, 1
            if self._reaches(start, goal):
                nodes[1], parents[1], size = goal, 0, 2
                return self._result(nodes, parents, size, iterations, restart)
            for _ in range(cfg.max_iterations):
                iterations += 1
                if rng.random() < cfg.goal_bias:
                    target = goal
                else:
                    target = rng.random(2) * (self.width, self.height) - 0.5
                d2 = np.sum((nodes[:size] - target) ** 2, axis=1)
                near = int(np.argmin(d2))
                dist = math.sqrt(d2[near])
                if dist == 0.0:
                    continue
                new = target if dist <= cfg.step_cells else nodes[near] + (target - nodes[near]) * (
                    cfg.step_cells / dist)
                if not self.edge_clear(nodes[near], new):
                    continue
                nodes[size], parents[size] = new, near
                size += 1
                if self._reaches(new, goal):
                    if not np.array_equal(new, goal):
                        nodes[size], parents[size] = goal, size - 1
                        size += 1
                    return self._result(nodes, parents, size, iterations, restart)
        return RrtResult([], math.inf, iterations, cfg.max_restarts, size)

    def _reaches(self, p, goal):
        return (np.linalg.norm(goal - p) <= self.cfg.goal_threshold_cells
                and self.edge_clear(p, goal))

    @staticmethod
    def _result(nodes, parents, size, iterations, restarts):
        path = []
        i = size - 1
        while i >= 0:
            path.append((float(nodes[i, 0]), float(nodes[i, 1])))
            i = int(parents[i])
        path.reverse()
        length = sum(math.dist(a, b) for a, b in zip(path, path[1:]))
        return RrtResult(path, length, iterations, restarts, size)
