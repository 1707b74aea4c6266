#!/usr/bin/python3
"""The success table of the escape mission from bench_mission.py result files, with each failure
put in a class.

A full bench (50 worlds per robot kind, plain and stressed) takes hours, so it is often run in
parts, and a part run again after a change. Pass the files in the order they were run: a world
found in several files counts once, as the last file has it. Per robot kind (and stress): the
worlds, the successes, the median sim time to the exit of the successes, and the failures by
class: judged out while inside a room, out of sim time (by the phase it was in), gave up (by its
reason), and runs that left no report. Reads only the files given; takes a second.

With --pool, every run counts, as when one setting was run again at nearby commits to see the
run-to-run spread: the share of successes over all runs with its 95 % Wilson interval, and the
worlds that failed in more than one run (how often, and the class each time).

    /usr/bin/python3 bench/mission_table.py bench/results/mission_ground_stressed_1-31_72008ba.json \\
        bench/results/mission_ground_stressed_32-36_404cdf4.json
"""
import argparse
import collections
import json
import os
import re
import sys

from scipy.stats import binomtest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_mission import summarise  # noqa: E402
from mission_looks import recorded_runs  # noqa: E402


def failure_class(run):
    """A short name for why a run failed."""
    if "error" in run:
        return "no report"
    if run["final_phase"] == "done":
        return "judged out while inside"
    if run["final_phase"] == "gave_up":
        # The reason's numbers differ from run to run; its words say why.
        reason = re.sub(r"\s*\(.*", "", run["final_reason"])
        return f"gave up: {re.sub(r'[-0-9.]+', 'N', reason)[:60]}"
    # Any other phase at the end: the sim-time limit stopped the run there.
    return f"out of time in {run['final_phase']}"


def merge(paths):
    """{robot kind: {world: run}}: the last file holding a world has its say."""
    table = collections.defaultdict(dict)
    for kind, run in recorded_runs(paths):
        table[kind][run["world"]] = run
    return table


def seed(world):
    match = re.search(r"(\d+)$", world)
    return int(match.group(1)) if match else -1


def summary(runs):
    """bench_mission's summary of the runs, with their failures by class."""
    failed = collections.defaultdict(list)
    for r in runs:
        if not r.get("success"):
            failed[failure_class(r)].append(seed(r["world"]))
    s = summarise(runs)
    return {"worlds": s["runs"], "successes": s["successes"],
            "median_sim_time_to_exit_s": s["median_sim_time_to_exit_s"],
            "look_arounds": s["look_arounds"],
            "failures": {k: {"count": len(w), "worlds": sorted(w)}
                         for k, w in sorted(failed.items(), key=lambda kw: -len(kw[1]))}}


def pool(paths):
    """{robot kind: every run of it in the files, in file order}."""
    table = collections.defaultdict(list)
    for kind, run in recorded_runs(paths):
        table[kind].append(run)
    return table


def pooled_summary(runs):
    """Success share over all runs with its 95 % Wilson interval; worlds failed more than once."""
    s = summarise(runs)
    interval = binomtest(s["successes"], s["runs"]).proportion_ci(0.95, method="wilson")
    tried, failed = collections.Counter(), collections.defaultdict(list)
    for r in runs:
        tried[r["world"]] += 1
        if not r.get("success"):
            failed[r["world"]].append(failure_class(r))
    repeated = {w: {"failed": len(c), "runs": tried[w], "classes": c}
                for w, c in sorted(failed.items(), key=lambda wc: (-len(wc[1]), seed(wc[0])))
                if len(c) > 1}
    return {"runs": s["runs"], "successes": s["successes"], "success_share": s["success_rate"],
            "interval_95": [round(interval.low, 3), round(interval.high, 3)],
            "worlds_failed_once": sum(1 for c in failed.values() if len(c) == 1),
            "worlds_failed_more_than_once": repeated}


def print_merged(table):
    for kind, row in table.items():
        median = row["median_sim_time_to_exit_s"]
        print(f"{kind}: {row['successes']} of {row['worlds']} "
              f"({100 * row['successes'] / row['worlds']:.0f} %), median time to the exit "
              f"{'-' if median is None else f'{median:.0f} s'}")
        for name, failures in row["failures"].items():
            print(f"  {failures['count']:3d} {name}: random:"
                  + ", ".join(str(s) for s in failures["worlds"]))


def print_pooled(table):
    for kind, row in table.items():
        low, high = row["interval_95"]
        print(f"{kind}: {row['successes']} of {row['runs']} runs "
              f"({100 * row['success_share']:.1f} %, 95 % interval {100 * low:.1f}-"
              f"{100 * high:.1f} %); {row['worlds_failed_once']} worlds failed once")
        for world, w in row["worlds_failed_more_than_once"].items():
            print(f"  {world} failed {w['failed']} of {w['runs']}: " + "; ".join(w["classes"]))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="bench_mission.py result files, oldest first")
    parser.add_argument("--pool", action="store_true",
                        help="count every run, not the last of each world (see above)")
    parser.add_argument("--json", help="also write the table here")
    args = parser.parse_args(argv)
    if args.pool:
        table = {kind: pooled_summary(runs) for kind, runs in sorted(pool(args.files).items())}
        print_pooled(table)
    else:
        table = {kind: summary([runs[w] for w in sorted(runs, key=seed)])
                 for kind, runs in sorted(merge(args.files).items())}
        print_merged(table)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"files": args.files, "pooled" if args.pool else "table": table}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
