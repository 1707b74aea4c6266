#!/usr/bin/python3
"""The ground robot's initial scan against the exit finder, without ROS.

The built-in simulator (ROS-free core) drives the ground robot through seed 000's initial scan as
the conductor does (each step's cmd_vel segments from ``scanning.to_velocity_segments``, then a
0.5 s pause), and ``find_exit`` (the default method, ``gaps``) runs on the SLAM map points brought
into the world frame with the simulator's ground truth, seen from the scan's start. Per seed: the
points mapped beyond the exit's wall and on the corridor wall behind it, the distance of the best
candidate from the true exit, and whether the exit is the best candidate (within
``--hit-m``). Reads nothing from ../shared. About 10-30 s of wall time per seed on an idle core;
writes bench/results/ground_scan.json.

    /usr/bin/python3 bench/bench_ground_scan.py --seeds 10
"""
import argparse
import json
import math
import os
import re
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.exit_finder import find_exit  # noqa: E402
from sparse_nav.scanning import (GROUND_SPEED_M_S, GROUND_TURN_RATE_RAD_S,  # noqa: E402
                                 InitialScanConfig, initial_scan, to_velocity_segments)
from sparse_nav.sim import SimConfig, load_world  # noqa: E402
from sparse_nav.sim.simulator import Simulator  # noqa: E402

PAUSE_S = 0.5   # the conductor's pause after each step


def scan_once(world_name, seed, hit_m, speed_m_s, turn_rate_rad_s, turn_deg):
    world = load_world(world_name)
    sim = Simulator(world, SimConfig(robot="ground", seed=seed))
    for step in initial_scan(InitialScanConfig(turn_deg=turn_deg)):
        for v, w, duration in to_velocity_segments([step], speed_m_s=speed_m_s,
                                                    turn_rate_rad_s=turn_rate_rad_s):
            sim.set_cmd_vel(v, w)
            sim.step(duration)
        sim.set_cmd_vel(0.0, 0.0)
        sim.step(PAUSE_S)
    out = sim.slam_output()
    points = sim.slam_to_world(out.all_points) if out is not None and len(out.all_points) \
        else np.zeros((0, 3))
    exits = [(e["x"], e["y"]) for e in world.exits]
    row = {"seed": seed, "sim_time_s": round(sim.time_s, 1), "tracking_losses":
           sim.tracking_losses, "points": int(len(points))}
    try:
        result = find_exit(points, up_axis="z", viewpoint=world.start[:2])
        best = result.exits[0] if result.exits else None
    except Exception as exc:  # noqa: BLE001 - a bench row records why the finder refused
        row["error"] = str(exc)
        best = None
    row["best"] = [round(v, 3) for v in best] if best else None
    row["best_error_m"] = round(min(math.dist(best[:2], e) for e in exits), 3) if best else None
    row["hit"] = bool(best) and row["best_error_m"] <= hit_m
    if world_name == "one_room" and len(points):
        # one_room's exit is in its northernmost wall: points north of it were seen through it.
        row["points_beyond_exit"] = int(np.count_nonzero(points[:, 1] > exits[0][1] + 0.4))
    return row


def _worlds(spec):
    """random:A-B -> random:A .. random:B; anything else is one world's name."""
    match = re.fullmatch(r"random:(\d+)-(\d+)", spec)
    if not match:
        return [spec]
    return [f"random:{n}" for n in range(int(match.group(1)), int(match.group(2)) + 1)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="one_room",
                        help="a world, or generated worlds random:A-B (seeds A..B), each scanned "
                             "with every seed")
    parser.add_argument("--seeds", type=int, default=10, help="seeds first .. first + N - 1")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--hit-m", type=float, default=1.0,
                        help="a best candidate this close to a true exit is a hit (m)")
    parser.add_argument("--speed-m-s", type=float, default=GROUND_SPEED_M_S,
                        help="driving speed (m/s; default %(default)s, the conductor's)")
    parser.add_argument("--turn-rate-rad-s", type=float, default=GROUND_TURN_RATE_RAD_S,
                        help="turn rate on the spot (rad/s; default %(default)s, the conductor's)")
    parser.add_argument("--turn-deg", type=float, default=InitialScanConfig().turn_deg,
                        help="turn per iteration of the scan (deg; default %(default)s)")
    parser.add_argument("--json", default=os.path.join(HERE, "results", "ground_scan.json"),
                        help="where the rows and the summary go (default: %(default)s)")
    args = parser.parse_args()
    rows = []
    for world in _worlds(args.world):
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            start = time.time()
            row = scan_once(world, seed, args.hit_m, args.speed_m_s, args.turn_rate_rad_s,
                            args.turn_deg)
            row["world"] = world
            row["wall_s"] = round(time.time() - start, 1)
            rows.append(row)
            print(json.dumps(row), flush=True)
    hits = sum(r["hit"] for r in rows)
    summary = {"world": args.world, "seeds": args.seeds, "turn_deg": args.turn_deg, "hits": hits,
               "hit_rate": hits / max(len(rows), 1), "hit_m": args.hit_m,
               "median_best_error_m": float(np.median([r["best_error_m"] if r["best_error_m"]
                                                       is not None else np.inf for r in rows])),
               "tracking_losses": sum(r["tracking_losses"] for r in rows),
               "scan_sim_time_s": rows[0]["sim_time_s"] if rows else None}
    print(json.dumps(summary))
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"summary": summary, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
