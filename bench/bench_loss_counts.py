#!/usr/bin/python3
"""Looks around beyond doors, replayed without ROS under a forced loss every 30 sim-s: which
losses the conductor counts as signs of open space, and whether a second look in place
(``recheck_lossy_look``) tells a room's glitch from open space.

The ground robot scans the room from the start (``scan_runner.drive_scan`` on the built-in
simulator, the conductor's rules for a scan that loses tracking around it, as
bench_scan_passes.py does), is driven on its true pose to 1.5 m beyond a door (each exit: truly
outside; each partition door: truly in another room), and looks around there twice as the
conductor does (``circular_scan``, no passing). A forced loss comes every 30 sim-s, as in the
stressed mission bench. Each loss is recorded with the map points SLAM tracked in the last
tracking frame before it (``last``), the frame before that (``before``: the conductor may read
that one when a SLAM message is dropped), and the simulator's cause (forced, or too few points).

Per ``sudden_loss_min_tracked_points`` threshold: the natural losses of the first looks it would
call sudden and the forced ones it would count, and the looks lossy (a loss counted) on the
first look and on both, by where the robot truly stood. Reads nothing from ../shared. About 10
minutes of wall time for the defaults; writes bench/results/loss_counts.json.

    /usr/bin/python3 bench/bench_loss_counts.py --worlds 50
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from bench_scan_passes import LOST, STRESS_LOSS_PERIOD_S, TICK_S, SimGround  # noqa: E402
from sparse_nav.conductor.machine import ConductorConfig  # noqa: E402
from sparse_nav.conductor.scan_runner import (ScanRunner, ScanRunnerConfig,  # noqa: E402
                                              config_for_scan)
from sparse_nav.scanning import (GROUND_INITIAL_SCAN_TURN_DEG, GROUND_SPEED_M_S,  # noqa: E402
                                 GROUND_TURN_RATE_RAD_S, InitialScanConfig, WallScanConfig,
                                 circular_scan, initial_scan, relocalise)
from sparse_nav.sim import load_world  # noqa: E402
from sparse_nav.sim.slam import TrackingState  # noqa: E402
from sparse_nav.sim.world import point_in_polygon  # noqa: E402

THRESHOLDS = (40, 60, 80, 100, 120, 150, 200)
PASS_THROUGH_M = 1.5
DOOR_INNER_M = 0.8


class LossLog(SimGround):
    """SimGround that records every OK -> lost transition with the counts tracked before it."""

    def __init__(self, world, seed, losses_at_s):
        super().__init__(world, seed, losses_at_s)
        self.recent_counts = []   # n_tracked of the last two tracking frames
        self.was_lost = False
        self.losses = []
        self.phase = "scan"

    def advance(self, seconds):
        end = self.sim.time_s + seconds
        while self.sim.time_s < end - 1e-9:
            self.sim.step(min(TICK_S, end - self.sim.time_s))
            out = self.sim.slam_output()
            lost = out is not None and out.state in LOST
            if out is not None and out.state == TrackingState.OK:
                self.recent_counts = (self.recent_counts + [int(out.n_tracked)])[-2:]
            if lost and not self.was_lost and self.recent_counts:
                cause = self.sim.last_loss_cause
                self.losses.append({"phase": self.phase, "t": round(self.sim.time_s, 2),
                                    "forced": cause == "forced", "cause": cause,
                                    "last": self.recent_counts[-1],
                                    "before": self.recent_counts[0]})
            self.was_lost = lost
            if not lost:
                self.lost_since_s = None
            elif self.lost_since_s is None:
                self.lost_since_s = self.sim.time_s

    def drive_to(self, xy, limit_s):
        """Turn toward xy and drive there on the true pose (no SLAM needed); False if blocked."""
        end = self.sim.time_s + limit_s
        while self.sim.time_s < end:
            x, y, _, yaw = self.sim.true_base_pose()
            dx, dy = xy[0] - x, xy[1] - y
            if math.hypot(dx, dy) < 0.1:
                self.sim.set_cmd_vel(0.0, 0.0)
                return True
            err = math.atan2(math.sin(math.atan2(dy, dx) - yaw), math.cos(math.atan2(dy, dx) - yaw))
            w = max(-GROUND_TURN_RATE_RAD_S, min(GROUND_TURN_RATE_RAD_S, 2.0 * err))
            v = GROUND_SPEED_M_S if abs(err) < 0.3 else 0.0
            self.sim.set_cmd_vel(v, w)
            self.advance(TICK_S)
        self.sim.set_cmd_vel(0.0, 0.0)
        return False

    def scan(self, steps, limit_s, look=False):
        config = config_for_scan("look_around" if look else "initial", ScanRunnerConfig())
        runner = ScanRunner(steps, config)
        while not runner.done and self.sim.time_s < limit_s:
            self.drive(runner, self.conductor_stops_scan)
            if runner.done:
                break
            while self.tracking_lost() and self.sim.time_s < limit_s:
                self.drive(ScanRunner(relocalise("ground"), while_lost=True),
                           lambda: not self.tracking_lost())
                self.advance(0.5)


def doors(world):
    """(kind, inner xy, beyond xy) for each door gap: the side nearer the start is inner."""
    start = np.array(world.start[:2])
    out = []
    for x1, y1, x2, y2, outer in world.door_gaps:
        a, b = np.array([x1, y1]), np.array([x2, y2])
        c = (a + b) / 2
        n = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
        if outer:
            inside = any(point_in_polygon(c - 0.3 * n, o) for o in world.outlines)
            n = n if inside else -n        # n points out of the building
        elif np.dot(start - c, n) > 0:
            n = -n                         # n points away from the start's room
        out.append(("outside" if outer else "room", c - DOOR_INNER_M * n, c + PASS_THROUGH_M * n))
    return out


def run_world(name, seed, look_s):
    world = load_world(name)
    rows = []
    for kind, inner, beyond in doors(world):
        robot = LossLog(world, seed, [STRESS_LOSS_PERIOD_S * k for k in range(1, 40)])
        robot.scan(initial_scan(InitialScanConfig(turn_deg=GROUND_INITIAL_SCAN_TURN_DEG)), 300.0)
        robot.phase = "drive"
        if not (robot.drive_to(inner, 120.0) and robot.drive_to(beyond, 30.0)):
            rows.append({"world": name, "kind": kind, "reached": False})
            continue
        robot.phase = "look"
        robot.scan(circular_scan(WallScanConfig()), robot.sim.time_s + look_s, look=True)
        robot.phase = "look2"
        robot.scan(circular_scan(WallScanConfig()), robot.sim.time_s + look_s, look=True)
        rows.append({"world": name, "kind": kind, "reached": True,
                     "losses": [l for l in robot.losses if l["phase"] == "look"],
                     "losses2": [l for l in robot.losses if l["phase"] == "look2"],
                     "scan_losses": [l for l in robot.losses if l["phase"] == "scan"]})
    return rows


def counted(losses, key, threshold):
    return sum(loss[key] < threshold for loss in losses)


def summarise(rows, key):
    """Per threshold and kind of place: losses of the first looks, and lossy looks."""
    reached = [r for r in rows if r.get("reached")]
    table = {}
    for t in THRESHOLDS:
        cell = {}
        for kind in ("outside", "room"):
            looks = [r for r in reached if r["kind"] == kind]
            first = [loss for r in looks for loss in r["losses"]]
            cell[kind] = {
                "looks": len(looks),
                "natural": sum(not loss["forced"] for loss in first),
                "natural_called_sudden": sum(not loss["forced"] and loss[key] >= t
                                             for loss in first),
                "forced": sum(loss["forced"] for loss in first),
                "forced_counted": sum(loss["forced"] and loss[key] < t for loss in first),
                "lossy_first": sum(counted(r["losses"], key, t) > 0 for r in looks),
                "lossy_both": sum(counted(r["losses"], key, t) > 0
                                  and counted(r["losses2"], key, t) > 0 for r in looks)}
        table[t] = cell
    return table


def losses_per_look(rows, threshold=ConductorConfig().sudden_loss_min_tracked_points):
    """{kind: {losses the conductor counts on the first look: looks}}, read from the last
    tracking frame at the conductor's sudden-loss threshold (recheck_lossy_look_max_losses)."""
    table = {}
    for r in rows:
        if r.get("reached"):
            n = counted(r["losses"], "last", threshold)
            cell = table.setdefault(r["kind"], {})
            cell[n] = cell.get(n, 0) + 1
    return {kind: dict(sorted(cell.items())) for kind, cell in sorted(table.items())}


def print_summary(summary):
    for key, table in summary.items():
        print(f"counts read from the {key!r} tracking frame:")
        print(f"{'threshold':>9s} | {'where':7s} {'natural called sudden':>22s} "
              f"{'forced counted':>15s} {'lossy looks':>12s} {'lossy twice':>12s}")
        for t, cell in table.items():
            for kind, c in cell.items():
                print(f"{t:9d} | {kind:7s} {c['natural_called_sudden']:>13d} of {c['natural']:<5d}"
                      f"{c['forced_counted']:>9d} of {c['forced']:<3d}"
                      f"{c['lossy_first']:>6d} of {c['looks']:<3d}"
                      f"{c['lossy_both']:>6d} of {c['looks']:<3d}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", type=int, default=50, help="random:F .. random:F+N-1")
    parser.add_argument("--first-world", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="the simulator's seed")
    parser.add_argument("--look-s", type=float, default=90.0, help="sim-s per look at most")
    parser.add_argument("--json", default=os.path.join(HERE, "results", "loss_counts.json"))
    args = parser.parse_args()
    start = time.time()
    rows = []
    for k in range(args.first_world, args.first_world + args.worlds):
        for row in run_world(f"random:{k}", args.seed, args.look_s):
            rows.append(row)
            print(json.dumps(row), flush=True)
    summary = {key: summarise(rows, key) for key in ("last", "before")}
    print_summary(summary)
    per_look = losses_per_look(rows)
    for kind, cell in per_look.items():
        print(f"{kind}: first looks by losses counted: "
              + ", ".join(f"{n}: {looks}" for n, looks in cell.items()))
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"seed": args.seed, "look_s": args.look_s,
                       "wall_s": round(time.time() - start, 1), "summary": summary,
                       "first_look_losses": per_look,
                       "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
