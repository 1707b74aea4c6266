#!/usr/bin/python3
"""Occupancy-grid correctness on simulator worlds with ground truth (issue 3, "Show it").

For each shipped world the drone flies the seed 000 initial scan in the ROS-free simulator; its
SLAM cloud, put back in the world frame with the simulator's ground truth (so that the figures
measure the grid pipeline, not the scale estimate), goes through build_grid. Reported per world:
- IoU of occupied cells with the true walls and furniture after a one-cell dilation of both,
  within the observed part of the grid, and the precision (occupied cells within 0.3 m of a true
  obstacle) and recall (observed true obstacle cells covered) behind it;
- whether each true exit is passable: observed free cells, or non-occupied ones in the doorway
  (the strip as wide as the door, 1 m to either side of its wall), lead from the start through
  the door to 0.4 m beyond it;
- floor tilt error when the cloud is tilted by 0, 5, 10 and 15 degrees.
Free-space rays start at the world's start position at the drone's flight height (--camera).
Writes bench/results/grid_accuracy.json. Does not read ../shared.
"""
import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np
import yaml
from scipy import ndimage

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.pointfiles import write_points_csv  # noqa: E402
from sparse_nav.scanning import initial_scan, to_tello_commands  # noqa: E402
from sparse_nav.sim import SimConfig, Simulator, list_worlds, load_world  # noqa: E402
from sparse_nav.sim.world import doorway_strip  # noqa: E402

BUILD_GRID = os.environ.get("SPARSE_NAV_BUILD_GRID",
                            os.path.join(HERE, "..", "build", "ws", "devel", "lib", "sparse_nav",
                                         "build_grid"))
# build_grid's defaults are config/cloud_filter.yaml's, ground_mapper.yaml's and grid_builder.yaml's.
PIPELINE_ARGS = ["--up-axis", "z"]


def scanned_cloud(world):
    sim = Simulator(world, SimConfig(robot="drone", seed=0))
    for command in ["command", "takeoff"] + to_tello_commands(initial_scan()):
        sim.drone_command(command)
        while not sim.pop_drone_responses():
            sim.step(0.02)
    return sim.slam_to_world(sim.slam_output().all_points)


def run_build_grid(points, prefix, camera):
    csv = prefix + ".csv"
    write_points_csv(csv, points)
    camera_arg = ",".join(f"{v:.4f}" for v in camera)
    out = subprocess.run([BUILD_GRID, csv, "--out", prefix, "--json", "--camera", camera_arg,
                          *PIPELINE_ARGS], capture_output=True, text=True)
    report = json.loads(out.stdout) if out.stdout.strip().startswith("{") else {}
    if out.returncode != 0:
        return report, None
    meta = yaml.safe_load(open(prefix + ".yaml"))
    image = cv2.imread(prefix + ".pgm", cv2.IMREAD_UNCHANGED)[::-1]  # row 0 at the lowest y
    cells = np.where(image == 0, 100, np.where(image == 254, 0, -1)).astype(np.int8)
    return report, (cells, meta["resolution"], meta["origin"][0], meta["origin"][1])


def rasterise_segments(segments, shape, resolution, ox, oy):
    truth = np.zeros(shape, np.uint8)
    for x1, y1, x2, y2 in segments:
        p1 = (int((x1 - ox) / resolution), int((y1 - oy) / resolution))
        p2 = (int((x2 - ox) / resolution), int((y2 - oy) / resolution))
        cv2.line(truth, p1, p2, 1, 1)
    return truth.astype(bool)


def dilate(mask):
    return cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)


def door_passable(cells, resolution, ox, oy, start, gap, reach_m=1.0, beyond_m=0.4):
    """True when observed free cells, or unknown ones in the doorway, lead from start through the
    door gap (x1, y1, x2, y2) to at least beyond_m past its wall; the doorway is the strip as wide
    as the gap reaching reach_m to either side of the wall."""
    rows, cols = cells.shape
    cc, rr = np.meshgrid(np.arange(cols), np.arange(rows))
    xy = np.stack([ox + (cc.ravel() + 0.5) * resolution, oy + (rr.ravel() + 0.5) * resolution], 1)
    doorway, out_m = doorway_strip(xy, gap, start, reach_m)
    doorway, out_m = doorway.reshape(rows, cols), out_m.reshape(rows, cols)
    allowed = (cells == 0) | ((cells != 100) & doorway)
    goal = doorway & (out_m >= beyond_m)
    first = (min(max(int((start[1] - oy) / resolution), 0), rows - 1),
             min(max(int((start[0] - ox) / resolution), 0), cols - 1))
    allowed[first] = True
    labels, _ = ndimage.label(allowed)  # 4-connected components
    return bool(goal[labels == labels[first]].any())


def tilt(points, degrees):
    a = np.radians(degrees)
    rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    return points @ rot.T


def main():
    if not os.path.isfile(BUILD_GRID):
        print(f"build_grid not found at {BUILD_GRID}: run make build first", file=sys.stderr)
        return 2
    tmp = tempfile.mkdtemp(prefix="sparse_nav_grid_acc_")
    rows = []
    for name in list_worlds():
        world = load_world(name)
        points = scanned_cloud(world)
        # The scan turns in place around the start at the flight height: free-space rays start there.
        camera = np.array([world.start[0], world.start[1], SimConfig().drone_flight_height_m])
        report, grid = run_build_grid(points, os.path.join(tmp, name), camera)
        row = {"world": name, "points": int(len(points))}
        if grid is None:
            row["error"] = report.get("error", "build_grid failed")
            rows.append(row)
            continue
        cells, res, ox, oy = grid
        occupied = cells == 100
        truth = rasterise_segments(world.obstacle_segments()[0], cells.shape, res, ox, oy)
        observed = dilate(dilate(cells >= 0))
        occ_d, truth_d = dilate(occupied) & observed, dilate(truth) & observed
        union = np.count_nonzero(occ_d | truth_d)
        row["iou_dilated"] = round(np.count_nonzero(occ_d & truth_d) / union, 3) if union else None
        # IoU punishes the thickness of monocular walls; precision and recall tell what it hides.
        near_truth = cv2.dilate(truth.astype(np.uint8), np.ones((13, 13), np.uint8)).astype(bool)
        row["precision_0.3m"] = round(np.count_nonzero(occupied & near_truth)
                                      / max(np.count_nonzero(occupied), 1), 3)
        seen_truth = truth & observed
        row["recall"] = round(np.count_nonzero(seen_truth & dilate(occupied))
                              / max(np.count_nonzero(seen_truth), 1), 3)
        start = np.array(world.start[:2])
        row["doors_passable"] = [bool(door_passable(cells, res, ox, oy, start, world.exit_gap(e)))
                                 for e in world.exits]
        row["floor_tilt_error_deg"] = {}
        for degrees in (0, 5, 10, 15):
            rep, _ = run_build_grid(tilt(points, degrees), os.path.join(tmp, f"{name}_t{degrees}"),
                                    tilt(camera[None, :], degrees)[0])
            floor = rep.get("floor", {})
            row["floor_tilt_error_deg"][degrees] = (round(abs(floor["tilt_deg"] - degrees), 2)
                                                    if floor.get("found") else "no floor")
        row["total_ms"] = report.get("total_ms")
        rows.append(row)
    print(f"{'world':16s} {'points':>6s} {'IoU(dil)':>8s} {'prec':>5s} {'recall':>6s} "
          f"{'doors passable':>15s}  floor tilt error at 0/5/10/15 deg")
    for r in rows:
        if "error" in r:
            print(f"{r['world']:16s} {r['points']:6d}  {r['error']}")
            continue
        doors = "/".join("yes" if d else "no" for d in r["doors_passable"])
        tilts = " / ".join(str(v) for v in r["floor_tilt_error_deg"].values())
        print(f"{r['world']:16s} {r['points']:6d} {r['iou_dilated']:8.3f} {r['precision_0.3m']:5.2f} "
              f"{r['recall']:6.2f} {doors:>15s}  {tilts}")
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "grid_accuracy.json"), "w") as f:
        json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
