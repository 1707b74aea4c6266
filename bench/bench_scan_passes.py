#!/usr/bin/python3
"""The ground robot's initial scan through the conductor's own scan loop, without ROS: passing a
place that loses tracking at every speed (``retry/fails_before_pass``) against retrying it.

The built-in simulator drives the ground robot through ``scan_runner.drive_scan``, the loop the
conductor node runs: each step's cmd_vel segments, stopped and backed off by wheel odometry when
tracking is lost, a 0.5 s pause, the retry mechanism. Around it, the conductor's rules for a scan
that loses tracking: lost longer than ``scan_retry_lost_s`` (or SLAM gave up its map), the scan
stops, ``scanning.relocalise`` runs until tracking is back, and the scan goes on where it was cut.
``--stress`` forces a loss every 30 sim-s, as bench_mission.py's stressed runs do.

Per world and setting: whether the scan failed (max_total_fails soft fails: the conductor scans
the room again, up to three times), the share of its steps that succeeded, its sim time, the
tracking losses, the SLAM maps begun, and whether the exit finder's best candidate on the final
map's points (brought into the world frame by the simulator's ground truth) lies within
``--hit-m`` of a true exit. Both settings run on the same worlds in the same process. Reads
nothing from ../shared. About 10 min of wall time for the defaults on one core; writes
bench/results/scan_passes.json.

    /usr/bin/python3 bench/bench_scan_passes.py --worlds 50
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.conductor import ConductorConfig  # noqa: E402
from sparse_nav.conductor.scan_runner import ScanRunner, ScanRunnerConfig, drive_scan  # noqa: E402
from sparse_nav.exit_finder import find_exit  # noqa: E402
from sparse_nav.scanning import (GROUND_INITIAL_SCAN_TURN_DEG, GROUND_SPEED_M_S,  # noqa: E402
                                 GROUND_TURN_RATE_RAD_S, InitialScanConfig, initial_scan,
                                 relocalise, to_velocity_segments)
from sparse_nav.sim import SimConfig, load_world  # noqa: E402
from sparse_nav.sim.simulator import Simulator  # noqa: E402
from sparse_nav.sim.slam import TrackingState  # noqa: E402

TICK_S = 0.05
STRESS_LOSS_PERIOD_S = 30.0
LOST = (TrackingState.RECENTLY_LOST, TrackingState.LOST)


class SimGround:
    """The simulated ground robot as drive_scan sees it, and the conductor's LOST rules."""

    def __init__(self, world, seed, losses_at_s):
        self.sim = Simulator(world, SimConfig(robot="ground", seed=seed,
                                              force_loss_at_s=list(losses_at_s)))
        self.lost_since_s = None
        self.retry_lost_s = ConductorConfig().scan_retry_lost_s

    def tracking_lost(self):
        out = self.sim.slam_output()
        return out is not None and out.state in LOST

    def conductor_stops_scan(self):
        """Lost longer than scan_retry_lost_s, or SLAM gave up its map: relocalise instead."""
        out = self.sim.slam_output()
        return self.lost_since_s is not None and (
            out.state == TrackingState.LOST
            or self.sim.time_s - self.lost_since_s > self.retry_lost_s)

    def advance(self, seconds):
        end = self.sim.time_s + seconds
        while self.sim.time_s < end - 1e-9:
            self.sim.step(min(TICK_S, end - self.sim.time_s))
            if not self.tracking_lost():
                self.lost_since_s = None
            elif self.lost_since_s is None:
                self.lost_since_s = self.sim.time_s

    def execute(self, step, speed_factor=1.0, should_stop=lambda: False):
        try:
            for v, w, duration in to_velocity_segments(
                    [step], speed_m_s=GROUND_SPEED_M_S * speed_factor,
                    turn_rate_rad_s=GROUND_TURN_RATE_RAD_S * speed_factor):
                end = self.sim.time_s + duration
                while self.sim.time_s < end - 1e-9:
                    if should_stop():
                        return False
                    self.sim.set_cmd_vel(v, w)
                    self.advance(min(TICK_S, end - self.sim.time_s))
            return True
        finally:
            self.sim.set_cmd_vel(0.0, 0.0)

    def drive(self, runner, stop_requested):
        drive_scan(runner, self.execute, self.tracking_lost, self.sim.odometry, stop_requested,
                   pause=self.advance)


def scan_once(world_name, seed, runner_config, stress, limit_s, hit_m):
    world = load_world(world_name)
    losses = ([STRESS_LOSS_PERIOD_S * k for k in range(1, int(limit_s // STRESS_LOSS_PERIOD_S))]
              if stress else [])
    robot = SimGround(world, seed, losses)
    runner = ScanRunner(initial_scan(InitialScanConfig(turn_deg=GROUND_INITIAL_SCAN_TURN_DEG)),
                        runner_config)
    relocalising = 0
    while not runner.done and robot.sim.time_s < limit_s:
        robot.drive(runner, robot.conductor_stops_scan)
        if runner.done:
            break
        relocalising += 1
        while robot.tracking_lost() and robot.sim.time_s < limit_s:
            robot.drive(ScanRunner(relocalise("ground"), while_lost=True),
                        lambda: not robot.tracking_lost())
            robot.advance(0.5)
    sim = robot.sim
    out = sim.slam_output()
    tracking = out is not None and out.state == TrackingState.OK and len(out.all_points)
    points = sim.slam_to_world(out.all_points) if tracking else np.zeros((0, 3))
    best = None
    if len(points):
        try:
            result = find_exit(points, up_axis="z", viewpoint=world.start[:2])
            best = result.exits[0] if result.exits else None
        except ValueError:
            best = None
    error = (min(math.dist(best[:2], (e["x"], e["y"])) for e in world.exits)
             if best is not None else None)
    return {"world": world_name, "seed": seed, "failed": runner.failed,
            "share_done": round(runner.share_done, 3), "passed_steps": len(runner.skipped),
            "sim_time_s": round(sim.time_s, 1), "tracking_losses": sim.tracking_losses,
            "relocalising": relocalising, "slam_maps": sim._slam._next_id,
            "best_error_m": None if error is None else round(error, 3),
            "hit": error is not None and error <= hit_m}


def summarise(rows):
    return {"runs": len(rows), "scans_failed": sum(r["failed"] for r in rows),
            "exit_hits": sum(r["hit"] for r in rows),
            "median_sim_time_s": float(np.median([r["sim_time_s"] for r in rows])),
            "mean_sim_time_s": round(float(np.mean([r["sim_time_s"] for r in rows])), 1),
            "tracking_losses": sum(r["tracking_losses"] for r in rows),
            "slam_maps": sum(r["slam_maps"] for r in rows)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", type=int, default=50, help="random:F .. random:F+N-1")
    parser.add_argument("--first-world", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="the simulator's seed")
    parser.add_argument("--stress", action="store_true",
                        help=f"a forced loss every {STRESS_LOSS_PERIOD_S:g} sim-s")
    parser.add_argument("--limit-s", type=float, default=400.0, help="sim-s per scan at most")
    parser.add_argument("--hit-m", type=float, default=1.0,
                        help="a best candidate this close to a true exit is a hit (m)")
    parser.add_argument("--json", default=os.path.join(HERE, "results", "scan_passes.json"))
    args = parser.parse_args()
    settings = {"retried": ScanRunnerConfig(fails_before_pass=0),
                "passed": ScanRunnerConfig()}
    rows = {name: [] for name in settings}
    start = time.time()
    for k in range(args.first_world, args.first_world + args.worlds):
        for name, config in settings.items():
            row = scan_once(f"random:{k}", args.seed, config, args.stress, args.limit_s,
                            args.hit_m)
            rows[name].append(row)
            print(name, json.dumps(row), flush=True)
    summary = {name: summarise(r) for name, r in rows.items()}
    print(f"{'setting':8s} {'failed':>6s} {'hits':>5s} {'median s':>9s} {'mean s':>7s} "
          f"{'losses':>6s} {'maps':>5s}")
    for name, s in summary.items():
        print(f"{name:8s} {s['scans_failed']:6d} {s['exit_hits']:5d} {s['median_sim_time_s']:9.1f} "
              f"{s['mean_sim_time_s']:7.1f} {s['tracking_losses']:6d} {s['slam_maps']:5d}")
    base, new = summary["retried"], summary["passed"]
    print(f"passed / retried: mean scan time x{new['mean_sim_time_s'] / base['mean_sim_time_s']:.2f}, "
          f"losses x{new['tracking_losses'] / max(base['tracking_losses'], 1):.2f}")
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"stress": args.stress, "seed": args.seed, "limit_s": args.limit_s,
                       "wall_s": round(time.time() - start, 1), "summary": summary,
                       "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
