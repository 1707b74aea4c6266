#!/usr/bin/python3
"""Exits given up for losing tracking on the way, in the committed failed runs' logs: how many of
the losses that counted were sudden (the evidence for sudden losses not counting toward
``max_goal_losses``).

Each failed run of bench_mission.py keeps its conductor log under
bench/results/*_failed_logs/<run>/. An exit is given up when tracking was lost
``max_goal_losses`` times in a row on the way to it (or passing through it) without coming
``stall_progress_m`` closer; the losses that counted are the last of that phase before the
verdict, as many as it names (the count restarts at one on progress). A loss is sudden with at least
``sudden_loss_min_tracked_points`` map points tracked at it (the forced losses of the stressed
bench: 600-2300). Logs of code where sudden losses did not count (e7654e3, left on the branch
sudden-goal-losses) hold the skipped sudden ones in that window too: their rows overstate them.
Reads nothing from ../shared; takes a second.

    /usr/bin/python3 bench/goal_loss_counts.py
"""
import argparse
import collections
import glob
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

from sparse_nav.conductor.machine import ConductorConfig  # noqa: E402

LOSS = re.compile(r"LOST / (go_to_exit|pass_through): SLAM tracking lost \((\d+) map points")
NEW_GOAL = ("exit found at", "next candidate", "at the exit: pass through")
GIVEN_UP = re.compile(r"SLAM tracking lost (\d+) times (on the way to the exit|passing through)")


def given_up_exits(log_path):
    """(phase, tracked points of the losses that counted) of each exit given up in one log."""
    found, losses = [], {"go_to_exit": [], "pass_through": []}
    with open(log_path, errors="replace") as f:
        for line in f:
            verdict = GIVEN_UP.search(line)
            if verdict:
                phase = "go_to_exit" if "on the way" in verdict.group(2) else "pass_through"
                found.append((phase, losses[phase][-int(verdict.group(1)):]))
            loss = LOSS.search(line)
            if loss:
                losses[loss.group(1)].append(int(loss.group(2)))
            if verdict or any(sign in line for sign in NEW_GOAL):
                losses = {"go_to_exit": [], "pass_through": []}
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default=os.path.join(HERE, "results"))
    args = parser.parse_args()
    cfg = ConductorConfig()
    table = collections.Counter()
    for path in sorted(glob.glob(os.path.join(args.results, "*_failed_logs", "*",
                                              "conductor-*.log"))):
        setting = os.path.basename(os.path.dirname(os.path.dirname(path)))
        setting = re.sub(r"^mission_|_failed_logs$", "", setting)
        for phase, tracked in given_up_exits(path):
            sudden = sum(n >= cfg.sudden_loss_min_tracked_points for n in tracked)
            table[(setting, phase, sudden)] += 1
    print(f"exits given up after {cfg.max_goal_losses} losses; sudden: at least "
          f"{cfg.sudden_loss_min_tracked_points} map points tracked")
    print(f"{'failed runs of':45} {'phase':13} " + " ".join(
        f"{k} sudden" for k in range(cfg.max_goal_losses + 1)))
    for setting, phase in sorted({(s, p) for s, p, _ in table}):
        counts = [table[(setting, phase, k)] for k in range(cfg.max_goal_losses + 1)]
        print(f"{setting:45} {phase:13} " + " ".join(f"{c:8d}" for c in counts))
    total = [sum(v for (_, _, k), v in table.items() if k == n)
             for n in range(cfg.max_goal_losses + 1)]
    print(f"{'all':45} {'':13} " + " ".join(f"{c:8d}" for c in total))


if __name__ == "__main__":
    main()
