"""Random worlds from a seed: a rectangular, L-shaped or two-room building with 1-2 exits.

Exits are door gaps of 0.8-1.2 m in the outer wall, some at the end of a short recess in a
corner (the seed 000 escape room), each with a textured wall a few metres beyond it (what the
camera sees through the door). Some walls are nearly featureless, some furniture boxes stand in
the room, and the whole world has a random heading. The result goes through the same validation
as a YAML world, so a generated world is always a valid one.
"""
import math

import numpy as np

from sparse_nav.sim.world import point_in_polygon, segment_distances, world_from_dict

# Clearances (m): furniture keeps paths open; the start has room to move.
_BOX_WALL_CLEARANCE_M = 0.7
_BOX_START_CLEARANCE_M = 1.2
_BOX_DOOR_CLEARANCE_M = 1.5
_START_WALL_CLEARANCE_M = 1.0
_DOOR_END_MARGIN_M = 0.5


def random_world(seed):
    """A random, valid :class:`World` named ``random:SEED``; the same seed gives the same world."""
    rng = np.random.default_rng(int(seed))
    kind = ("rect", "l_shape", "two_rooms")[int(rng.integers(3))]
    outline, partitions, start_region = _shape(kind, rng)

    # Exits: some in a recess at a convex corner, others as plain doors in a long outer segment.
    n_exits = int(rng.integers(1, 3))
    recess = [bool(rng.random() < 0.5) for _ in range(n_exits)]
    doors = []                                  # (segment index, at_m, width_m) in the outline
    corners = [i for i in _convex_corners(outline)
               if _seg_len(outline, i) >= 2.6]  # next edge holds a recess and a margin
    rng.shuffle(corners)
    corners = sorted(corners[:sum(recess)], reverse=True)   # insert from the end: indices hold
    for i in corners:
        outline, door = _add_recess(outline, i, rng)
        doors = [(s + 2 if s > i else s, a, w) for s, a, w in doors] + [door]
    for _ in range(n_exits - len(corners)):
        used = {s for s, _, _ in doors}
        recess_segs = {s + d for s, _, _ in doors for d in (-1, 0, 1)}
        options = [s for s in range(len(outline)) if _seg_len(outline, s) >= 2.2
                   and s not in used and s not in recess_segs]
        if not options:
            break
        s = options[int(rng.integers(len(options)))]
        length = _seg_len(outline, s)
        width = float(rng.uniform(0.8, 1.2))
        at = float(rng.uniform(_DOOR_END_MARGIN_M + width / 2,
                               length - _DOOR_END_MARGIN_M - width / 2))
        doors.append((s, at, width))

    poly = np.array(outline)
    exits, backdrops = [], []
    for s, at, width in doors:
        a, b = poly[s], poly[(s + 1) % len(poly)]
        d = (b - a) / np.linalg.norm(b - a)
        centre = a + d * at
        exits.append({"x": float(centre[0]), "y": float(centre[1]), "width_m": width})
        backdrop = _backdrop(poly, backdrops, centre, d, rng)
        if backdrop is not None:
            backdrops.append(backdrop)

    base_tex = float(rng.uniform(50.0, 110.0))
    seg_tex = {}
    door_segs = {s for s, _, _ in doors}
    # Up to two nearly blank walls, at most a quarter of the perimeter: a room that is mostly
    # blank cannot be mapped by any monocular SLAM.
    perimeter = sum(_seg_len(outline, s) for s in range(len(outline)))
    budget = 0.25 * perimeter
    candidates = [int(s) for s in rng.permutation(len(outline)) if s not in door_segs]
    for s in candidates[:int(rng.integers(0, 3))]:
        if _seg_len(outline, s) <= budget:
            seg_tex[s] = float(rng.uniform(0.0, 3.0))
            budget -= _seg_len(outline, s)

    walls = [{"name": "outer", "points": [list(map(float, p)) for p in outline], "closed": True,
              "texture_per_m2": base_tex, "segment_texture_per_m2": seg_tex,
              "doors": [{"segment": int(s), "at_m": float(a), "width_m": float(w)}
                        for s, a, w in doors]}]
    for k, (pts, door) in enumerate(partitions):
        walls.append({"name": f"partition{k}", "points": pts, "texture_per_m2": base_tex,
                      "doors": [door] if door else []})
    for k, seg in enumerate(backdrops):
        walls.append({"name": f"beyond_exit{k}", "points": seg,
                      "texture_per_m2": float(rng.uniform(50.0, 110.0))})

    start = _sample_start(poly, walls, start_region, rng)
    door_centres = [(e["x"], e["y"]) for e in exits]
    for pts, door in partitions:
        a, b = np.array(pts[0]), np.array(pts[1])
        door_centres.append(tuple(a + (b - a) / np.linalg.norm(b - a) * door["at_m"]))
    boxes = _sample_boxes(poly, walls, start, door_centres, rng)
    heading = float(rng.uniform(-math.pi, math.pi))
    data = {
        "name": f"random:{int(seed)}",
        "ceiling_height_m": float(rng.uniform(2.4, 3.5)),
        "floor_texture_per_m2": float(rng.uniform(1.0, 4.0)),
        "ceiling_texture_per_m2": float(rng.uniform(0.0, 2.0)),
        "clutter_per_m2": float(rng.uniform(1.0, 8.0)),
        "start": {"x": start[0], "y": start[1], "yaw_deg": float(rng.uniform(-180.0, 180.0))},
        "walls": walls,
        "boxes": boxes,
        "exits": exits,
    }
    return world_from_dict(_rotate(data, heading), source=f"random:{int(seed)}")


def _shape(kind, rng):
    """Counter-clockwise outline, partitions [(points, door dict)], start region (x0,y0,x1,y1)."""
    if kind == "rect":
        w, h = rng.uniform(4.0, 12.0, 2)
        return [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)], [], (0.0, 0.0, w, h)
    if kind == "l_shape":
        w, h = rng.uniform(6.0, 12.0, 2)
        cw = w * rng.uniform(0.35, 0.6)
        ch = h * rng.uniform(0.35, 0.6)
        outline = [(0.0, 0.0), (w, 0.0), (w, h - ch), (w - cw, h - ch), (w - cw, h), (0.0, h)]
        return outline, [], (0.0, 0.0, w, h - ch)
    wa, wb = rng.uniform(4.0, 7.0, 2)
    ha, hb = rng.uniform(4.0, 8.0, 2)
    if abs(ha - hb) < 0.5:
        hb = ha
        outline = [(0.0, 0.0), (wa + wb, 0.0), (wa + wb, ha), (0.0, ha)]
    else:
        outline = [(0.0, 0.0), (wa + wb, 0.0), (wa + wb, hb), (wa, hb), (wa, ha), (0.0, ha)]
    shared = min(ha, hb)
    width = float(rng.uniform(0.8, 1.2))
    at = float(rng.uniform(_DOOR_END_MARGIN_M + width / 2, shared - _DOOR_END_MARGIN_M - width / 2))
    partition = ([[float(wa), 0.0], [float(wa), float(shared)]],
                 {"segment": 0, "at_m": at, "width_m": width})
    return outline, [partition], (0.0, 0.0, wa, ha)


def _seg_len(outline, i):
    a, b = np.array(outline[i]), np.array(outline[(i + 1) % len(outline)])
    return float(np.linalg.norm(b - a))


def _convex_corners(outline):
    """Indices of convex vertices of a counter-clockwise outline."""
    n = len(outline)
    out = []
    for i in range(n):
        p, v, q = (np.array(outline[(i - 1) % n]), np.array(outline[i]),
                   np.array(outline[(i + 1) % n]))
        d1, d2 = v - p, q - v
        if d1[0] * d2[1] - d1[1] * d2[0] > 0:
            out.append(i)
    return out


def _add_recess(outline, i, rng):
    """Replace convex corner i by an alcove along the next edge, with a door in its end wall.

    The previous edge runs on past the corner by the recess depth, the end wall (the door's
    wall) runs parallel to the next edge, and a short wall comes back to the room: the notch
    of seed 000 that gives the exit two extra lines and a concave vertex.
    """
    n = len(outline)
    p, v, q = (np.array(outline[(i - 1) % n]), np.array(outline[i]),
               np.array(outline[(i + 1) % n]))
    d1 = (v - p) / np.linalg.norm(v - p)
    d2 = (q - v) / np.linalg.norm(q - v)
    depth = float(rng.uniform(0.5, 1.0))
    width = float(rng.uniform(1.0, 1.4))
    v1 = v + depth * d1
    v2 = v1 + width * d2
    v3 = v + width * d2
    new = list(outline[:i]) + [tuple(v1), tuple(v2), tuple(v3)] + list(outline[i + 1:])
    door_w = float(rng.uniform(0.8, min(1.2, width - 0.1)))
    return new, (i, width / 2.0, door_w)


def _segments_cross(a, b, c, d):
    """True if 2D segments ab and cd intersect."""
    def orient(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    o1, o2 = orient(a, b, c), orient(a, b, d)
    o3, o4 = orient(c, d, a), orient(c, d, b)
    return (o1 * o2 <= 0) and (o3 * o4 <= 0)


def _backdrop(poly, others, centre, d, rng):
    """A textured wall segment beyond an exit, parallel to its wall, clear of the building and
    of the other backdrops, seen straight through the door; None if none fits."""
    outward = np.array([d[1], -d[0]])      # right of a counter-clockwise outline's edge
    segs = [(poly[k], poly[(k + 1) % len(poly)]) for k in range(len(poly))]
    segs += [(np.array(o[0]), np.array(o[1])) for o in others]
    seg_array = np.array([[*s0, *s1] for s0, s1 in segs])
    for dist in (rng.uniform(1.5, 3.0), 1.5, 1.2):
        mid = centre + outward * dist
        if any(_segments_cross(centre + outward * 0.05, mid, s0, s1) for s0, s1 in segs):
            continue  # the view from the door would hit the building first
        half = rng.uniform(1.5, 2.5)
        for _ in range(3):
            a, b = mid - d * half, mid + d * half
            if not any(_segments_cross(a, b, s0, s1) for s0, s1 in segs) and \
                    segment_distances(mid, seg_array).min() > 0.8:
                return [[float(a[0]), float(a[1])], [float(b[0]), float(b[1])]]
            half *= 0.6
    return None


def _all_segments(walls):
    segs = []
    for w in walls:
        pts = [np.array(p) for p in w["points"]]
        if w.get("closed"):
            pts.append(pts[0])
        segs += [[*pts[k], *pts[k + 1]] for k in range(len(pts) - 1)]
    return np.array(segs)


def _sample_start(poly, walls, region, rng):
    """A start position inside the outline and the start region, clear of every wall."""
    segs = _all_segments(walls)
    x0, y0, x1, y1 = region
    for _ in range(500):
        p = rng.uniform([x0, y0], [x1, y1])
        if point_in_polygon(p, poly) and segment_distances(p, segs).min() >= \
                _START_WALL_CLEARANCE_M:
            return float(p[0]), float(p[1])
    # Region centre as a fallback: every generated region is at least 4 m x 2.4 m.
    return float((x0 + x1) / 2), float((y0 + y1) / 2)


def _sample_boxes(poly, walls, start, doors, rng):
    """0-5 furniture boxes inside the outline, clear of walls, the start, doors (centres, m)
    and each other."""
    segs = _all_segments(walls)
    xmin, ymin = poly.min(axis=0)
    xmax, ymax = poly.max(axis=0)
    boxes, footprints = [], []
    for _ in range(int(rng.integers(0, 6))):
        for _ in range(50):
            size = rng.uniform(0.4, 1.5, 2)
            yaw = float(rng.uniform(0.0, 180.0)) if rng.random() < 0.3 else 0.0
            centre = rng.uniform([xmin, ymin], [xmax, ymax])
            c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
            local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * size / 2
            fp = local @ np.array([[c, s], [-s, c]]) + centre
            radius = float(np.linalg.norm(size)) / 2
            if not all(point_in_polygon(q, poly) for q in fp):
                continue
            if segment_distances(centre, segs).min() < radius + _BOX_WALL_CLEARANCE_M:
                continue
            if np.hypot(*(centre - start)) < radius + _BOX_START_CLEARANCE_M:
                continue
            if any(np.hypot(centre[0] - dx, centre[1] - dy) < radius + _BOX_DOOR_CLEARANCE_M
                   for dx, dy in doors):
                continue
            if any(np.hypot(*(centre - oc)) < radius + orad + _BOX_WALL_CLEARANCE_M
                   for oc, orad in footprints):
                continue
            footprints.append((centre, radius))
            boxes.append({"center": [float(centre[0]), float(centre[1])],
                          "size": [float(size[0]), float(size[1])], "yaw_deg": yaw,
                          "height_m": float(rng.uniform(0.4, 1.8)),
                          "texture_per_m2": float(rng.uniform(20.0, 80.0))})
            break
    return boxes


def _rotate(data, heading):
    """The world description rotated by heading (rad) about the origin."""
    c, s = math.cos(heading), math.sin(heading)

    def rot(p):
        return [c * p[0] - s * p[1], s * p[0] + c * p[1]]

    for w in data["walls"]:
        w["points"] = [rot(p) for p in w["points"]]
    for b in data["boxes"]:
        b["center"] = rot(b["center"])
        b["yaw_deg"] = b["yaw_deg"] + math.degrees(heading)
    for e in data["exits"]:
        e["x"], e["y"] = rot([e["x"], e["y"]])
    st = data["start"]
    st["x"], st["y"] = rot([st["x"], st["y"]])
    st["yaw_deg"] = st["yaw_deg"] + math.degrees(heading)
    return data
