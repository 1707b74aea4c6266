#!/usr/bin/python3
"""Simulator speed against real time, per world and robot kind, and cloud realism.

Speed: the seed 000 initial scan is run without ROS for every shipped world; the table gives the
simulated seconds per wall second (the ratio to real time, the baseline a robot would run at).
Realism: when ../shared/data/orbslam_rooms is present, the clouds of those scans are compared with
the real ORB-SLAM clouds by ../shared/tools/cloud_stats.py (statistics outside the real 10-90% band).
"""
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.pointfiles import write_points_csv  # noqa: E402
from sparse_nav.scanning import initial_scan, to_tello_commands, to_velocity_segments  # noqa: E402
from sparse_nav.sim import SimConfig, Simulator, list_worlds, load_world  # noqa: E402

SHARED = os.path.join(HERE, "..", "..", "shared")
DT_S = 0.02


def run_scan(world_name, robot, seed=0):
    sim = Simulator(load_world(world_name), SimConfig(robot=robot, seed=seed))
    steps = initial_scan()
    start = time.perf_counter()
    if robot == "drone":
        commands = ["command", "takeoff"] + to_tello_commands(steps)
        for command in commands:
            sim.drone_command(command)
            while not sim.pop_drone_responses():
                sim.step(DT_S)
    else:
        for v, w, duration in to_velocity_segments(steps):
            sim.set_cmd_vel(v, w)
            end = sim.time_s + duration
            while sim.time_s < end:
                sim.step(DT_S)
    wall = time.perf_counter() - start
    out = sim.slam_output()
    return sim, out, wall


def main():
    rows, clouds = [], []
    tmp = tempfile.mkdtemp(prefix="sparse_nav_bench_")
    for world in list_worlds():
        for robot in ("ground", "drone"):
            sim, out, wall = run_scan(world, robot)
            n = len(out.all_points) if out is not None else 0
            rows.append({"world": world, "robot": robot, "sim_s": round(sim.time_s, 1),
                         "wall_s": round(wall, 2), "real_time_factor": round(sim.time_s / wall, 1),
                         "map_points": n, "tracking_losses": sim.tracking_losses})
            if n >= 100:
                path = os.path.join(tmp, f"{world}_{robot}.csv")
                write_points_csv(path, out.all_points)
                clouds.append(path)
    print(f"{'world':16s} {'robot':7s} {'sim s':>7s} {'wall s':>7s} {'x real time':>11s} "
          f"{'points':>7s} {'losses':>6s}")
    for r in rows:
        print(f"{r['world']:16s} {r['robot']:7s} {r['sim_s']:7.1f} {r['wall_s']:7.2f} "
              f"{r['real_time_factor']:11.1f} {r['map_points']:7d} {r['tracking_losses']:6d}")
    result = {"scan": rows}
    rooms = os.path.join(SHARED, "data", "orbslam_rooms")
    stats_tool = os.path.join(SHARED, "tools", "cloud_stats.py")
    if os.path.isdir(rooms) and os.path.isfile(stats_tool):
        real = [os.path.join(d, f) for d, _, fs in os.walk(rooms) for f in fs
                if f.endswith((".csv", ".txt"))]
        ref = os.path.join(tmp, "real.json")
        subprocess.run([sys.executable, stats_tool, *real, "--json", ref], check=True,
                       capture_output=True)
        compare = subprocess.run([sys.executable, stats_tool, *clouds, "--compare", ref],
                                 check=True, capture_output=True, text=True).stdout
        print("cloud realism against ../shared/data/orbslam_rooms (cloud_stats.py):")
        print(compare)
        result["realism"] = compare.splitlines()
    else:
        print("../shared/data not present: cloud realism comparison skipped")
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "sim.json"), "w") as f:
        json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
