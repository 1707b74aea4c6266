#!/usr/bin/python3
"""Occupancy grid rebuild time: sparse_nav's build_grid, seed 004 and an octomap_server peer.

Clouds: synthetic ORB-SLAM-like clouds of 10k, 100k and 1M points, made here from a fixed seed
(no data from ../shared is used). The world is a 25 m x 26 m floor with a 2.6 m ceiling, split by
internal walls with door gaps (one exit in the outer wall); ORB features cluster on textured
patches of the walls, the floor and the ceiling, with noise that grows with the distance from the
camera, plus 0.2% outliers. Points are written as CSV (x, y, z in metres, z up) in a
SLAM-like frame whose origin is the first camera, 1.2 m above the floor.

Per cloud size, in one run:
- ours: ``build_grid FILE --out PREFIX --up-axis z --resolution 0.05 --json``, median of 3 runs
  per stage. Its JSON includes reading the file and writing PGM/YAML/PNG; "rebuild" is the total
  less those two, i.e. guard, density filter, voxel grid, floor, alignment, octree, the ray count
  under obstacle points, alpha shapes and rasterisation.
- seed 004: bench/seed004_grid.py on the same obstacle slice (the cloud's points between 0.15 m
  and 2.2 m above the true floor, build_grid's default band), same resolution and alpha, once,
  in a child process with a time budget; "> budget" when it does not finish in time.
- octomap peer: bench/octomap_peer.cpp (OcTree::insertPointCloud from the first camera, then
  octomap_server's projected map over the leaves in the same height band), median of 3 runs
  (one run above 100k points, where one run already takes minutes). Its
  binary is $SPARSE_NAV_OCTOMAP_PEER, else one built by catkin, else compiled here with g++.
- incremental update when 1% of the points change: measured only when ``build_grid --help``
  lists ``--update FILE2`` (process FILE, then FILE2 on the same pipeline; the JSON then holds
  ``"update": {"stages_ms": .., "total_ms": ..}``); otherwise reported as not exposed. "update"
  is that first update after the build; "steady" the median of the updates after it, when
  ``--repeat-update N`` is listed (back to FILE and again to FILE2, N times: each changes the
  same 1% of the points, as a map refreshed again and again sees it).

The build_grid binary is $SPARSE_NAV_BUILD_GRID, else <repo>/build/ws/devel/lib/sparse_nav/
build_grid, else <repo>/build/ws_core/devel/lib/sparse_nav/build_grid; without one the bench
says so and exits 2. Everything but the timings is deterministic.

Usage: bench/bench_grid.py [--sizes 10000,100000,1000000] [--runs 3] [--budget-s 300]
Prints a table and writes bench/results/grid.json.
"""
import argparse
import json
import multiprocessing
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)

try:
    import seed004_grid  # noqa: E402
    BASELINE_MISSING = None
except ImportError as missing:
    # The baseline needs shapely and rtree, which the package itself does not.
    seed004_grid = None
    BASELINE_MISSING = (f"not run: {missing} (apt-get install python3-shapely python3-rtree)")

RESOLUTION_M = 0.05
ALPHA_M = 0.17              # build_grid's default alpha radius, passed to it and to the baseline
FLOOR_CLEARANCE_M = 0.15    # build_grid's default obstacle band above the floor
CEILING_HEIGHT_M = 2.2
CLOUD_SEED = 4              # seed of every generated cloud
DEFAULT_SIZES = (10000, 100000, 1000000)
CHANGED_FRACTION = 0.01     # share of points that change for the incremental update

# The synthetic world, floor at z = 0 (world frame, metres).
ROOM_X_M = 25.0
ROOM_Y_M = 26.0
CEILING_M = 2.6
DOOR_HEAD_M = 2.3           # above the obstacle band, so a lintel never closes a door
WALL_HALF_THICKNESS_M = 0.06
CAMERA_WORLD = np.array([15.0, 8.0, 1.2])   # first camera: origin of the written clouds
# (x0, y0, x1, y1, both faces seen, door gaps as (from, to) metres along the wall)
WALLS = (
    (0.0, 0.0, 25.0, 0.0, False, ((20.0, 20.9),)),     # outer south, with the exit
    (25.0, 0.0, 25.0, 26.0, False, ()),
    (25.0, 26.0, 0.0, 26.0, False, ()),
    (0.0, 26.0, 0.0, 0.0, False, ()),
    (9.0, 0.0, 9.0, 26.0, True, ((5.0, 6.0), (18.0, 19.0))),
    (9.0, 15.0, 25.0, 15.0, True, ((6.5, 7.5),)),
    (17.0, 15.0, 17.0, 26.0, True, ((5.5, 6.4),)),
)
SHARE_WALLS, SHARE_FLOOR, SHARE_CEILING = 0.63, 0.20, 0.168   # the rest (0.2%) are outliers

OUR_STAGE_ORDER = ("read", "guard", "density", "voxel", "floor", "align", "octree", "slice", "clear",
                   "alpha", "raster", "grid", "write")
# Our stages that do what the seed 004 method does (obstacle slice to grid).
OUR_GRID_STAGES = ("slice", "alpha", "raster", "grid")



def _faces():
    """Wall faces: list of (start (2,), unit direction (2,), length, normal offset (2,), doors)."""
    faces = []
    for x0, y0, x1, y1, both, doors in WALLS:
        start, end = np.array([x0, y0]), np.array([x1, y1])
        length = float(np.linalg.norm(end - start))
        direction = (end - start) / length
        normal = np.array([-direction[1], direction[0]])
        offsets = (WALL_HALF_THICKNESS_M, -WALL_HALF_THICKNESS_M) if both else (0.0,)
        for off in offsets:
            faces.append((start + normal * off, direction, length, normal, doors))
    return faces


def _in_door(along, z, doors):
    """(N,) bool: the (along, z) wall coordinates fall in a door opening."""
    hit = np.zeros(along.shape, dtype=bool)
    for lo, hi in doors:
        hit |= (along >= lo) & (along <= hi) & (z < DOOR_HEAD_M)
    return hit


def _wall_points(rng, n):
    """n points on the wall faces: textured patches plus a sparse uniform share."""
    faces = _faces()
    texture = rng.uniform(0.4, 1.6, len(faces))      # some faces are barer than others
    weights = np.array([f[2] for f in faces]) * texture
    counts = rng.multinomial(n, weights / weights.sum())
    out = []
    for (start, direction, length, normal, doors), count in zip(faces, counts):
        pts = np.zeros((0, 3))
        # Rejection sampling against the door gaps keeps the count exact.
        while len(pts) < count:
            need = count - len(pts)
            m = int(need * 1.3) + 8
            n_patch = max(1, int(length * 1.5))
            centres_a = rng.uniform(0.0, length, n_patch)
            centres_z = rng.uniform(0.1, CEILING_M - 0.1, n_patch)
            pick = rng.integers(0, n_patch, m)
            patched = rng.random(m) < 0.7          # ORB features crowd on texture
            along = np.where(patched, centres_a[pick] + rng.normal(0.0, 0.25, m),
                             rng.uniform(0.0, length, m))
            z = np.where(patched, centres_z[pick] + rng.normal(0.0, 0.2, m),
                         rng.uniform(0.0, CEILING_M, m))
            ok = (along >= 0) & (along <= length) & (z >= 0) & (z <= CEILING_M)
            ok &= ~_in_door(along, z, doors)
            along, z = along[ok], z[ok]
            xy = start + np.outer(along, direction)
            pts = np.vstack([pts, np.column_stack([xy, z])])[:count]
        out.append(pts)
    return np.vstack(out)


def _layer_points(rng, n, z):
    """n points on a horizontal layer at height z (floor or ceiling), clustered like the walls."""
    n_patch = int(ROOM_X_M * ROOM_Y_M / 2.0)
    centres = rng.uniform([0.0, 0.0], [ROOM_X_M, ROOM_Y_M], (n_patch, 2))
    patched = rng.random(n) < 0.7          # features crowd on rugs, tile joints, lamps
    near = centres[rng.integers(0, n_patch, n)] + rng.normal(0.0, 0.25, (n, 2))
    xy = np.where(patched[:, None], near, rng.uniform([0.0, 0.0], [ROOM_X_M, ROOM_Y_M], (n, 2)))
    xy = np.clip(xy, [0.0, 0.0], [ROOM_X_M, ROOM_Y_M])
    return np.column_stack([xy, np.full(n, z)])


def make_cloud(n_points, seed=CLOUD_SEED):
    """(n_points, 3) float64 ORB-SLAM-like cloud, SLAM-like frame (origin: first camera, z up)."""
    rng = np.random.default_rng([seed, n_points])
    n_walls = int(round(n_points * SHARE_WALLS))
    n_floor = int(round(n_points * SHARE_FLOOR))
    n_ceiling = int(round(n_points * SHARE_CEILING))
    n_out = n_points - n_walls - n_floor - n_ceiling
    world = np.vstack([
        _wall_points(rng, n_walls),
        _layer_points(rng, n_floor, 0.0),
        _layer_points(rng, n_ceiling, CEILING_M),
    ])
    # Monocular depth noise: along the ray from the camera, growing with the distance.
    ray = world - CAMERA_WORLD
    dist = np.linalg.norm(ray, axis=1, keepdims=True)
    sigma = 0.01 + 0.002 * dist
    world = world + ray / np.maximum(dist, 1e-9) * rng.normal(0.0, 1.0, (len(world), 1)) * sigma
    world = world + rng.normal(0.0, 0.01, world.shape)
    outliers = rng.uniform([-1.0, -1.0, -0.5], [ROOM_X_M + 1.0, ROOM_Y_M + 1.0, CEILING_M + 0.6],
                           (n_out, 3))
    cloud = np.vstack([world, outliers])
    cloud = cloud[rng.permutation(len(cloud))]   # SLAM map points come in no spatial order
    return cloud - CAMERA_WORLD


def change_cloud(cloud, fraction=CHANGED_FRACTION, seed=CLOUD_SEED):
    """Copy of `cloud` whose points nearest to one wall spot (a `fraction` of all) moved.

    A local bundle adjustment moves a patch of map points: the changed points are the nearest
    ones to a spot on the east wall, each shifted by fresh noise of 3 cm.
    """
    rng = np.random.default_rng([seed, len(cloud), 1])
    spot = np.array([ROOM_X_M, 10.0]) - CAMERA_WORLD[:2]
    k = max(1, int(round(len(cloud) * fraction)))
    nearest = np.argpartition(np.linalg.norm(cloud[:, :2] - spot, axis=1), k - 1)[:k]
    changed = cloud.copy()
    changed[nearest] += rng.normal(0.0, 0.03, (k, 3))
    return changed


def obstacle_band():
    """(z_min, z_max) of the obstacle band in the written clouds' frame [m]."""
    floor_z = -CAMERA_WORLD[2]
    return floor_z + FLOOR_CLEARANCE_M, floor_z + CEILING_HEIGHT_M


def write_csv(path, cloud):
    """Writes x,y,z with a header line, millimetre precision."""
    np.savetxt(path, cloud, fmt="%.4f", delimiter=",", header="x,y,z", comments="")



def find_build_grid():
    """Path of the build_grid binary, or None (see the module docstring for the order)."""
    env = os.environ.get("SPARSE_NAV_BUILD_GRID")
    if env:
        return env if os.access(env, os.X_OK) else None
    for ws in ("ws", "ws_core"):
        path = os.path.join(REPO, "build", ws, "devel", "lib", "sparse_nav", "build_grid")
        if os.access(path, os.X_OK):
            return path
    return None


def find_octomap_peer(tmp):
    """(path, how) of an octomap_peer binary, compiling bench/octomap_peer.cpp if needed."""
    env = os.environ.get("SPARSE_NAV_OCTOMAP_PEER")
    if env and os.access(env, os.X_OK):
        return env, "$SPARSE_NAV_OCTOMAP_PEER"
    for ws in ("ws", "ws_core"):
        path = os.path.join(REPO, "build", ws, "devel", "lib", "sparse_nav", "octomap_peer")
        if os.access(path, os.X_OK):
            return path, "catkin build"
    source = os.path.join(HERE, "octomap_peer.cpp")
    compiler = shutil.which("g++")
    if not (os.path.isfile(source) and compiler):
        return None, "no binary, and no g++ or source to build one"
    path = os.path.join(tmp, "octomap_peer")
    proc = subprocess.run([compiler, "-O2", "-DNDEBUG", source, "-loctomap", "-loctomath",
                           "-o", path], capture_output=True, text=True)
    if proc.returncode != 0:
        return None, "g++ failed: " + proc.stderr.strip()[-300:]
    return path, "compiled here with g++ -O2"


def run_json(cmd, timeout_s=900):
    """Runs a tool that prints one JSON object on stdout; returns it, or raises RuntimeError."""
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    lines = [line for line in proc.stdout.splitlines() if line.strip().startswith("{")]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"{os.path.basename(cmd[0])} exited {proc.returncode}: "
                           f"{(proc.stderr or proc.stdout).strip()[-400:]}")
    return json.loads(lines[-1])


def median_stages(runs):
    """Median per stage over runs of {"stages_ms": {...}}; stages missing from a run count 0."""
    names = []
    for run in runs:
        names += [n for n in run["stages_ms"] if n not in names]
    return {n: statistics.median(r["stages_ms"].get(n, 0.0) for r in runs) for n in names}


def ordered(stages):
    """Stage names in pipeline order (known ones first, then the rest as given)."""
    known = [n for n in OUR_STAGE_ORDER if n in stages]
    return known + [n for n in stages if n not in known]


REPEATED_REBUILDS = 5       # build_grid --repeat-rebuild: rebuilds in the process after its first


def run_ours(binary, csv, tmp, runs, repeat_rebuild=False):
    """Median stages of `runs` build_grid runs, with rebuild = total - read - write (in a fresh
    process); with `repeat_rebuild` also the median of the rebuilds after the first in each
    process ("warm_rebuild_ms": a running node's rebuild, its memory already mapped)."""
    results = []
    for i in range(runs):
        prefix = os.path.join(tmp, f"ours_{i}")
        cmd = [binary, csv, "--out", prefix, "--up-axis", "z", "--resolution", str(RESOLUTION_M),
               "--alpha", str(ALPHA_M), "--json"]
        if repeat_rebuild:
            cmd += ["--repeat-rebuild", str(REPEATED_REBUILDS)]
        results.append(run_json(cmd))
    warm = [statistics.median(r["repeated_rebuild_ms"]) for r in results
            if r.get("repeated_rebuild_ms")]
    stages = median_stages(results)
    totals = [sum(r["stages_ms"].values()) for r in results]
    rebuilds = [sum(v for k, v in r["stages_ms"].items() if k not in ("read", "write"))
                for r in results]
    grids = [sum(v for k, v in r["stages_ms"].items() if k in OUR_GRID_STAGES) for r in results]
    last = results[-1]
    return {"stages_ms": {n: round(stages[n], 3) for n in ordered(stages)},
            "total_ms": round(statistics.median(totals), 3),
            "rebuild_ms": round(statistics.median(rebuilds), 3),
            "grid_stages_ms": round(statistics.median(grids), 3),
            "runs_rebuild_ms": [round(v, 3) for v in rebuilds],
            **({"warm_rebuild_ms": round(statistics.median(warm), 3),
                "runs_warm_rebuild_ms": [round(v, 3) for v in warm]} if warm else {}),
            "grid": last.get("grid"), "filtered": last.get("filtered"),
            "floor": last.get("floor")}


def update_interface(binary):
    """(--update, --repeat-update, --repeat-rebuild) each listed or not in build_grid's --help."""
    proc = subprocess.run([binary, "--help"], capture_output=True, text=True, timeout=60)
    text = proc.stdout + proc.stderr
    return "--update" in text, "--repeat-update" in text, "--repeat-rebuild" in text


REPEATED_UPDATES = 10       # build_grid --repeat-update: updates after the first, each way


def run_update(binary, csv, changed_csv, tmp, runs, repeat):
    """Median incremental update ms of build_grid's --update, or a reason string; with `repeat`
    also the median of the updates after the first ("steady_update_ms")."""
    totals, rebuilds, steady = [], [], []
    for i in range(runs):
        cmd = [binary, csv, "--update", changed_csv,
               "--out", os.path.join(tmp, f"upd_{i}"), "--up-axis", "z",
               "--resolution", str(RESOLUTION_M), "--alpha", str(ALPHA_M), "--json"]
        if repeat:
            cmd += ["--repeat-update", str(REPEATED_UPDATES)]
        out = run_json(cmd)
        update = out.get("update")
        if not isinstance(update, dict) or "stages_ms" not in update:
            return "build_grid --update printed no \"update\": {\"stages_ms\": ..} object"
        stages = update["stages_ms"]
        totals.append(sum(stages.values()))
        rebuilds.append(sum(v for k, v in stages.items() if k not in ("read", "write")))
        if repeat and update.get("repeated_ms"):
            steady.append(statistics.median(update["repeated_ms"]))
    result = {"total_ms": round(statistics.median(totals), 3),
              "update_ms": round(statistics.median(rebuilds), 3),
              "runs_update_ms": [round(v, 3) for v in rebuilds]}
    if steady:
        result["steady_update_ms"] = round(statistics.median(steady), 3)
        result["runs_steady_update_ms"] = [round(v, 3) for v in steady]
    return result


def run_peer(binary, csv, runs):
    """Median stages of the octomap_server-style peer over `runs` runs."""
    z_min, z_max = obstacle_band()
    results = [run_json([binary, csv, "--resolution", str(RESOLUTION_M), "--origin", "0", "0", "0",
                         "--min-z", f"{z_min:.6f}", "--max-z", f"{z_max:.6f}"])
               for _ in range(runs)]
    stages = median_stages(results)
    maps = [sum(v for k, v in r["stages_ms"].items() if k != "read") for r in results]
    return {"stages_ms": {n: round(v, 3) for n, v in stages.items()},
            "map_ms": round(statistics.median(maps), 3),
            "runs_map_ms": [round(v, 3) for v in maps], "grid": results[-1].get("grid")}


def _baseline_child(npy, out_json):
    """Child process: seed 004 on the cloud in `npy`; its summary goes to `out_json`."""
    cloud = np.load(npy)
    z_min, z_max = obstacle_band()
    result = seed004_grid.seed004_grid(cloud, RESOLUTION_M, ALPHA_M, z_min, z_max)
    summary = {"stages_ms": {k: round(v, 3) for k, v in result.stages_ms.items()},
               "total_ms": round(result.total_ms, 3), "vertices": result.n_vertices,
               "triangles": result.n_triangles, "kept_triangles": result.n_kept_triangles,
               "polygons": len(result.polygons), "probes": result.n_probes,
               "contains_calls": result.n_contains,
               "grid": dict(width=int(result.grid.shape[1]), height=int(result.grid.shape[0]),
                            **result.counts())}
    with open(out_json, "w") as handle:
        json.dump(summary, handle)


def run_baseline(cloud, tmp, budget_s):
    """Seed 004 on `cloud` in a child process; its summary, or {"over_budget_s": budget_s}."""
    npy = os.path.join(tmp, f"cloud_{len(cloud)}.npy")
    out_json = os.path.join(tmp, f"seed004_{len(cloud)}.json")
    np.save(npy, cloud)
    context = multiprocessing.get_context("fork")
    child = context.Process(target=_baseline_child, args=(npy, out_json))
    child.start()
    child.join(budget_s)
    if child.is_alive():
        child.terminate()    # our own child, by its handle
        child.join()
        return {"over_budget_s": budget_s}
    if child.exitcode != 0 or not os.path.isfile(out_json):
        return {"error": f"baseline child exited {child.exitcode}"}
    with open(out_json) as handle:
        return json.load(handle)



def _fmt_ms(value):
    """Milliseconds for the table: '-' for none, one decimal below 100 ms."""
    if value is None:
        return "-"
    return f"{value:.1f}" if value < 100 else f"{value:.0f}"


def _ratio(numerator, denominator):
    if numerator is None or not denominator:
        return None
    return round(numerator / denominator, 1)


def print_table(rows):
    """The summary table, one block per cloud size."""
    for row in rows:
        n = row["n_points"]
        ours = row.get("ours")
        print(f"\n-- {n} points (obstacle slice {row['slice_points']} points)")
        if "error" in ours:
            print(f"  ours: failed: {ours['error']}")
        else:
            stages = ", ".join(f"{k} {_fmt_ms(v)}" for k, v in ours["stages_ms"].items())
            print(f"  ours, median of {row['runs']} (ms): {stages}")
            print(f"  ours total {_fmt_ms(ours['total_ms'])} ms, rebuild (less read and write) "
                  f"{_fmt_ms(ours['rebuild_ms'])} ms, of which slice and grid "
                  f"{_fmt_ms(ours['grid_stages_ms'])} ms")
            if "warm_rebuild_ms" in ours:
                print(f"  ours rebuild again in the same process (median of {REPEATED_REBUILDS} "
                      f"after the first): {_fmt_ms(ours['warm_rebuild_ms'])} ms")
        base = row["seed004"]
        if "total_ms" in base:
            stages = ", ".join(f"{k} {_fmt_ms(v)}" for k, v in base["stages_ms"].items())
            print(f"  seed 004 (ms): {stages}; total {_fmt_ms(base['total_ms'])} ms "
                  f"({base['vertices']} vertices, {base['polygons']} polygons, "
                  f"{base['probes']} probes, {base['contains_calls']} contains calls)")
        elif "over_budget_s" in base:
            print(f"  seed 004: > budget ({base['over_budget_s']:.0f} s)")
        else:
            print(f"  seed 004: {base.get('skipped') or base.get('error')}")
        peer = row.get("octomap_peer")
        if isinstance(peer, dict):
            stages = ", ".join(f"{k} {_fmt_ms(v)}" for k, v in peer["stages_ms"].items())
            print(f"  octomap peer, median of {row['peer_runs']} (ms): {stages}; "
                  f"map (less read) {_fmt_ms(peer['map_ms'])} ms")
        upd = row.get("update")
        if isinstance(upd, dict):
            steady = upd.get("steady_update_ms")
            print(f"  incremental update, {CHANGED_FRACTION:.0%} of the points changed: "
                  f"{_fmt_ms(upd['update_ms'])} ms the first after the build"
                  + (f", {_fmt_ms(steady)} ms the median of the {2 * REPEATED_UPDATES} after it"
                     if steady is not None else ""))
    print("\nsummary (ms). ours: rebuild, i.e. build_grid less reading the file and writing the"
          "\nmaps; grid: its slice and grid stages alone; x: the other's time / ours (above 1: we"
          "\nare faster); update: incremental update after 1% of the points changed, the first"
          "\nafter the build; steady: the median of those after it; warm: ours again in the same"
          "\nprocess, as a running node rebuilds")
    print(f"{'points':>9} {'ours':>8} {'warm':>7} {'grid':>7} {'update':>8} {'steady':>7} {'seed004':>9} {'x seed':>7} "
          f"{'x seed/grid':>11} {'octomap':>8} {'x octo':>7}")
    for row in rows:
        ours = row.get("ours") or {}
        base = row["seed004"]
        peer = row.get("octomap_peer") if isinstance(row.get("octomap_peer"), dict) else {}
        upd = row.get("update") if isinstance(row.get("update"), dict) else {}
        if "total_ms" in base:
            base_s = _fmt_ms(base["total_ms"])
        elif "over_budget_s" in base:
            base_s = f">{base['over_budget_s']:.0f}s"
        else:
            base_s = "-"
        ratios = row.get("ratios", {})
        print(f"{row['n_points']:>9} {_fmt_ms(ours.get('rebuild_ms')):>8} "
              f"{_fmt_ms(ours.get('warm_rebuild_ms')):>7} {_fmt_ms(ours.get('grid_stages_ms')):>7} {_fmt_ms(upd.get('update_ms')):>8} "
              f"{_fmt_ms(upd.get('steady_update_ms')):>7} "
              f"{base_s:>9} {ratios.get('seed004_over_ours') or '-':>7} "
              f"{ratios.get('seed004_over_ours_grid_stages') or '-':>11} "
              f"{_fmt_ms(peer.get('map_ms')):>8} {ratios.get('octomap_over_ours') or '-':>7}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default=",".join(str(s) for s in DEFAULT_SIZES),
                        help="comma-separated cloud sizes (points)")
    parser.add_argument("--runs", type=int, default=3,
                        help="runs of ours and of the peer per size")
    parser.add_argument("--budget-s", type=float, default=300.0,
                        help="time budget of one seed 004 baseline run (s)")
    parser.add_argument("--baseline-max-points", type=int, default=1000000,
                        help="sizes above this skip the seed 004 baseline")
    parser.add_argument("--out", default=os.path.join(HERE, "results", "grid.json"))
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]

    binary = find_build_grid()
    if binary is None:
        print("bench_grid: no build_grid binary: looked at $SPARSE_NAV_BUILD_GRID "
              f"({os.environ.get('SPARSE_NAV_BUILD_GRID') or 'unset'}), then build/ws and "
              "build/ws_core under devel/lib/sparse_nav/build_grid; run `make build` or set "
              "SPARSE_NAV_BUILD_GRID", file=sys.stderr)
        return 2
    print(f"bench_grid: build_grid = {binary}")
    print("bench_grid: data: synthetic clouds generated here (seed "
          f"{CLOUD_SEED}); no data from ../shared is used")
    has_update, has_repeat, has_repeat_rebuild = update_interface(binary)
    if BASELINE_MISSING:
        print(f"bench_grid: seed 004 baseline {BASELINE_MISSING}", file=sys.stderr)
    t_start = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_grid_") as tmp:
        peer, peer_how = find_octomap_peer(tmp)
        print(f"bench_grid: octomap peer: {peer or 'none'} ({peer_how})")
        if not has_update:
            print("bench_grid: build_grid --help lists no --update: "
                  "incremental update not measured")
        for n in sizes:
            cloud = make_cloud(n)
            csv = os.path.join(tmp, f"cloud_{n}.csv")
            write_csv(csv, cloud)
            z_min, z_max = obstacle_band()
            slice_points = int(np.count_nonzero((cloud[:, 2] >= z_min) & (cloud[:, 2] <= z_max)))
            row = {"n_points": n, "slice_points": slice_points, "runs": args.runs}
            print(f"bench_grid: {n} points: ours ...", flush=True)
            try:
                row["ours"] = run_ours(binary, csv, tmp, args.runs, has_repeat_rebuild)
            except RuntimeError as err:
                row["ours"] = {"error": str(err)}
                print(f"bench_grid: {n} points: {err}", file=sys.stderr)
            if "error" in row["ours"]:
                row["update"] = "not measured: the full rebuild failed"
            elif has_update:
                changed = os.path.join(tmp, f"cloud_{n}_changed.csv")
                write_csv(changed, change_cloud(cloud))
                try:
                    row["update"] = run_update(binary, csv, changed, tmp, args.runs, has_repeat)
                except RuntimeError as err:
                    row["update"] = str(err)
            else:
                row["update"] = "not exposed by build_grid (no --update option)"
            if peer:
                print(f"bench_grid: {n} points: octomap peer ...", flush=True)
                # One peer run at 1M points takes minutes: three would break the time budget.
                row["peer_runs"] = args.runs if n <= 100000 else 1
                row["octomap_peer"] = run_peer(peer, csv, row["peer_runs"])
            else:
                row["octomap_peer"] = peer_how
            if BASELINE_MISSING:
                row["seed004"] = {"skipped": BASELINE_MISSING}
            elif n > args.baseline_max_points:
                row["seed004"] = {
                    "skipped": f"above --baseline-max-points {args.baseline_max_points}"}
            else:
                print(f"bench_grid: {n} points: seed 004 baseline "
                      f"(budget {args.budget_s:.0f} s) ...", flush=True)
                row["seed004"] = run_baseline(cloud, tmp, args.budget_s)
            ours_ms = row["ours"].get("rebuild_ms")
            row["ratios"] = {
                "seed004_over_ours": _ratio(row["seed004"].get("total_ms"), ours_ms),
                "seed004_over_ours_grid_stages": _ratio(row["seed004"].get("total_ms"),
                                                        row["ours"].get("grid_stages_ms")),
                "octomap_over_ours": _ratio(row["octomap_peer"].get("map_ms"), ours_ms)
                if isinstance(row["octomap_peer"], dict) else None,
            }
            rows.append(row)
    elapsed = time.perf_counter() - t_start
    print_table(rows)
    print(f"\nbench_grid: {elapsed:.0f} s")
    result = {
        "bench": "grid",
        "data": "synthetic ORB-SLAM-like clouds (bench_grid.make_cloud), none from ../shared",
        "cloud_seed": CLOUD_SEED, "resolution_m": RESOLUTION_M, "alpha_m": ALPHA_M,
        "obstacle_band_m": [FLOOR_CLEARANCE_M, CEILING_HEIGHT_M],
        "world": {"x_m": ROOM_X_M, "y_m": ROOM_Y_M, "ceiling_m": CEILING_M},
        "build_grid": binary, "octomap_peer": peer_how, "update_exposed": has_update,
        "changed_fraction": CHANGED_FRACTION, "elapsed_s": round(elapsed, 1), "sizes": rows,
    }
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as handle:
        json.dump(result, handle, indent=1)
    print(f"bench_grid: wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
