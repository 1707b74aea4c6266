#!/usr/bin/python3
"""How long a new SLAM map takes after a forced loss, per relocalising motion, without ROS.

The built-in simulator runs seed 000's initial scan as the conductor does (each step's cmd_vel
segments or Tello commands, then a 0.5 s pause) with one forced loss at a seeded time in
[40, 160] sim-s. From the first lost frame on, the robot repeats one relocalising motion until
tracking is back (a new map initialised) or ``--limit-s`` has passed. Once tracking is back, the scan
goes on where the loss cut it (as the conductor resumes it) for ``--after-s``, watched for SLAM
merging the new map into the lost one and for further losses. Motions, side by side on the same
losses:

- ``sway``: the seed 000 sway and a 60 deg turn, the conductor's motion for both robots before
  ``scanning.relocalise``;
- ``relocalise``: ``scanning.relocalise`` (the drone: the same sway; the ground robot: straight
  out and back into the side with more room).

The free distance that picks the ground robot's side comes from the true walls here, where the
conductor reads it from its last occupancy grid. Reads nothing from ../shared. About 5 min of
wall time for the defaults; writes bench/results/relocalise.json.

    /usr/bin/python3 bench/bench_relocalise.py --robots ground drone --worlds 10 --seeds 3
"""
import argparse
import json
import math
import os
import statistics
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.scanning import (RelocaliseConfig, Step, initial_scan, relocalise,  # noqa: E402
                                 sway, to_tello_commands, to_velocity_segments)
from sparse_nav.sim import SimConfig, load_world  # noqa: E402
from sparse_nav.sim.simulator import Simulator  # noqa: E402
from sparse_nav.sim.slam import TrackingState  # noqa: E402
from sparse_nav.sim.world import segment_distances  # noqa: E402

PAUSE_S = 0.5            # the conductor's pause after each step
TICK_S = 0.05
LOSS_WINDOW_S = (40.0, 160.0)
TRACKING = (TrackingState.OK,)


class Run:
    """One simulator with a robot-independent way to carry out Steps."""

    def __init__(self, world, robot, seed, loss_s):
        self.world = world
        self.sim = Simulator(world, SimConfig(robot=robot, seed=seed, force_loss_at_s=[loss_s]))
        self.robot = robot
        self.lost_at_s = None
        self.back_at_s = None
        self._segs, _heights = world.obstacle_segments()
        if robot == "drone":
            for command in ("command", "takeoff"):
                self._tello(command)

    def _watch(self):
        out = self.sim.slam_output()
        if out is None:
            return
        if self.lost_at_s is None and out.state in (TrackingState.LOST, TrackingState.RECENTLY_LOST) \
                and self.sim.tracking_losses > 0:
            self.lost_at_s = self.sim.time_s
        elif self.lost_at_s is not None and self.back_at_s is None and out.state in TRACKING:
            self.back_at_s = self.sim.time_s

    def _advance(self, duration_s, until_lost=False):
        end = self.sim.time_s + duration_s
        while self.sim.time_s < end - 1e-9:
            self.sim.step(min(TICK_S, end - self.sim.time_s))
            self._watch()
            if until_lost and self.lost_at_s is not None:
                return

    def _tello(self, command):
        self.sim.drone_command(command)
        for _ in range(int(60.0 / TICK_S)):
            self._advance(TICK_S)
            if self.sim.pop_drone_responses():
                return

    def execute(self, step, until_lost=False):
        """Carries out one step and the pause after it; until_lost: a ground robot stops at the
        first lost frame, as the conductor stops a scan (a Tello command in flight ends first)."""
        if self.robot == "drone":
            try:
                commands = to_tello_commands([step])
            except ValueError:
                commands = []
            for command in commands:
                self._tello(command)
        else:
            for v, w, duration in to_velocity_segments([step]):
                self.sim.set_cmd_vel(v, w)
                self._advance(duration, until_lost)
                if until_lost and self.lost_at_s is not None:
                    break
            self.sim.set_cmd_vel(0.0, 0.0)
        self._advance(PAUSE_S, until_lost)

    def free_distance(self, bearing_deg, max_m=10.0):
        """Metres along a bearing from the robot's true pose to the first wall or box (truth)."""
        x, y, _z, yaw = self.sim.true_base_pose()
        heading = yaw + math.radians(bearing_deg)
        d = 0.0
        while d < max_m:
            p = np.array([x + d * math.cos(heading), y + d * math.sin(heading)])
            if len(self._segs) and float(np.min(segment_distances(p, self._segs))) < 0.25:
                return d
            d += 0.05
        return max_m


def motion_steps(name, run):
    if name == "sway":
        return sway() + [Step(ccw_deg=RelocaliseConfig().turn_deg)]
    return relocalise(run.robot, run.free_distance)


def one_loss(world_name, robot, seed, motion, limit_s, after_s):
    world = load_world(world_name)
    rng = np.random.default_rng([seed, int(world_name.split(":")[-1]) if ":" in world_name else 0, 7])
    loss_s = float(rng.uniform(*LOSS_WINDOW_S))
    run = Run(world, robot, seed, loss_s)
    scan = initial_scan()
    while scan:
        run.execute(scan.pop(0), until_lost=True)
        if run.lost_at_s is not None:
            break
    lost_map = run.sim.slam_output().map_id
    row = {"world": world_name, "robot": robot, "seed": seed, "motion": motion,
           "loss_s": round(loss_s, 1)}
    if run.lost_at_s is None:
        row["skipped"] = "the scan ended before the forced loss"
        return row
    tries = 0
    while run.back_at_s is None and run.sim.time_s - run.lost_at_s < limit_s:
        tries += 1
        for step in motion_steps(motion, run):
            run.execute(step)
            if run.back_at_s is not None or run.sim.time_s - run.lost_at_s >= limit_s:
                break
    row.update(back=run.back_at_s is not None, tries=tries, collisions=run.sim.collisions,
               recovery_s=round(run.back_at_s - run.lost_at_s, 1) if run.back_at_s else None)
    if run.back_at_s is None:
        return row
    # Then the scan goes on where the loss cut it, for after_s: does the new map merge into the
    # one lost (or an older one), and is tracking lost again on the way?
    losses, merged_s = run.sim.tracking_losses, None
    steps = scan
    back_s = run.sim.time_s
    while steps and run.sim.time_s - back_s < after_s and merged_s is None:
        run.execute(steps.pop(0))
        out = run.sim.slam_output()
        if out.state in TRACKING and out.map_id <= lost_map:  # ids only grow: an old map
            merged_s = run.sim.time_s - back_s
    row.update(merged=merged_s is not None,
               merged_after_s=round(merged_s, 1) if merged_s is not None else None,
               losses_after=run.sim.tracking_losses - losses)
    return row


def summarise(rows, limit_s):
    out = {}
    for key in sorted({(r["robot"], r["motion"]) for r in rows}):
        mine = [r for r in rows if (r["robot"], r["motion"]) == key and "skipped" not in r]
        times = [r["recovery_s"] if r["back"] else limit_s for r in mine]
        out[" ".join(key)] = {
            "losses": len(mine), "back": sum(r["back"] for r in mine),
            "median_recovery_s": statistics.median(times) if times else None,
            "back_within_10_s": sum(t <= 10.0 for t in times),
            "back_within_30_s": sum(t <= 30.0 for t in times),
            "merged": sum(r.get("merged", False) for r in mine),
            "lost_again": sum(r.get("losses_after", 0) > 0 for r in mine)}
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=["ground", "drone"])
    parser.add_argument("--motions", nargs="+", default=["sway", "relocalise"])
    parser.add_argument("--after-s", type=float, default=30.0,
                        help="sim-s of the scan after tracking is back, watched for a merge")
    parser.add_argument("--worlds", type=int, default=10, help="random:1 .. random:N")
    parser.add_argument("--seeds", type=int, default=3, help="losses per world (seeds 0 .. N-1)")
    parser.add_argument("--limit-s", type=float, default=60.0,
                        help="a loss not recovered in this many sim-s counts as not back")
    parser.add_argument("--json", default=os.path.join(HERE, "results", "relocalise.json"))
    args = parser.parse_args()
    started = time.time()
    rows = []
    for robot in args.robots:
        for w in range(1, args.worlds + 1):
            for seed in range(args.seeds):
                for motion in args.motions:
                    row = one_loss(f"random:{w}", robot, seed, motion, args.limit_s,
                                   args.after_s)
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    summary = summarise(rows, args.limit_s)
    print(json.dumps(summary, indent=1))
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"bench": "relocalise", "data": "generated worlds random:1..N, none from "
                       "../shared", "limit_s": args.limit_s, "loss_window_s": LOSS_WINDOW_S,
                       "elapsed_s": round(time.time() - started, 1), "summary": summary,
                       "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
