"""Simulator worlds: walls with door gaps, furniture boxes, textures and ground-truth exits.

A world is 2.5D: walls are vertical segments from the floor (z = 0) to the ceiling, boxes are
prisms on the floor. Coordinates are metres in the world frame (REP-103: x, y horizontal, z up).
Worlds are read from YAML files whose schema is documented at the top of every file in
``worlds/`` and in :func:`world_from_dict`; the loader validates everything and raises
:class:`WorldError` with the file (or world name) and the problem.
"""
import dataclasses
import math
import os
from pathlib import Path

import numpy as np
import yaml

#: Environment variable that overrides the directory of shipped worlds.
WORLDS_DIR_ENV = "SPARSE_NAV_WORLDS_DIR"

# Geometry tolerances (m): how close an exit must be to a door gap, how far the start pose must
# stay from walls and boxes, and how far features keep from segment ends (so that a feature never
# sits exactly on a neighbouring wall's end point, where occlusion tests are ill-conditioned).
_EXIT_TO_GAP_MAX_M = 0.3
_START_CLEARANCE_M = 0.3
_FEATURE_END_MARGIN_M = 0.01


class WorldError(ValueError):
    """A world cannot be loaded or is invalid; the message names the world and the problem."""


@dataclasses.dataclass(frozen=True)
class Wall:
    """A vertical wall segment from (x1, y1) to (x2, y2) in metres, floor to ceiling.

    ``texture_per_m2`` is the density of ORB-like features on each textured face (features/m^2).
    ``faces`` is 2 for a free-standing wall (both faces carry features) or 1 for a segment of a
    closed room outline, textured on the inside face only; ``normal`` then points into the room.
    """

    x1: float
    y1: float
    x2: float
    y2: float
    texture_per_m2: float
    faces: int = 2
    normal: tuple = (0.0, 0.0)
    name: str = ""

    @property
    def length_m(self):
        """Length of the segment (m)."""
        return math.hypot(self.x2 - self.x1, self.y2 - self.y1)


@dataclasses.dataclass(frozen=True)
class Box:
    """A furniture box or pillar standing on the floor.

    ``center`` (x, y) m; ``size`` (w along its own x, d along its own y) m; ``yaw_rad`` heading
    about +z; ``height_m`` above the floor; ``texture_per_m2`` on its sides and top (features/m^2).
    """

    center: tuple
    size: tuple
    yaw_rad: float
    height_m: float
    texture_per_m2: float

    def footprint(self):
        """Corners of the footprint, (4, 2) metres in the world frame, counter-clockwise."""
        w, d = self.size[0] / 2.0, self.size[1] / 2.0
        local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]])
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        rot = np.array([[c, -s], [s, c]])
        return local @ rot.T + np.asarray(self.center, dtype=float)

    def edges(self):
        """Footprint edges as (4, 4) segments (x1, y1, x2, y2) in metres."""
        fp = self.footprint()
        return np.hstack([fp, np.roll(fp, -1, axis=0)])


@dataclasses.dataclass
class World:
    """A simulator world.

    Attributes (metres, radians, world frame, z up):
      name: world name.
      walls: list of :class:`Wall` (door gaps are simply absent).
      boxes: list of :class:`Box`.
      ceiling_height_m: height of the flat ceiling above the floor.
      floor_texture, ceiling_texture: feature densities (features/m^2) of floor and ceiling.
      exits: ground-truth exit door centres in the outer wall, dicts {x, y, width_m}.
      start: robot start pose (x, y, yaw_rad).
      door_gaps: (x1, y1, x2, y2, outer) of every door gap; outer is True for gaps in a closed
        room outline.
      wall_texture_band_m, wall_texture_band_fraction: that fraction of wall features lies in the
        height band [lo, hi] (furniture, posters, door frames); the rest spreads floor to ceiling.
      wall_texture_cluster_fraction: share of wall features gathered in texture patches.
      clutter_per_m2: density (features per m^2 of floor inside the room outlines) of small
        objects (chairs, plants, lamps) in the wall texture band: features seen from any side
        that are not obstacles.
      outlines: closed room outlines as (M, 2) vertex arrays (m), doors not cut.
    """

    name: str
    walls: list
    boxes: list
    ceiling_height_m: float
    floor_texture: float
    ceiling_texture: float
    exits: list
    start: tuple
    door_gaps: list = dataclasses.field(default_factory=list)
    wall_texture_band_m: tuple = (0.3, 1.9)
    wall_texture_band_fraction: float = 0.6
    wall_texture_cluster_fraction: float = 0.5
    clutter_per_m2: float = 0.0
    outlines: list = dataclasses.field(default_factory=list)

    def wall_segments(self):
        """Wall segments as a (K, 4) float array of (x1, y1, x2, y2) in metres."""
        if not self.walls:
            return np.zeros((0, 4))
        return np.array([[w.x1, w.y1, w.x2, w.y2] for w in self.walls], dtype=float)

    def box_segments(self):
        """Footprint edges of all boxes, (4 * n_boxes, 4) metres, and their heights (m)."""
        if not self.boxes:
            return np.zeros((0, 4)), np.zeros(0)
        segs = np.vstack([b.edges() for b in self.boxes])
        heights = np.repeat([b.height_m for b in self.boxes], 4)
        return segs, heights

    def exit_gap(self, exit_):
        """The door gap (x1, y1, x2, y2) in metres of a closed outline nearest to an exit dict."""
        outer = [g[:4] for g in self.door_gaps if g[4]]
        if not outer:
            raise WorldError(f"world {self.name}: no door gap in a closed outline")
        centre = np.array([exit_["x"], exit_["y"]])
        return min(outer, key=lambda g: _point_segment_distance(centre, np.array(g)))

    def bounds(self):
        """Axis-aligned bounds (xmin, ymin, xmax, ymax) in metres of walls and boxes."""
        pts = [self.wall_segments().reshape(-1, 2)]
        pts += [b.footprint() for b in self.boxes]
        allp = np.vstack(pts)
        return (float(allp[:, 0].min()), float(allp[:, 1].min()),
                float(allp[:, 0].max()), float(allp[:, 1].max()))

    def features(self, rng):
        """World-frame feature points (N, 3) in metres; deterministic for a given generator state.

        Features lie on wall faces between floor and ceiling, on box sides and tops, and, sparser,
        on the floor and ceiling. See :meth:`features_with_normals`.
        """
        return self.features_with_normals(rng)[0]

    def features_with_normals(self, rng):
        """Feature points (N, 3) and their surface normals (N, 3), world frame.

        The normal points to the side the feature is seen from: a one-sided outline wall only
        from inside the room, a free-standing wall from both sides (one feature set per face).
        Counts are Poisson with mean density x area, so a world's texture is a density, not a
        fixed count.
        """
        pts, nrm = [], []
        h = self.ceiling_height_m
        lo, hi = self.wall_texture_band_m
        lo, hi = max(0.0, min(lo, h)), max(0.0, min(hi, h))
        for wall in self.walls:
            length = wall.length_m
            usable = length - 2 * _FEATURE_END_MARGIN_M
            if usable <= 0 or wall.texture_per_m2 <= 0:
                continue
            d = np.array([wall.x2 - wall.x1, wall.y2 - wall.y1]) / length
            normals = [np.array(wall.normal, dtype=float)] if wall.faces == 1 else \
                [np.array([-d[1], d[0]]), np.array([d[1], -d[0]])]
            for n2 in normals:
                n = rng.poisson(wall.texture_per_m2 * length * h)
                u, z = self._wall_face_samples(rng, n, length, h, lo, hi)
                xy = np.array([wall.x1, wall.y1]) + u[:, None] * d
                pts.append(np.column_stack([xy, z]))
                nrm.append(np.tile([n2[0], n2[1], 0.0], (n, 1)))
        for box in self.boxes:
            if box.texture_per_m2 <= 0:
                continue
            fp = box.footprint()
            for i in range(4):
                a, b = fp[i], fp[(i + 1) % 4]
                length = float(np.hypot(*(b - a)))
                n = rng.poisson(box.texture_per_m2 * length * box.height_m)
                u = rng.uniform(0.0, 1.0, n)
                xy = a + u[:, None] * (b - a)
                z = rng.uniform(0.0, box.height_m, n)
                out = np.array([(b - a)[1], -(b - a)[0]]) / length  # CCW footprint: right = out
                pts.append(np.column_stack([xy, z]))
                nrm.append(np.tile([out[0], out[1], 0.0], (n, 1)))
            n = rng.poisson(box.texture_per_m2 * box.size[0] * box.size[1])
            local = rng.uniform(-0.5, 0.5, (n, 2)) * np.asarray(box.size)
            c, s = math.cos(box.yaw_rad), math.sin(box.yaw_rad)
            xy = local @ np.array([[c, s], [-s, c]]) + np.asarray(box.center)
            pts.append(np.column_stack([xy, np.full(n, box.height_m)]))
            nrm.append(np.tile([0.0, 0.0, 1.0], (n, 1)))
        # Floor and ceiling extend 2 m beyond the walls: what lies past an exit is seen through it.
        xmin, ymin, xmax, ymax = self.bounds()
        xmin, ymin, xmax, ymax = xmin - 2.0, ymin - 2.0, xmax + 2.0, ymax + 2.0
        area = (xmax - xmin) * (ymax - ymin)
        for density, z, nz in ((self.floor_texture, 0.0, 1.0), (self.ceiling_texture, h, -1.0)):
            n = rng.poisson(density * area) if density > 0 else 0
            xy = rng.uniform([xmin, ymin], [xmax, ymax], (n, 2))
            pts.append(np.column_stack([xy, np.full(n, z)]))
            nrm.append(np.tile([0.0, 0.0, nz], (n, 1)))
        if self.clutter_per_m2 > 0:
            clutter = self._clutter(rng, lo, hi)
            pts.append(clutter)
            nrm.append(np.zeros_like(clutter))  # no normal: seen from every side
        if not pts:
            return np.zeros((0, 3)), np.zeros((0, 3))
        return np.vstack(pts), np.vstack(nrm)

    def _clutter(self, rng, lo, hi):
        """Small-object features inside the outlines, clear of walls and boxes, (K, 3) m."""
        out = []
        segs = self.obstacle_segments()[0]
        for poly in self.outlines:
            area = polygon_area(poly)
            n = rng.poisson(self.clutter_per_m2 * area)
            pmin, pmax = poly.min(axis=0), poly.max(axis=0)
            cand = rng.uniform(pmin, pmax, (int(n * np.prod(pmax - pmin) / area) + 1, 2))
            cand = cand[points_in_polygon(cand, poly)][:n]
            if len(cand) and len(segs):
                cand = cand[_distances_to_segments(cand, segs).min(axis=1) > 0.2]
            for box in self.boxes:
                cand = cand[~points_in_polygon(cand, box.footprint())]
            out.append(np.column_stack([cand, rng.uniform(lo, hi, len(cand))]))
        return np.vstack(out) if out else np.zeros((0, 3))

    def _wall_face_samples(self, rng, n, length, h, lo, hi):
        """n feature positions on a wall face: u along it (m), z height (m).

        Real walls are textured in patches (posters, shelves, frames) between blank paint:
        ``wall_texture_cluster_fraction`` of the features gather in Gaussian patches, the rest
        spread evenly, a share of them in the height band [lo, hi].
        """
        u0, u1 = _FEATURE_END_MARGIN_M, length - _FEATURE_END_MARGIN_M
        u = rng.uniform(u0, u1, n)
        in_band = rng.random(n) < self.wall_texture_band_fraction
        z = np.where(in_band, rng.uniform(lo, hi, n), rng.uniform(0.0, h, n))
        clustered = rng.random(n) < self.wall_texture_cluster_fraction
        k = int(np.count_nonzero(clustered))
        if k:
            n_patches = 1 + rng.poisson(length / 2.0)
            cu = rng.uniform(u0, u1, n_patches)
            cz = rng.uniform(lo, hi, n_patches) if hi > lo else np.full(n_patches, lo)
            su = rng.uniform(0.15, 0.6, n_patches)
            sz = rng.uniform(0.1, 0.4, n_patches)
            which = rng.integers(n_patches, size=k)
            u[clustered] = np.clip(cu[which] + su[which] * rng.standard_normal(k), u0, u1)
            z[clustered] = np.clip(cz[which] + sz[which] * rng.standard_normal(k), 0.0, h)
        return u, z

    def obstacle_segments(self):
        """Walls and box edges as (K, 4) segments (m) with heights (K,) m (walls: ceiling)."""
        walls = self.wall_segments()
        bsegs, bh = self.box_segments()
        heights = np.concatenate([np.full(len(walls), self.ceiling_height_m), bh])
        return np.vstack([walls, bsegs]), heights


# Loading and validation


def worlds_dir():
    """Directory of the shipped worlds: $SPARSE_NAV_WORLDS_DIR, else <repo root>/worlds."""
    env = os.environ.get(WORLDS_DIR_ENV)
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "worlds"


def list_worlds():
    """Names (file stems) of the shipped worlds, sorted."""
    d = worlds_dir()
    if not d.is_dir():
        return []
    return sorted(p.stem for p in d.glob("*.yaml"))


def load_world(name_or_path):
    """Load a world by shipped name ("one_room"), YAML path, or "random:SEED".

    Raises:
      WorldError: unknown name (the message lists the known ones), missing or unreadable file,
        YAML syntax error, or any schema/geometry problem found by :func:`world_from_dict`.
    """
    spec = str(name_or_path).strip()
    if spec.startswith("random:"):
        from sparse_nav.sim.generator import random_world  # generator imports this module
        try:
            seed = int(spec[len("random:"):])
        except ValueError:
            raise WorldError(f"world {spec!r}: the seed after 'random:' must be an "
                             "integer") from None
        return random_world(seed)
    looks_like_path = (os.sep in spec or spec.endswith((".yaml", ".yml"))
                       or (os.altsep is not None and os.altsep in spec))
    if looks_like_path:
        path = Path(spec)
        if not path.is_file():
            raise WorldError(f"world file {spec}: not found")
    else:
        path = worlds_dir() / f"{spec}.yaml"
        if not path.is_file():
            known = ", ".join(list_worlds()) or f"none in {worlds_dir()}"
            raise WorldError(f"unknown world {spec!r}; known worlds: {known} "
                             f"(or a path to a .yaml file, or random:SEED)")
    try:
        text = path.read_text()
    except OSError as exc:
        raise WorldError(f"world file {path}: cannot read: {exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise WorldError(f"world file {path}: YAML syntax error: {exc}") from None
    return world_from_dict(data, default_name=path.stem, source=str(path))


_TOP_KEYS = frozenset({
    "name", "ceiling_height_m", "floor_texture_per_m2", "ceiling_texture_per_m2", "start",
    "walls", "boxes", "exits", "wall_texture_band_m", "wall_texture_band_fraction",
    "wall_texture_cluster_fraction", "clutter_per_m2"})
_REQUIRED_TOP = ("ceiling_height_m", "start", "walls", "exits")
_WALL_KEYS = frozenset({"name", "points", "closed", "texture_per_m2", "segment_texture_per_m2",
                        "doors"})
_DOOR_KEYS = frozenset({"segment", "at_m", "width_m"})
_BOX_KEYS = frozenset({"center", "size", "yaw_deg", "height_m", "texture_per_m2"})
_EXIT_KEYS = frozenset({"x", "y", "width_m"})
_START_KEYS = frozenset({"x", "y", "yaw_deg"})


class _Checker:
    """Reads typed values from the parsed YAML, raising WorldError naming source and key path."""

    def __init__(self, source):
        self.source = source

    def fail(self, where, problem):
        raise WorldError(f"world {self.source}: {where}: {problem}")

    def mapping(self, value, where, allowed, required=()):
        if not isinstance(value, dict):
            self.fail(where, f"must be a mapping, got {type(value).__name__}")
        unknown = sorted(str(k) for k in value if k not in allowed)
        if unknown:
            self.fail(where, f"unknown key(s) {', '.join(unknown)}; allowed: "
                      f"{', '.join(sorted(allowed))}")
        for key in required:
            if key not in value:
                self.fail(where, f"missing key '{key}'")
        return value

    def number(self, value, where, minimum=None, strict=False):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(where, f"must be a number, got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            self.fail(where, f"must be finite, got {value!r}")
        if minimum is not None and (v < minimum or (strict and v == minimum)):
            self.fail(where, f"must be {'>' if strict else '>='} {minimum}, got {v:g}")
        return v

    def point(self, value, where):
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            self.fail(where, f"must be a pair [x, y], got {value!r}")
        return (self.number(value[0], f"{where}[0]"), self.number(value[1], f"{where}[1]"))

    def sequence(self, value, where):
        if not isinstance(value, list):
            self.fail(where, f"must be a list, got {type(value).__name__}")
        return value


def world_from_dict(data, default_name="world", source=None):
    """Build and validate a :class:`World` from parsed YAML.

    Schema (metres, degrees; unknown keys are errors):
      name: str, optional (default: the file name)
      ceiling_height_m: > 0
      floor_texture_per_m2, ceiling_texture_per_m2: >= 0, optional (default 2 and 1)
      start: {x, y, yaw_deg}
      walls: list of polylines {name (optional), points: [[x, y], ...] (>= 2, >= 3 if closed),
             closed: bool (default false; a closed polyline is a room outline, textured inside),
             texture_per_m2: >= 0 (default 40),
             segment_texture_per_m2: {segment index: density} (optional overrides),
             doors: [{segment: index (optional), at_m, width_m}]}
             A door is a gap of width_m centred at at_m metres along the given segment (from its
             first point) or, without ``segment``, along the whole polyline; it must fit inside
             one segment.
      boxes: [{center: [x, y], size: [w, d], yaw_deg (default 0), height_m, texture_per_m2}]
      exits: [{x, y, width_m}], each at a door gap of a closed outline
      wall_texture_band_m: [lo, hi], wall_texture_band_fraction: in [0, 1] (optional)
      wall_texture_cluster_fraction: in [0, 1] (optional, default 0.5)
      clutter_per_m2: >= 0 (optional, default 0): small-object features per m^2 of floor

    Raises:
      WorldError: naming ``source`` and the problem.
    """
    ck = _Checker(source or default_name)
    if data is None:
        ck.fail("file", "is empty")
    ck.mapping(data, "top level", _TOP_KEYS, _REQUIRED_TOP)
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        ck.fail("name", f"must be a non-empty string, got {name!r}")
    ceiling = ck.number(data["ceiling_height_m"], "ceiling_height_m", 0.0, strict=True)
    floor_tex = ck.number(data.get("floor_texture_per_m2", 2.0), "floor_texture_per_m2", 0.0)
    ceil_tex = ck.number(data.get("ceiling_texture_per_m2", 1.0), "ceiling_texture_per_m2", 0.0)

    walls, gaps = [], []
    wall_list = ck.sequence(data["walls"], "walls")
    if not wall_list:
        ck.fail("walls", "must hold at least one wall")
    outlines = []
    for wi, wd in enumerate(wall_list):
        w_walls, w_gaps, outline = _parse_wall(ck, wd, wi)
        walls += w_walls
        gaps += w_gaps
        if outline is not None:
            outlines.append(outline)

    boxes = []
    for bi, bd in enumerate(ck.sequence(data.get("boxes", []) or [], "boxes")):
        where = f"boxes[{bi}]"
        ck.mapping(bd, where, _BOX_KEYS, ("center", "size", "height_m"))
        size = ck.point(bd["size"], f"{where}.size")
        if size[0] <= 0 or size[1] <= 0:
            ck.fail(f"{where}.size", f"both sizes must be > 0, got {list(size)}")
        boxes.append(Box(center=ck.point(bd["center"], f"{where}.center"), size=size,
                         yaw_rad=math.radians(ck.number(bd.get("yaw_deg", 0.0),
                                                        f"{where}.yaw_deg")),
                         height_m=ck.number(bd["height_m"], f"{where}.height_m", 0.0, True),
                         texture_per_m2=ck.number(bd.get("texture_per_m2", 40.0),
                                                  f"{where}.texture_per_m2", 0.0)))

    sd = ck.mapping(data["start"], "start", _START_KEYS, ("x", "y"))
    start = (ck.number(sd["x"], "start.x"), ck.number(sd["y"], "start.y"),
             math.radians(ck.number(sd.get("yaw_deg", 0.0), "start.yaw_deg")))

    exits = []
    for ei, ed in enumerate(ck.sequence(data["exits"], "exits")):
        where = f"exits[{ei}]"
        ck.mapping(ed, where, _EXIT_KEYS, ("x", "y"))
        ex = {"x": ck.number(ed["x"], f"{where}.x"), "y": ck.number(ed["y"], f"{where}.y"),
              "width_m": ck.number(ed.get("width_m", 0.9), f"{where}.width_m", 0.0, True)}
        outer = [g for g in gaps if g[4]]
        dists = [_point_segment_distance(np.array([ex["x"], ex["y"]]), np.array(g[:4]))
                 for g in outer]
        if not dists or min(dists) > _EXIT_TO_GAP_MAX_M:
            near = f"nearest outer door gap is {min(dists):.2f} m away" if dists else \
                "the world has no door gap in a closed outline"
            ck.fail(where, f"exit at ({ex['x']:g}, {ex['y']:g}) is not at a door gap "
                    f"({near}; must be within {_EXIT_TO_GAP_MAX_M} m)")
        exits.append(ex)

    band = data.get("wall_texture_band_m", [0.3, 1.9])
    band = ck.point(band, "wall_texture_band_m")
    if band[1] < band[0]:
        ck.fail("wall_texture_band_m", f"must be [lo, hi] with lo <= hi, got {list(band)}")
    band_frac = ck.number(data.get("wall_texture_band_fraction", 0.6),
                          "wall_texture_band_fraction", 0.0)
    if band_frac > 1:
        ck.fail("wall_texture_band_fraction", f"must be in [0, 1], got {band_frac:g}")

    cluster_frac = ck.number(data.get("wall_texture_cluster_fraction", 0.5),
                             "wall_texture_cluster_fraction", 0.0)
    if cluster_frac > 1:
        ck.fail("wall_texture_cluster_fraction", f"must be in [0, 1], got {cluster_frac:g}")

    clutter = ck.number(data.get("clutter_per_m2", 0.0), "clutter_per_m2", 0.0)

    world = World(name=name, walls=walls, boxes=boxes, ceiling_height_m=ceiling,
                  floor_texture=floor_tex, ceiling_texture=ceil_tex, exits=exits, start=start,
                  door_gaps=gaps, wall_texture_band_m=band, wall_texture_band_fraction=band_frac,
                  wall_texture_cluster_fraction=cluster_frac, clutter_per_m2=clutter,
                  outlines=outlines)
    _check_start(ck, world, outlines)
    return world


def _parse_wall(ck, wd, wi):
    """One polyline entry -> (walls, door gaps, outline polygon or None)."""
    where = f"walls[{wi}]"
    ck.mapping(wd, where, _WALL_KEYS, ("points",))
    wname = wd.get("name", str(wi))
    if not isinstance(wname, (str, int)):
        ck.fail(f"{where}.name", f"must be a string, got {wname!r}")
    where = f"wall '{wname}'"
    raw = ck.sequence(wd["points"], f"{where}.points")
    pts = [ck.point(p, f"{where}.points[{i}]") for i, p in enumerate(raw)]
    closed = wd.get("closed", False)
    if not isinstance(closed, bool):
        ck.fail(f"{where}.closed", f"must be true or false, got {closed!r}")
    need = 3 if closed else 2
    if len(pts) < need:
        ck.fail(f"{where}.points", f"a {'closed' if closed else 'open'} wall needs at least "
                f"{need} points, got {len(pts)}")
    verts = pts + [pts[0]] if closed else pts
    segs = [(verts[i], verts[i + 1]) for i in range(len(verts) - 1)]
    for si, (a, b) in enumerate(segs):
        if math.hypot(b[0] - a[0], b[1] - a[1]) < 1e-6:
            ck.fail(f"{where}.points", f"segment {si} has zero length at ({a[0]:g}, {a[1]:g})")
    tex = ck.number(wd.get("texture_per_m2", 40.0), f"{where}.texture_per_m2", 0.0)
    seg_tex = [tex] * len(segs)
    overrides = wd.get("segment_texture_per_m2", {}) or {}
    if not isinstance(overrides, dict):
        ck.fail(f"{where}.segment_texture_per_m2", "must be a mapping {segment index: density}")
    for key, val in overrides.items():
        if isinstance(key, bool) or not isinstance(key, int) or not 0 <= key < len(segs):
            ck.fail(f"{where}.segment_texture_per_m2", f"segment index {key!r} is not in "
                    f"0..{len(segs) - 1}")
        seg_tex[key] = ck.number(val, f"{where}.segment_texture_per_m2[{key}]", 0.0)

    # Doors cut [start, end] intervals out of segments.
    cuts = [[] for _ in segs]
    lengths = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in segs]
    for di, dd in enumerate(ck.sequence(wd.get("doors", []) or [], f"{where}.doors")):
        dwhere = f"{where}.doors[{di}]"
        ck.mapping(dd, dwhere, _DOOR_KEYS, ("at_m", "width_m"))
        at = ck.number(dd["at_m"], f"{dwhere}.at_m", 0.0)
        width = ck.number(dd["width_m"], f"{dwhere}.width_m", 0.0, strict=True)
        if "segment" in dd:
            si = dd["segment"]
            if isinstance(si, bool) or not isinstance(si, int) or not 0 <= si < len(segs):
                ck.fail(f"{dwhere}.segment", f"must be a segment index in 0..{len(segs) - 1}, "
                        f"got {si!r}")
        else:
            si, rest = 0, at
            while si < len(segs) - 1 and rest > lengths[si]:
                rest -= lengths[si]
                si += 1
            if rest > lengths[si] + 1e-9:
                ck.fail(f"{dwhere}.at_m", f"{at:g} m is beyond the end of the wall "
                        f"(length {sum(lengths):.2f} m)")
            at = rest
        lo, hi = at - width / 2.0, at + width / 2.0
        if width > lengths[si] + 1e-9:
            ck.fail(dwhere, f"door width {width:g} m is wider than its wall segment {si} "
                    f"(length {lengths[si]:.2f} m)")
        if lo < -1e-9 or hi > lengths[si] + 1e-9:
            ck.fail(dwhere, f"door [{lo:.2f}, {hi:.2f}] m does not fit in segment {si} "
                    f"(length {lengths[si]:.2f} m)")
        for olo, ohi in cuts[si]:
            if lo < ohi and olo < hi:
                ck.fail(dwhere, f"door overlaps another door in segment {si}")
        cuts[si].append((max(lo, 0.0), min(hi, lengths[si])))

    area2 = 0.0
    if closed:
        area2 = sum(a[0] * b[1] - b[0] * a[1] for a, b in segs)
        if abs(area2) < 1e-9:
            ck.fail(f"{where}.points", "a closed wall must enclose a non-zero area")
    walls, gaps = [], []
    for si, ((a, b), length) in enumerate(zip(segs, lengths)):
        d = ((b[0] - a[0]) / length, (b[1] - a[1]) / length)
        # Inside of a counter-clockwise outline is on the left of each segment.
        sign = 1.0 if area2 > 0 else -1.0
        normal = (-d[1] * sign, d[0] * sign) if closed else (0.0, 0.0)
        keep, pos = [], 0.0
        for lo, hi in sorted(cuts[si]):
            if lo > pos:
                keep.append((pos, lo))
            gaps.append((a[0] + d[0] * lo, a[1] + d[1] * lo, a[0] + d[0] * hi,
                         a[1] + d[1] * hi, closed))
            pos = hi
        if pos < length:
            keep.append((pos, length))
        for lo, hi in keep:
            if hi - lo < 1e-6:
                continue
            walls.append(Wall(a[0] + d[0] * lo, a[1] + d[1] * lo, a[0] + d[0] * hi,
                              a[1] + d[1] * hi, seg_tex[si], faces=1 if closed else 2,
                              normal=normal, name=f"{wname}:{si}"))
    return walls, gaps, (np.array(pts) if closed else None)


def _check_start(ck, world, outlines):
    """The start must be inside a room outline (when there is one) and clear of walls/boxes."""
    p = np.array(world.start[:2])
    if outlines and not any(point_in_polygon(p, poly) for poly in outlines):
        ck.fail("start", f"({p[0]:g}, {p[1]:g}) is not inside any closed wall outline")
    segs, _ = world.obstacle_segments()
    if len(segs):
        d = segment_distances(p, segs).min()
        if d < _START_CLEARANCE_M:
            ck.fail("start", f"({p[0]:g}, {p[1]:g}) is {d:.2f} m from a wall or box; "
                    f"needs {_START_CLEARANCE_M} m")
    for bi, box in enumerate(world.boxes):
        if point_in_polygon(p, box.footprint()):
            ck.fail("start", f"({p[0]:g}, {p[1]:g}) is inside box {bi}")


# Small 2D geometry helpers shared by the simulator modules


def point_in_polygon(p, poly):
    """True if the 2D point p lies inside the polygon (M, 2) (even-odd rule)."""
    return bool(points_in_polygon(np.asarray(p, dtype=float).reshape(1, 2), poly)[0])


def points_in_polygon(points, poly):
    """Boolean mask (N,) of 2D points (N, 2) inside the polygon (M, 2) (even-odd rule)."""
    x, y = points[:, 0:1], points[:, 1:2]
    xs, ys = poly[None, :, 0], poly[None, :, 1]
    xj, yj = np.roll(xs, 1, axis=1), np.roll(ys, 1, axis=1)
    dy = np.where(yj == ys, 1e-300, yj - ys)
    crosses = ((ys > y) != (yj > y)) & (x < (xj - xs) * (y - ys) / dy + xs)
    return np.count_nonzero(crosses, axis=1) % 2 == 1


def doorway_strip(xy, gap, inside_xy, reach_m=1.0):
    """Cells of a door's doorway and how far beyond the door they lie.

    xy: (N, 2) points (m); gap: the door gap (x1, y1, x2, y2) (m); inside_xy: a point on the
    room's side of the door. Returns (mask, beyond_m): mask (N,) is True inside the strip as wide
    as the gap reaching reach_m to either side of its wall; beyond_m (N,) is each point's signed
    distance (m) from the wall line, positive away from inside_xy.
    """
    a, b = np.asarray(gap[:2], dtype=float), np.asarray(gap[2:4], dtype=float)
    middle, width_m = (a + b) / 2, float(np.linalg.norm(b - a))
    along = (b - a) / width_m
    normal = np.array([-along[1], along[0]])
    if normal @ (np.asarray(inside_xy, dtype=float) - middle) > 0:
        normal = -normal
    offset = np.asarray(xy, dtype=float) - middle
    beyond_m = offset @ normal
    return (np.abs(offset @ along) <= width_m / 2) & (np.abs(beyond_m) <= reach_m), beyond_m


def polygon_area(poly):
    """Area (m^2) of a simple polygon (M, 2)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _distances_to_segments(points, segs):
    """Distances (N, K) in metres from 2D points (N, 2) to segments (K, 4)."""
    a = segs[None, :, :2]
    ab = segs[None, :, 2:] - a
    ap = points[:, None, :] - a
    t = np.clip(np.sum(ap * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-18), 0, 1)
    d = ap - t[:, :, None] * ab
    return np.hypot(d[:, :, 0], d[:, :, 1])


def segment_distances(p, segs):
    """Distances (K,) in metres from the 2D point p to each segment (K, 4)."""
    a = segs[:, :2]
    ab = segs[:, 2:] - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
    t = np.clip(np.einsum("ij,ij->i", np.asarray(p)[None, :] - a, ab) / denom, 0.0, 1.0)
    closest = a + t[:, None] * ab
    return np.hypot(closest[:, 0] - p[0], closest[:, 1] - p[1])


def _point_segment_distance(p, seg):
    return float(segment_distances(p, seg[None, :])[0])
