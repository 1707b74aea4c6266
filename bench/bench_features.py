#!/usr/bin/python3
"""Geometric features (seed 002, issue 6): speed on CARMEN logs, accuracy on simulator worlds.

1. Speed and Procrustes, on the CARMEN logs of ../shared/data/laser (read from there; skipped
   with a note when absent): scans per second of `extract_features` (extraction only, file parsing
   reported apart, best of --repeat passes), and the median translation / rotation error of
   Procrustes between consecutive scans against the logs' corrected poses.
2. Accuracy, on the shipped simulator worlds (no ../shared data): from many random free poses per
   world, a 360-beam scan is ray-cast in the world's walls and box footprints (the virtual scan a
   dense obstacle cloud gives, range 10 m) with Gaussian range noise (sigma 1 cm and 3 cm; the
   extractor is given that sigma and a split threshold of max(5 cm, 4 sigma)), and the features
   are scored against the world geometry:
   - walls: a detected wall is right when both its ends lie within 0.1 m of one true wall line
     (collinear touching world segments joined; door gaps split them) and its direction is within
     5 deg; a true wall counts as seen when a run of >= 5 consecutive beams over >= 0.3 m hits it,
     and is found when a right detection covers >= half of that run;
   - doors: a detected door is right when its centre is within 0.2 m of a true door gap's centre; a
     true door counts as seen when the walls on both sides are seen up to its jambs (within 0.15 m)
     and no beam through the gap is stopped in front of it;
   - corners: a detected inner / outer corner is right when it is within 0.1 m of a world vertex
     whose type, seen from the robot, is the same: the vertex's segments split the plane into
     sectors, the robot's sector is bounded by the two walls it sees, meeting at 30-150 deg; outer
     when that sector is under 180 deg (a room corner), inner when over (a corner pointing at the
     robot). A true corner counts as seen when two seen walls' runs meet there in consecutive
     beams. Potential corners are reported, not scored.
Writes bench/results/features.json.
"""
import argparse
import glob
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
sys.path.insert(0, os.path.join(ROOT, "src"))

from sparse_nav.sim import list_worlds, load_world  # noqa: E402

LASER_DIR = os.path.normpath(os.path.join(ROOT, "..", "shared", "data", "laser", "acschaefer__ple"))
LOGS = [("Intel", "intel-corrected.log.gz"), ("Freiburg 079", "freiburg-079-corrected.log.gz"),
        ("ACES", "aces-corrected.log.gz"), ("MIT infinite corridor", "infinite-corridor-corrected.log.gz"),
        ("MIT CSAIL", "csail-corrected.log.gz")]
N_BEAMS = 360
RANGE_MAX_M = 10.0
WALL_TOL_M, WALL_TOL_DEG, DOOR_TOL_M, CORNER_TOL_M = 0.1, 5.0, 0.2, 0.1
MIN_RUN_BEAMS, MIN_RUN_M = 5, 0.3


def find_tool():
    env = os.environ.get("SPARSE_NAV_EXTRACT_FEATURES")
    if env:
        return env
    for ws in ["ws"] + sorted(os.path.basename(p) for p in glob.glob(os.path.join(ROOT, "build", "ws_*"))):
        path = os.path.join(ROOT, "build", ws, "devel", "lib", "sparse_nav", "extract_features")
        if os.access(path, os.X_OK):
            return path
    return None


def run_tool(tool, path, *args):
    out = subprocess.run([tool, path, "--json", *args], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def bench_logs(tool, repeat):
    if not os.path.isdir(LASER_DIR):
        print(f"CARMEN logs: {LASER_DIR} is absent; speed and Procrustes figures skipped")
        return {"skipped": f"{LASER_DIR} absent"}
    print(f"CARMEN logs read from {LASER_DIR}")
    rows = {}
    print(f"{'log':24s} {'scans':>6s} {'beams':>5s} {'scans/s':>9s} {'us/scan':>8s} {'walls/scan':>10s} "
          f"{'doors':>6s} {'corners':>7s} {'match err m':>11s} {'deg':>6s} {'motion m':>8s} {'deg':>6s}")
    for name, fname in LOGS:
        path = os.path.join(LASER_DIR, fname)
        if not os.path.exists(path):
            print(f"{name:24s} absent")
            continue
        best = None
        for _ in range(3):
            r = run_tool(tool, path, "--summary", "--repeat", str(repeat))
            if best is None or r["scans_per_s"] > best["scans_per_s"]:
                best = r
        m = run_tool(tool, path, "--summary", "--match")["match"]
        c = best["counts"]
        n = best["n_scans"]
        corners = c["corners_inner"] + c["corners_outer"] + c["corners_potential"]
        rows[name] = {"file": fname, "scans": n, "beams": best["max_beams"], "scans_per_s": best["scans_per_s"],
                      "median_us_per_scan": best["median_us_per_scan"], "parse_ms": best["parse_ms"],
                      "walls_per_scan": round(c["walls"] / n, 2), "doors": c["doors"],
                      "corners": {"inner": c["corners_inner"], "outer": c["corners_outer"],
                                  "potential": c["corners_potential"]},
                      "corridors": c["corridors"], "match": m}
        print(f"{name:24s} {n:6d} {best['max_beams']:5d} {best['scans_per_s']:9.0f} "
              f"{best['median_us_per_scan']:8.1f} {c['walls'] / n:10.2f} {c['doors']:6d} {corners:7d} "
              f"{m['median_translation_error_m']:11.3f} {m['median_rotation_error_deg']:6.2f} "
              f"{m['median_motion_m']:8.3f} {m['median_motion_deg']:6.2f}")
    return rows


def world_lines(world):
    """Obstacle segments joined into lines: collinear segments that touch become one."""
    segs, _ = world.obstacle_segments()
    segs = [tuple(map(float, s)) for s in segs]
    parent = list(range(len(segs)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def collinear_touching(a, b):
        da = np.array([a[2] - a[0], a[3] - a[1]])
        db = np.array([b[2] - b[0], b[3] - b[1]])
        na, nb = np.linalg.norm(da), np.linalg.norm(db)
        if abs(da[0] * db[1] - da[1] * db[0]) > 1e-6 * na * nb:
            return False
        ends_a = [np.array(a[:2]), np.array(a[2:])]
        ends_b = [np.array(b[:2]), np.array(b[2:])]
        return any(np.linalg.norm(p - q) < 1e-6 for p in ends_a for q in ends_b)

    for i in range(len(segs)):
        for j in range(i + 1, len(segs)):
            if collinear_touching(segs[i], segs[j]):
                parent[find(i)] = find(j)
    groups = {}
    for i, s in enumerate(segs):
        groups.setdefault(find(i), []).append(s)
    lines = []
    for members in groups.values():
        pts = np.array([p for s in members for p in (s[:2], s[2:])])
        d = np.array(members[0][2:]) - np.array(members[0][:2])
        d /= np.linalg.norm(d)
        t = pts @ d
        lines.append((pts[np.argmin(t)], pts[np.argmax(t)]))
    return np.array([[a[0], a[1], b[0], b[1]] for a, b in lines]), segs


def world_vertices(segs):
    """Points where two or more segments end, with the unit directions of their legs."""
    verts = []
    for s in segs:
        for p, q in ((s[:2], s[2:]), (s[2:], s[:2])):
            leg = np.subtract(q, p)
            leg = leg / np.linalg.norm(leg)
            for v in verts:
                if math.dist(v[0], p) < 1e-6:
                    v[1].append(leg)
                    break
            else:
                verts.append((np.array(p, dtype=float), [leg]))
    return [(v, legs) for v, legs in verts if len(legs) >= 2]


def corner_seen_as(vertex, legs, robot):
    """Type of the corner the robot sees at a vertex, or None when it sees none there.

    The legs split the plane around the vertex into sectors; the robot is in one. Its two bounding
    legs are the walls it sees: a sector under 180 deg is a room corner around the robot ('outer'),
    over 180 deg a corner pointing at it ('inner'); the walls must meet at 30-150 deg.
    """
    r = robot - vertex
    heading = math.atan2(r[1], r[0])
    angles = sorted(math.atan2(l[1], l[0]) for l in legs)
    prev = max(a for a in angles if a <= heading) if any(a <= heading for a in angles) else angles[-1]
    nxt = min(a for a in angles if a > heading) if any(a > heading for a in angles) else angles[0]
    sector = math.degrees((nxt - prev) % (2 * math.pi))
    inner_angle = sector if sector < 180.0 else 360.0 - sector
    if not 30.0 <= inner_angle <= 150.0:
        return None
    return "outer" if sector < 180.0 else "inner"


def cast(lines, x, y, yaw):
    """Hit distance and line index per beam (inf, -1 for none within RANGE_MAX_M)."""
    ang = yaw - math.pi + np.arange(N_BEAMS) * 2 * math.pi / N_BEAMS
    d = np.stack([np.cos(ang), np.sin(ang)], 1)
    a = lines[:, :2] - [x, y]
    e = lines[:, 2:] - lines[:, :2]
    den = d[:, :1] * e[None, :, 1] - d[:, 1:] * e[None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[None, :, 0] * e[None, :, 1] - a[None, :, 1] * e[None, :, 0]) / den
        u = (a[None, :, 0] * d[:, 1:] - a[None, :, 1] * d[:, :1]) / den
    ok = (np.abs(den) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
    t = np.where(ok, t, np.inf)
    idx = np.argmin(t, 1)
    dist = t[np.arange(N_BEAMS), idx]
    idx = np.where(np.isfinite(dist) & (dist <= RANGE_MAX_M), idx, -1)
    dist = np.where(idx >= 0, dist, np.inf)
    return ang, dist, idx


def runs_of(idx):
    """Maximal circular runs of equal line index >= 0: (line, first beam, last beam, length in beams)."""
    n = len(idx)
    if (idx == idx[0]).all():
        return [(int(idx[0]), 0, n - 1, n)] if idx[0] >= 0 else []
    start = next(i for i in range(n) if idx[i] != idx[i - 1])
    runs = []
    k = 0
    while k < n:
        b = (start + k) % n
        line = idx[b]
        m = 1
        while k + m < n and idx[(start + k + m) % n] == line:
            m += 1
        if line >= 0:
            runs.append((int(line), b, (b + m - 1) % n, m))
        k += m
    return runs


def point_to_segment(p, a, b):
    e = b - a
    u = np.clip((p - a) @ e / (e @ e), 0.0, 1.0)
    return float(np.linalg.norm(a + u * e - p))


def angle_between(d1, d2):
    c = abs(d1 @ d2) / np.linalg.norm(d1) / np.linalg.norm(d2)
    return math.degrees(math.acos(min(1.0, c)))


def free_poses(world, lines, n, rng):
    xmin, ymin, xmax, ymax = world.bounds()
    poses = []
    polys = [np.asarray(p, dtype=float) for p in world.outlines]
    boxes = [b.footprint() for b in world.boxes]

    def inside(poly, p):
        x, y = p
        c = False
        for i in range(len(poly)):
            (x1, y1), (x2, y2) = poly[i], poly[i - 1]
            if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
                c = not c
        return c

    tries = 0
    while len(poses) < n and tries < 100000:
        tries += 1
        p = np.array([rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)])
        if not any(inside(poly, p) for poly in polys) or any(inside(b, p) for b in boxes):
            continue
        if min(point_to_segment(p, l[:2], l[2:]) for l in lines) < 0.4:
            continue
        poses.append((p[0], p[1], rng.uniform(-math.pi, math.pi)))
    return poses


def ground_truth(world, lines, segs, corners, pose):
    x, y, yaw = pose
    robot = np.array([x, y])
    ang, dist, idx = cast(lines, x, y, yaw)
    hits = robot + dist[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
    seen_walls = []
    runs = runs_of(idx)
    for line, b0, b1, m in runs:
        a, b = hits[b0], hits[b1]
        if m >= MIN_RUN_BEAMS and np.linalg.norm(b - a) >= MIN_RUN_M:
            seen_walls.append((line, a, b, b0, b1))
    # Corners: two seen runs of different lines meeting in consecutive beams at a world corner.
    seen_corners = []
    for l1, _, b1, _, e1 in seen_walls:
        for l2, a2, _, s2, _ in seen_walls:
            if l1 == l2 or (e1 + 1) % N_BEAMS != s2:
                continue
            for v, legs in corners:
                if np.linalg.norm(b1 - v) < 0.15 and np.linalg.norm(a2 - v) < 0.15:
                    typ = corner_seen_as(v, legs, robot)
                    if typ:
                        seen_corners.append((v, typ))
                    break
    # Doors: walls seen up to both jambs, nothing in front of the gap.
    seen_doors = []
    for gx1, gy1, gx2, gy2, _ in world.door_gaps:
        j1, j2 = np.array([gx1, gy1]), np.array([gx2, gy2])
        near1 = any(np.linalg.norm(a - j1) < 0.15 or np.linalg.norm(b - j1) < 0.15 for _, a, b, _, _ in seen_walls)
        near2 = any(np.linalg.norm(a - j2) < 0.15 or np.linalg.norm(b - j2) < 0.15 for _, a, b, _, _ in seen_walls)
        if not (near1 and near2):
            continue
        # Beams whose ray crosses the gap must not stop short of it.
        e = j2 - j1
        d = np.stack([np.cos(ang), np.sin(ang)], 1)
        den = d[:, 0] * e[1] - d[:, 1] * e[0]
        aa = j1 - robot
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (aa[0] * e[1] - aa[1] * e[0]) / den
            u = (aa[0] * d[:, 1] - aa[1] * d[:, 0]) / den
        crossing = (np.abs(den) > 1e-12) & (t > 0) & (u > 0.05) & (u < 0.95)
        if crossing.sum() < 2 or np.any(dist[crossing] < t[crossing] - 0.05):
            continue
        seen_doors.append(0.5 * (j1 + j2))
    return ang, dist, seen_walls, seen_corners, seen_doors


def score_scan(det, lines, corners, world, gt, robot):
    _, _, seen_walls, seen_corners, seen_doors = gt
    walls = [np.array(w, dtype=float) for w in det["walls"]]
    s = {k: 0 for k in ("walls_det", "walls_ok", "walls_seen", "walls_found", "doors_det", "doors_ok",
                        "doors_seen", "doors_found", "corners_det", "corners_ok", "corners_seen",
                        "corners_found", "corners_potential")}
    right = []
    for w in walls:
        a, b = w[:2], w[2:]
        ok_line = -1
        for li, l in enumerate(lines):
            if (point_to_segment(a, l[:2], l[2:]) <= WALL_TOL_M and point_to_segment(b, l[:2], l[2:]) <= WALL_TOL_M
                    and angle_between(b - a, l[2:] - l[:2]) <= WALL_TOL_DEG):
                ok_line = li
                break
        right.append((ok_line, a, b))
        s["walls_det"] += 1
        s["walls_ok"] += ok_line >= 0
    for line, a, b, _, _ in seen_walls:
        s["walls_seen"] += 1
        d = (b - a) / np.linalg.norm(b - a)
        run = sorted([a @ d, b @ d])
        for li, wa, wb in right:
            if li != line:
                continue
            cov = sorted([wa @ d, wb @ d])
            if min(run[1], cov[1]) - max(run[0], cov[0]) >= 0.5 * (run[1] - run[0]):
                s["walls_found"] += 1
                break
    all_doors = [0.5 * np.array([g[0] + g[2], g[1] + g[3]]) for g in world.door_gaps]
    det_doors = [0.5 * np.array([d[0] + d[2], d[1] + d[3]]) for d in det["doors"]]
    s["doors_det"] = len(det_doors)
    s["doors_ok"] = sum(any(np.linalg.norm(c - g) <= DOOR_TOL_M for g in all_doors) for c in det_doors)
    s["doors_seen"] = len(seen_doors)
    s["doors_found"] = sum(any(np.linalg.norm(c - g) <= DOOR_TOL_M for c in det_doors) for g in seen_doors)
    det_corners = [(np.array([c["x"], c["y"]]), c["type"]) for c in det["corners"] if c["type"] != "potential"]
    s["corners_potential"] = sum(c["type"] == "potential" for c in det["corners"])
    s["corners_det"] = len(det_corners)
    for p, typ in det_corners:
        s["corners_ok"] += any(np.linalg.norm(p - v) <= CORNER_TOL_M and corner_seen_as(v, legs, robot) == typ
                               for v, legs in corners)
    s["corners_seen"] = len(seen_corners)
    s["corners_found"] = sum(any(np.linalg.norm(p - v) <= CORNER_TOL_M and typ == t for p, typ in det_corners)
                             for v, t in seen_corners)
    return s


def ratio(a, b):
    return round(a / b, 4) if b else None


def summarise(s):
    return {"walls": {"precision": ratio(s["walls_ok"], s["walls_det"]), "recall": ratio(s["walls_found"], s["walls_seen"]),
                      "detected": s["walls_det"], "seen": s["walls_seen"]},
            "doors": {"precision": ratio(s["doors_ok"], s["doors_det"]), "recall": ratio(s["doors_found"], s["doors_seen"]),
                      "detected": s["doors_det"], "seen": s["doors_seen"]},
            "corners": {"precision": ratio(s["corners_ok"], s["corners_det"]),
                        "recall": ratio(s["corners_found"], s["corners_seen"]),
                        "detected": s["corners_det"], "seen": s["corners_seen"],
                        "potential": s["corners_potential"]}}


def bench_worlds(tool, worlds, n_poses, sigma, seed):
    total = {}
    per_world = {}
    timing = []
    with tempfile.TemporaryDirectory() as tmp:
        for wname in worlds:
            world = load_world(wname)
            lines, segs = world_lines(world)
            corners = world_vertices(segs)
            rng = np.random.default_rng(seed)
            poses = free_poses(world, lines, n_poses, rng)
            gts, rows = [], []
            inc = 2 * math.pi / N_BEAMS
            for pose in poses:
                gt = ground_truth(world, lines, segs, corners, pose)
                gts.append(gt)
                dist = gt[1]
                noisy = np.where(np.isfinite(dist), dist + rng.normal(0.0, sigma, N_BEAMS), np.inf)
                rows.append([-math.pi, -math.pi + (N_BEAMS - 1) * inc, inc, RANGE_MAX_M, *pose]
                            + [f"{r:.4f}" if np.isfinite(r) else "inf" for r in noisy])
            path = os.path.join(tmp, f"{wname}.csv")
            with open(path, "w") as f:
                for r in rows:
                    f.write(",".join(str(v) for v in r) + "\n")
            # The extractor is told the sensor's noise: breakpoint sigma and a split threshold of 4 sigma.
            out = run_tool(tool, path, "--world", "--max-range", str(RANGE_MAX_M), "--sigma", str(sigma),
                           "--split", str(max(0.05, 4.0 * sigma)))
            timing.append(out["scans_per_s"])
            sums = {}
            for det, gt, pose in zip(out["scans"], gts, poses):
                s = score_scan(det, lines, corners, world, gt, np.array(pose[:2]))
                for k, v in s.items():
                    sums[k] = sums.get(k, 0) + v
                    total[k] = total.get(k, 0) + v
            per_world[wname] = {"poses": len(poses), **summarise(sums)}
            w = per_world[wname]
            print(f"{wname:16s} {len(poses):5d}  walls P {w['walls']['precision']} R {w['walls']['recall']} "
                  f"({w['walls']['seen']})  doors P {w['doors']['precision']} R {w['doors']['recall']} "
                  f"({w['doors']['seen']})  corners P {w['corners']['precision']} R {w['corners']['recall']} "
                  f"({w['corners']['seen']}, {w['corners']['potential']} potential)")
    overall = summarise(total)
    print(f"{'all':16s}        walls P {overall['walls']['precision']} R {overall['walls']['recall']}  "
          f"doors P {overall['doors']['precision']} R {overall['doors']['recall']}  "
          f"corners P {overall['corners']['precision']} R {overall['corners']['recall']}")
    return {"per_world": per_world, "overall": overall, "scans_per_s_360_beams": timing}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--poses", type=int, default=100, help="random poses per world (default 100)")
    ap.add_argument("--sigma", default="0.01,0.03",
                    help="range noise sigmas in metres, comma-separated (default 0.01,0.03)")
    ap.add_argument("--repeat", type=int, default=20, help="extraction passes per log for timing (default 20)")
    ap.add_argument("--seed", type=int, default=2)
    args = ap.parse_args()
    tool = find_tool()
    if tool is None:
        print("extract_features not built: run `make build` (or set SPARSE_NAV_EXTRACT_FEATURES)")
        return 2
    print(f"extract_features: {tool}")
    logs = bench_logs(tool, args.repeat)
    accuracy = {}
    for sigma in [float(v) for v in args.sigma.split(",")]:
        print(f"\nsimulator worlds: {args.poses} poses each, {N_BEAMS} beams, range noise sigma {sigma} m")
        accuracy[f"sigma_{sigma:g}_m"] = bench_worlds(tool, list_worlds(), args.poses, sigma, args.seed)
    result = {"carmen_logs": logs, "carmen_dir": LASER_DIR, "accuracy": accuracy,
              "settings": {"poses_per_world": args.poses, "beams": N_BEAMS, "range_max_m": RANGE_MAX_M,
                           "noise_sigma_m": args.sigma, "seed": args.seed, "repeat": args.repeat,
                           "wall_tol_m": WALL_TOL_M, "wall_tol_deg": WALL_TOL_DEG, "door_tol_m": DOOR_TOL_M,
                           "corner_tol_m": CORNER_TOL_M}}
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "features.json"), "w") as f:
        json.dump(result, f, indent=1)
    print("wrote bench/results/features.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
