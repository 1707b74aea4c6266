#!/usr/bin/python3
"""Floor accuracy of build_grid on generated rooms: the drone's initial scan in random_world(seed).

The rooms and their scans are bench_exit_finder's (same seeds, same scan cache: a scan costs
seconds, so they are shared). Each scan's SLAM cloud is put in the world frame with the
simulator's ground truth, optionally tilted about x, and written as CSV; build_grid (z up, its
defaults, no octree) finds the floor. Reported per tilt: how many rooms get a floor, the angle
between the found and the true floor normal (mean, median, 90th percentile, max, rooms over 5
deg), and the found plane's height error under the start position. Reads nothing from ../shared.

Usage: bench/bench_floor.py [--rooms 100] [--tilts 0,10,15] [--jobs 2] [--cache DIR]
Writes bench/results/floor.json.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import bench_exit_finder  # noqa: E402
from bench_grid import find_build_grid  # noqa: E402


def tilt_matrix(degrees):
    a = np.radians(degrees)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def floor_of(binary, points, workdir):
    csv = os.path.join(workdir, "cloud.csv")
    np.savetxt(csv, points, delimiter=",", fmt="%.5f")
    out = subprocess.run([binary, csv, "--out", os.path.join(workdir, "grid"), "--up-axis", "z",
                          "--no-octree", "--json"], capture_output=True, text=True, timeout=300)
    try:
        report = json.loads(out.stdout)
    except json.JSONDecodeError:
        return None, None
    return report.get("floor", {}), report.get("stages_ms", {}).get("floor")


def evaluate(binary, rooms, degrees, workdir):
    rot = tilt_matrix(degrees)
    true_normal = rot @ np.array([0.0, 0.0, 1.0])
    angles, heights, floor_ms, missing = [], [], [], 0
    for room in rooms:
        world = room["points"] @ room["affine_a"].T + room["affine_b"]
        floor, ms = floor_of(binary, world @ rot.T, workdir)
        if ms is not None:
            floor_ms.append(ms)
        if not floor or not floor.get("found"):
            missing += 1
            continue
        normal = np.array(floor["normal"], dtype=float)
        normal /= np.linalg.norm(normal)
        angles.append(float(np.degrees(np.arccos(min(1.0, abs(normal @ true_normal))))))
        under_start = rot @ np.array([room["start"][0], room["start"][1], 0.0])
        heights.append(abs(float(normal @ under_start + floor["d"])))
    a, h = np.array(angles), np.array(heights)
    return {"tilt_deg": degrees, "rooms": len(rooms), "floor_found": len(angles),
            "no_floor": missing,
            "angle_error_deg": {"mean": round(float(a.mean()), 2), "median": round(float(np.median(a)), 2),
                                "p90": round(float(np.quantile(a, 0.9)), 2), "max": round(float(a.max()), 2),
                                "over_5": int((a > 5).sum())} if len(a) else None,
            "height_error_at_start_m": {"mean": round(float(h.mean()), 3),
                                        "p90": round(float(np.quantile(h, 0.9)), 3)} if len(h) else None,
            "floor_stage_ms_median": round(float(np.median(floor_ms)), 1) if floor_ms else None}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rooms", type=int, default=100)
    parser.add_argument("--tilts", default="0,10,15")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    parser.add_argument("--cache", default=None, help="bench_exit_finder's scan cache")
    parser.add_argument("--out", default=os.path.join(HERE, "results", "floor.json"))
    args = parser.parse_args(argv)
    binary = find_build_grid()
    if binary is None:
        print("bench_floor: build_grid not found: run make build first", file=sys.stderr)
        return 2
    cache = args.cache or bench_exit_finder.default_cache()
    t0 = time.perf_counter()
    rooms = [r for r in bench_exit_finder.load_rooms(range(args.rooms), cache, args.jobs)
             if len(r["points"]) >= 100 and np.isfinite(r["affine_a"]).all()]
    rows = []
    with tempfile.TemporaryDirectory(prefix="sparse_nav_floor_") as workdir:
        for degrees in (float(t) for t in args.tilts.split(",") if t):
            rows.append(evaluate(binary, rooms, degrees, workdir))
    print(f"{'tilt':>5s} {'floor':>8s} {'mean':>6s} {'median':>6s} {'p90':>6s} {'max':>6s} "
          f"{'>5deg':>5s} {'height':>7s} {'ms':>5s}")
    for r in rows:
        e, h = r["angle_error_deg"] or {}, r["height_error_at_start_m"] or {}
        print(f"{r['tilt_deg']:5.0f} {r['floor_found']:4d}/{r['rooms']:<3d} {e.get('mean', float('nan')):6.2f} "
              f"{e.get('median', float('nan')):6.2f} {e.get('p90', float('nan')):6.2f} "
              f"{e.get('max', float('nan')):6.2f} {e.get('over_5', 0):5d} {h.get('mean', float('nan')):7.3f} "
              f"{r['floor_stage_ms_median'] or float('nan'):5.1f}")
    result = {"bench": "floor", "build_grid": binary, "data": "generated rooms (bench_exit_finder "
              "scans), none from ../shared", "elapsed_s": round(time.perf_counter() - t0, 1),
              "rows": rows}
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)
    print(f"bench_floor: wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
