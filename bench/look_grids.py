#!/usr/bin/python3
"""The conductor's look-around verdicts, offline: each look's grid recorded, judged again.

`bench_mission.py --looks DIR` calls :func:`save_looks` on every run's run.bag before removing it:
at the end of each look around beyond an exit it writes DIR/<run>_<k>.npz with the occupancy
grid the conductor had (`map`), the robot's pose in it (tf map -> base_link), the exit it came
through (conductor/state), and whether the robot truly stood outside every room then. Run as a
script on DIR, it judges every saved look again with the conductor's present rule and config and
prints the verdicts against the truth, so that a change of the rule can be measured on the same
grids without flying the missions again. Reads nothing from ../shared.

    /usr/bin/python3 bench/look_grids.py DIR [--outside-open-share S] [--half-fan-deg D]
"""
import argparse
import glob
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.conductor import ConductorConfig  # noqa: E402
from sparse_nav.conductor.grid_queries import GridView, open_beside_share  # noqa: E402
from sparse_nav.mission_report import left_the_room  # noqa: E402
from sparse_nav.sim.world import load_world  # noqa: E402


def _matrix(transform):
    from scipy.spatial.transform import Rotation
    q, t = transform.rotation, transform.translation
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    m[:3, 3] = [t.x, t.y, t.z]
    return m


def save_looks(bag_path, world_name, prefix):
    """Writes prefix_<k>.npz for each look around that ended in the bag; returns how many."""
    import rosbag
    world = load_world(world_name)
    tf, grid, truth, phase, door, saved = {}, None, None, None, None, 0
    with rosbag.Bag(bag_path) as bag:
        for topic, msg, t in bag.read_messages(
                topics=["/tf", "map", "ground_truth/odom", "conductor/state"]):
            if topic == "/tf":
                for tr in msg.transforms:
                    tf[(tr.header.frame_id, tr.child_frame_id)] = tr.transform
            elif topic == "map":
                grid = msg
            elif topic == "ground_truth/odom":
                truth = (msg.pose.pose.position.x, msg.pose.pose.position.y)
            else:
                ended = phase == "look_around" and msg.phase != "look_around"
                if ended and None not in (grid, truth, door) and \
                        ("map", "odom") in tf and ("odom", "base_link") in tf:
                    m = _matrix(tf[("map", "odom")]) @ _matrix(tf[("odom", "base_link")])
                    np.savez_compressed(
                        f"{prefix}_{saved}.npz",
                        cells=np.asarray(grid.data, dtype=np.int8).reshape(grid.info.height,
                                                                           grid.info.width),
                        resolution_m=grid.info.resolution,
                        origin_xy=(grid.info.origin.position.x, grid.info.origin.position.y),
                        robot_xy=(m[0, 3], m[1, 3]), door_xy=door,
                        truly_outside=left_the_room(world, truth), then=msg.phase,
                        reason=msg.reason, sim_time_s=t.to_sec())
                    saved += 1
                if msg.has_exit:
                    door = (msg.exit.x, msg.exit.y)
                phase = msg.phase
    return saved


def judge(path, config):
    """(truly outside, judged outside, open share) of one saved look."""
    d = np.load(path)
    view = GridView(d["cells"].astype(int), float(d["resolution_m"]), tuple(d["origin_xy"]))
    x, y = d["robot_xy"]
    door = d["door_xy"]
    walls = view.walls_around(x, y, config.walls_around_range_m)
    share = open_beside_share(walls, math.atan2(door[1] - y, door[0] - x),
                              config.beside_half_fan_deg)
    return bool(d["truly_outside"]), share >= config.outside_open_share, share


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("looks_dir")
    parser.add_argument("--outside-open-share", type=float)
    parser.add_argument("--half-fan-deg", type=float)
    args = parser.parse_args(argv)
    config = ConductorConfig()
    if args.outside_open_share is not None:
        config.outside_open_share = args.outside_open_share
    if args.half_fan_deg is not None:
        config.beside_half_fan_deg = args.half_fan_deg
    config.validate()
    paths = sorted(glob.glob(os.path.join(args.looks_dir, "*.npz")))
    if not paths:
        print(f"look_grids: no saved looks in {args.looks_dir}")
        return 1
    counts = {"out_truly_outside": 0, "out_truly_inside": 0, "inside_truly_outside": 0,
              "inside_truly_inside": 0}
    recorded_right = 0
    for path in paths:
        outside, judged_out, share = judge(path, config)
        counts[f"{'out' if judged_out else 'inside'}_truly_{'outside' if outside else 'inside'}"] += 1
        recorded_right += (str(np.load(path)["then"]) == "done") == outside
        if judged_out != outside:
            print(f"wrong: {os.path.basename(path)} open share {share:.2f}, truly "
                  f"{'outside' if outside else 'inside'}")
    right = counts["out_truly_outside"] + counts["inside_truly_inside"]
    print(f"{len(paths)} looks: judged now {right} right ({', '.join(f'{k.replace(chr(95), chr(32))} {v}' for k, v in counts.items())}); "
          f"the verdicts recorded in the runs: {recorded_right} right")
    return 0


if __name__ == "__main__":
    sys.exit(main())
