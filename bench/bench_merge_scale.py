#!/usr/bin/python3
"""How right the bridge's scale is after SLAM merges, against the simulator's, without ROS.

Replays the ground robot's scan in random:<first>..<first+worlds-1> with a forced loss every
30 s (``replay_measured`` of test/python/test_bridge_follows_sim_merges.py): each SLAM map is
measured from the simulator's own scale after 8 s in it, so every error comes from the bridge's
map bookkeeping at merges. Counts the carry-overs of scale samples more than 20 % off, and the
scans that end in a measured map with the scale more than 20 % off. Reads nothing from
../shared. About 3 min of wall time for the defaults; writes bench/results/merge_scale.json.
To measure an older bridge, put its checkout's src first on PYTHONPATH.

    /usr/bin/python3 bench/bench_merge_scale.py --worlds 40
"""
import argparse
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.append(os.path.join(HERE, "..", "src"))
sys.path.append(os.path.join(HERE, "..", "test", "python"))

from test_bridge_follows_sim_merges import replay_measured  # noqa: E402

OFF = 1.2  # a scale more than 20 % off either way


def _off(estimate, truth):
    return not 1.0 / OFF <= estimate / truth <= OFF


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=40)
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--out", default=os.path.join(HERE, "results", "merge_scale.json"))
    args = parser.parse_args()
    runs = []
    for seed in range(args.first_seed, args.first_seed + args.worlds):
        world = f"random:{seed}"
        merges, carried, (value, truth, n, tracked_s) = replay_measured(world)
        runs.append({"world": world, "merges": len(merges),
                     "moved": sum(m.left == m.into for m in merges),
                     "carried": len(carried),
                     "carried_off": sum(_off(e, t) for e, t in carried),
                     "final_ratio": value / truth, "final_samples": n,
                     "final_map_tracked_s": round(tracked_s, 1)})
        print(json.dumps(runs[-1]), flush=True)
    measured = [r for r in runs if r["final_samples"] > 0]
    summary = {
        "worlds": len(runs),
        "carry_overs": sum(r["carried"] for r in runs),
        "carry_overs_off_20pct": sum(r["carried_off"] for r in runs),
        "moves_into_unknown_frames": sum(r["moved"] for r in runs),
        "scans_ending_in_a_measured_map": len(measured),
        "of_those_off_20pct": sum(_off(r["final_ratio"], 1.0) for r in measured),
    }
    print(json.dumps(summary))
    with open(args.out, "w") as f:
        json.dump({"bench": "merge_scale", "summary": summary, "runs": runs}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
