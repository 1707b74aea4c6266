#!/usr/bin/python3
"""Baseline: the occupancy grid method of seed 004 ("Spotting"), reproduced in Python.

This module is a benchmark baseline only; the sparse_nav package never imports it. It follows
the seed's "Occupancy Grid Generation" section and its retrospective, step by step, and keeps
the seed's costs on purpose (per-triangle Python loop, unprepared shapely predicates, one
rtree query and one ``contains`` per probed cell):

1. Slice: obstacle points whose height lies in ``[z_min, z_max]``, z dropped. The seed sent this
   slice "as an ``OccupancyGrid`` message" (octomap_server's projected map), so the slice is
   binned into cells at the grid resolution; "all coordinates where features have been
   identified are obstructed", and those occupied cell centres are the Delaunay vertices
   (``vertices="points"`` uses the raw slice points instead, a heavier variant).
2. ``scipy.spatial.Delaunay`` over the vertices.
3. Alpha shape: a triangle is kept when its circumradius (Heron's formula) is below ``alpha_m``;
   the edges of the kept triangles, each once, form a ``MultiLineString``.
4. Polygonise: ``shapely.ops.polygonize`` of those edges gives the triangles (and any face
   closed by them), ``unary_union`` dissolves the internal edges into the obstacle polygons.
5. Rasterise: every polygon's bounds go into an ``rtree`` index. The grid is probed at every
   third cell along both axes (the centre of each 3 x 3 block); a probe queries the index with
   its point and calls ``polygon.contains(Point)`` on each candidate. An occupied probe
   "occludes the nine surrounding cells"; a free probe leaves its block free, which is the
   seed's dropped resolution (blocks cut by the grid edge probe their clipped centre).
6. The feature cells of step 1 are marked occupied on top, everything else in the grid is free.

Grid values: 100 occupied, 0 free, -1 unknown. The grid covers ``bounds`` (default: the slice's
bounding box); cells outside the slice's bounding box are -1 (the seed never probed there).
Row 0 is the lowest y, column 0 the lowest x, as in ``nav_msgs/OccupancyGrid``.
"""
import math
import time
from collections import OrderedDict

import numpy as np
from rtree import index as rtree_index
from scipy.spatial import Delaunay, QhullError
from shapely.geometry import MultiLineString, Point, Polygon
from shapely.ops import polygonize, unary_union

OCCUPIED = 100
FREE = 0
UNKNOWN = -1
PROBE_STEP = 3  # the seed probed every third cell along both axes


class Seed004Result:
    """The baseline's output: grid, its geometry and the time spent per stage."""

    def __init__(self, grid, origin, resolution, polygons, n_vertices, n_triangles,
                 n_kept_triangles, n_probes, n_contains, stages_ms):
        self.grid = grid                    # (height, width) int8
        self.origin = origin                # (x, y) of the corner of cell (0, 0) [m]
        self.resolution = resolution        # [m]
        self.polygons = polygons            # list of shapely Polygons
        self.n_vertices = n_vertices
        self.n_triangles = n_triangles
        self.n_kept_triangles = n_kept_triangles
        self.n_probes = n_probes
        self.n_contains = n_contains        # shapely contains() calls made
        self.stages_ms = stages_ms          # OrderedDict stage -> ms
        self.total_ms = float(sum(stages_ms.values()))

    def counts(self):
        """Cells per value: {"occupied", "free", "unknown"}."""
        return {"occupied": int(np.count_nonzero(self.grid == OCCUPIED)),
                "free": int(np.count_nonzero(self.grid == FREE)),
                "unknown": int(np.count_nonzero(self.grid == UNKNOWN))}


class _Laps:
    """Wall-clock laps into an ordered dict of milliseconds."""

    def __init__(self):
        self.stages = OrderedDict()
        self._t = time.perf_counter()

    def lap(self, name):
        now = time.perf_counter()
        self.stages[name] = (now - self._t) * 1000.0
        self._t = now


def obstacle_slice(points, z_min, z_max):
    """(N, 2) x, y of the points (N, 3) whose z lies in [z_min, z_max] (the 2D slice)."""
    points = np.asarray(points, dtype=float)
    keep = np.isfinite(points).all(axis=1) & (points[:, 2] >= z_min) & (points[:, 2] <= z_max)
    return points[keep, :2]


def grid_geometry(xy, resolution, bounds=None):
    """Origin (x, y) and shape (height, width) of a grid at `resolution` covering `bounds`.

    `bounds` is (min_x, min_y, max_x, max_y) in metres; None uses the bounding box of `xy`.
    """
    if bounds is None:
        bounds = (xy[:, 0].min(), xy[:, 1].min(), xy[:, 0].max(), xy[:, 1].max())
    min_x, min_y, max_x, max_y = bounds
    # Snap the origin to the resolution so that cell edges do not depend on the noise.
    origin = (math.floor(min_x / resolution) * resolution,
              math.floor(min_y / resolution) * resolution)
    width = int(math.floor((max_x - origin[0]) / resolution)) + 1
    height = int(math.floor((max_y - origin[1]) / resolution)) + 1
    return origin, (height, width)


def feature_cells(xy, origin, shape, resolution):
    """(height, width) bool: cells holding at least one slice point (the projected map)."""
    cols = np.floor((xy[:, 0] - origin[0]) / resolution).astype(np.int64)
    rows = np.floor((xy[:, 1] - origin[1]) / resolution).astype(np.int64)
    inside = (cols >= 0) & (cols < shape[1]) & (rows >= 0) & (rows < shape[0])
    mask = np.zeros(shape, dtype=bool)
    mask[rows[inside], cols[inside]] = True
    return mask


def alpha_shape(coords, alpha_m):
    """The seed's alpha shape: (edges, kept triangle count, triangle count).

    Delaunay triangles whose circumradius is below `alpha_m` are kept; each edge of a kept
    triangle is returned once, as a (2, 2) array of its end points. Fewer than four points, or
    points all on one line, have no alpha shape (their cells stay occupied all the same).
    """
    if len(coords) < 4:
        return [], 0, 0
    try:
        tri = Delaunay(coords)
    except QhullError:
        return [], 0, 0
    edges = set()
    edge_points = []

    def add_edge(i, j):
        # Each undirected edge once, whichever triangle brings it first.
        if (i, j) in edges or (j, i) in edges:
            return
        edges.add((i, j))
        edge_points.append(coords[[i, j]])

    kept = 0
    for ia, ib, ic in tri.simplices:
        pa, pb, pc = coords[ia], coords[ib], coords[ic]
        a = math.sqrt((pa[0] - pb[0]) ** 2 + (pa[1] - pb[1]) ** 2)
        b = math.sqrt((pb[0] - pc[0]) ** 2 + (pb[1] - pc[1]) ** 2)
        c = math.sqrt((pc[0] - pa[0]) ** 2 + (pc[1] - pa[1]) ** 2)
        s = (a + b + c) / 2.0
        area_sq = s * (s - a) * (s - b) * (s - c)
        if area_sq <= 0.0:
            continue  # collinear cell centres: a degenerate sliver has no circumcircle
        circum_r = a * b * c / (4.0 * math.sqrt(area_sq))
        if circum_r < alpha_m:
            kept += 1
            add_edge(ia, ib)
            add_edge(ib, ic)
            add_edge(ic, ia)
    return edge_points, kept, len(tri.simplices)


def polygonise(edge_points):
    """Obstacle polygons from alpha-shape edges: polygonize, then unary_union."""
    if not edge_points:
        return []
    faces = list(polygonize(MultiLineString(edge_points)))
    merged = unary_union(faces)
    if merged.is_empty:
        return []
    if isinstance(merged, Polygon):
        return [merged]
    return [g for g in getattr(merged, "geoms", []) if isinstance(g, Polygon)]


def rasterise(polygons, origin, shape, resolution, step=PROBE_STEP):
    """(grid int8, probes, contains calls): rtree + shapely contains on every `step`-th cell."""
    height, width = shape
    grid = np.full(shape, FREE, dtype=np.int8)
    idx = rtree_index.Index()
    for i, poly in enumerate(polygons):
        idx.insert(i, poly.bounds)
    probes = 0
    contains_calls = 0
    half = step // 2
    for row0 in range(0, height, step):
        row = min(row0 + half, height - 1)
        y = origin[1] + (row + 0.5) * resolution
        for col0 in range(0, width, step):
            col = min(col0 + half, width - 1)
            x = origin[0] + (col + 0.5) * resolution
            point = Point(x, y)
            probes += 1
            occupied = False
            for i in idx.intersection((x, y, x, y)):
                contains_calls += 1
                if polygons[i].contains(point):
                    occupied = True
                    break
            if occupied:
                grid[row0:row0 + step, col0:col0 + step] = OCCUPIED
    return grid, probes, contains_calls


def seed004_grid(points, resolution=0.05, alpha_m=0.25, z_min=-np.inf, z_max=np.inf,
                 bounds=None, vertices="cells", step=PROBE_STEP):
    """Occupancy grid of a 3D cloud by the seed 004 method (see the module docstring).

    points: (N, 3) in a z-up frame [m]; z_min, z_max: the obstacle height band [m];
    resolution: cell size [m]; alpha_m: circumradius threshold [m]; bounds: grid extent
    (min_x, min_y, max_x, max_y) [m] or None for the slice's bounding box; vertices: "cells"
    (the seed: one vertex per occupied cell of the projected map) or "points" (raw slice points).
    Returns a Seed004Result.
    """
    if vertices not in ("cells", "points"):
        raise ValueError("vertices must be 'cells' or 'points'")
    laps = _Laps()
    xy = obstacle_slice(points, z_min, z_max)
    if len(xy) == 0:
        raise ValueError("the obstacle slice is empty")
    origin, shape = grid_geometry(xy, resolution, bounds)
    cells = feature_cells(xy, origin, shape, resolution)
    if vertices == "cells":
        rows, cols = np.nonzero(cells)
        coords = np.column_stack([origin[0] + (cols + 0.5) * resolution,
                                  origin[1] + (rows + 0.5) * resolution])
    else:
        coords = xy
    laps.lap("slice")
    edge_points, kept, n_tri = alpha_shape(coords, alpha_m)
    laps.lap("alpha_shape")
    polygons = polygonise(edge_points)
    laps.lap("polygonise")
    grid, probes, contains_calls = rasterise(polygons, origin, shape, resolution, step)
    laps.lap("rasterise")
    grid[cells] = OCCUPIED
    # Outside the slice's bounding box nothing was seen: unknown, not free.
    min_col = int(math.floor((xy[:, 0].min() - origin[0]) / resolution))
    max_col = int(math.floor((xy[:, 0].max() - origin[0]) / resolution))
    min_row = int(math.floor((xy[:, 1].min() - origin[1]) / resolution))
    max_row = int(math.floor((xy[:, 1].max() - origin[1]) / resolution))
    seen = np.zeros(shape, dtype=bool)
    seen[max(min_row, 0):max_row + 1, max(min_col, 0):max_col + 1] = True
    grid[~seen] = UNKNOWN
    laps.lap("finish")
    return Seed004Result(grid, origin, resolution, polygons, len(coords), n_tri, kept,
                         probes, contains_calls, laps.stages)
